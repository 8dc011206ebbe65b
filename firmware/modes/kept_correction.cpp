#include "firmware/modes/kept_correction.hpp"

#include <memory>
#include <stdexcept>
#include <string>

namespace calbox::firmware {

// The one in force before is kept with the cycle's record first, so that nothing is lost if the
// new one cannot be written.
void KeptCorrectionMode::apply(std::function<void(bool verify)> then) {
    steps_.enter(CycleState::apply, files_.apply_detail);
    const auto previous = steps_.read(files_.kept);
    if (!steps_.keep(steps_.record_name(files_.backup), previous.value_or(files_.none))) return;
    if (!steps_.keep(files_.kept, kept_text())) return;
    then(true);
}

void KeptCorrectionMode::verification_job(const std::vector<std::string>& target,
                                          std::function<void(std::vector<std::string>)> then) {
    work_out<std::vector<std::string>>(
        steps_,
        [text = joined(target), correction = jobs::MachineCorrection{correction(), measured_area()},
         frame = target_frame()] {
            jobs::CompensateReport ignored;
            return lines_of(jobs::compensate_gcode(text, correction, frame, {}, ignored));
        },
        std::move(then));
}

std::string KeptCorrectionMode::revert(int number, std::function<void(std::string what)> then) {
    const std::string backup_name = steps_.record_name(files_.backup);
    const auto kept = steps_.read(backup_name);
    if (!kept)
        return "revert: cycle " + std::to_string(number) + " applied nothing (no " + backup_name +
               ")";
    steps_.enter(CycleState::apply,
                 "reverting to the correction in force before cycle " + std::to_string(number));
    if (!steps_.keep(files_.kept, *kept)) return {};  // the cycle is in error, saying why
    then("reverted to " + backup_name);
    return {};
}

std::optional<std::string> KeptCorrectionMode::kept_result_text() const {
    auto kept = steps_.read(files_.kept);
    if (!kept || *kept == files_.none) return std::nullopt;
    return kept;
}

std::optional<jobs::KeptCorrection> KeptCorrectionMode::correction_in_force() const {
    try {
        return kept_correction();
    } catch (const std::exception& e) {
        steps_.log(std::string(files_.kept) + " does not read (" + e.what() +
                       "): drift is worked out from the error without it",
                   hal::LogLevel::warning);
        return std::nullopt;
    }
}

std::optional<jobs::KeptCorrection> KeptCorrectionMode::kept_correction() const {
    const auto kept = steps_.read(files_.kept);
    if (!kept || *kept == files_.none) return std::nullopt;
    return correction_of(*kept);
}

}  // namespace calbox::firmware
