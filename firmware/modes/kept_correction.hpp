#pragma once
// The apply strategy of a mode whose correction the box keeps (galvo, planar): the correction is
// a file in the box's data directory that jobs are sent through; the one in force before a
// cycle is kept with its record, so that revert can put it back; the verification job is the
// target sent through the new correction.
#include <string>

#include "firmware/cycle/cycle_mode.hpp"

namespace calbox::firmware {

struct KeptCorrectionFiles {
    const char* kept;           // in the data directory: "galvo-table.json"
    const char* none;           // what the kept file holds when no correction is in force
    const char* backup;         // in a cycle's record: "backup-table.json"
    const char* apply_detail;   // "keeping the table: jobs now go through it"
    const char* verify_detail;  // "burning the grid again through the table"
};

class KeptCorrectionMode : public CycleMode {
  public:
    void apply(std::function<void(bool verify)> then) override;
    std::string verify_detail() const override { return files_.verify_detail; }
    void verification_job(const std::vector<std::string>& target,
                          std::function<void(std::vector<std::string>)> then) override;
    std::string revert(int number, std::function<void(std::string what)> then) override;
    std::optional<jobs::KeptCorrection> kept_correction() const override;
    std::optional<std::string> kept_result_text() const override;
    std::vector<std::string> kept_files() const override { return {files_.kept}; }

  protected:
    KeptCorrectionMode(CycleSteps& steps, KeptCorrectionFiles files)
        : steps_(steps), files_(files) {}
    // The solved correction as the box keeps it, and as jobs go through it.
    virtual std::string kept_text() const = 0;
    virtual jobs::Correction correction() const = 0;
    // Where the correction was measured, in machine coordinates (held at its edge beyond), and
    // the frame the target ran in.
    virtual jobs::Area measured_area() const = 0;
    virtual jobs::JobFrame target_frame() const = 0;
    // A kept file read back (throws when it does not parse).
    virtual jobs::KeptCorrection correction_of(const std::string& kept_text) const = 0;
    // The correction jobs go through now, for the machine's error through it (drift); a kept
    // file that does not read is said in the log, and the error without it stands instead.
    std::optional<jobs::KeptCorrection> correction_in_force() const;

    CycleSteps& steps_;

  private:
    KeptCorrectionFiles files_;
};

}  // namespace calbox::firmware
