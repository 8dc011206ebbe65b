#pragma once
// The page's Place screen: a job in the data directory drawn on the bed view before anything
// runs, where it means the tool to go once placed at a work zero through the correction in force
// (core/modes/compensate_job: the same placement, the same refusals, as the job compensated).
#include <cstddef>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>

namespace calbox::firmware {

// The most points one outline carries: a drawing on a view a few hundred pixels across.
constexpr std::size_t kOutlinePointsMax = 20000;

// {"job", "work_zero", "frame", "summary", "points": [[x_mm, y_mm], ...], "points_in_job"}:
// the job's path in machine coordinates, thinned to kOutlinePointsMax for the drawing (the
// count before thinning said). Throws modes::JobError with the job's, the zero's or the
// result's one line.
// A work zero "camera [CORNER]" places it at `found_text`'s sheet, "marks" by its printed marks
// (the last bed photo's stock.json or marks.json: found_file_for).
nlohmann::json job_outline_json(const std::string& kept_result_text, const std::string& job_text,
                                const std::string& job_name, const std::string& work_zero,
                                const std::optional<std::string>& found_text);

}  // namespace calbox::firmware
