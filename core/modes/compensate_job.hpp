#pragma once
// A job compensated through a kept result (a planar error model or a galvo table), where the
// machine really is: the command line and the box's console call this one function. It places
// the job on the machine (the job's work zero, the frame the result was measured in), refuses
// what it cannot place, marks the output with the result it went through, and refuses a job
// that already carries such a mark.
#include <optional>
#include <stdexcept>
#include <string>

#include "core/jobs/compensate.hpp"

namespace calbox::modes {

class JobError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct JobRequest {
    std::string result_text, result_name;  // the result file's text, and its name for messages
    std::string job_text, job_name;
    // --work-zero: "X,Y" (G54's zero in machine coordinates), "measured" (the frame the result
    // was measured in), or entries "G54=X,Y G55=X,Y ..." separated by blanks.
    std::optional<std::string> work_zero;
    // --work-zero camera: the sheet the camera found (calbox view stock's file) and the corner
    // the job's zero goes to ("nearest": the one nearest the machine's zero); the job is turned
    // with the sheet's front edge.
    std::optional<std::string> stock_text, stock_name;
    std::string stock_corner = "nearest";
    // --register: the drawing's place that its printed marks gave (calbox view marks); the job
    // is in the drawing's frame, and goes where the drawing lies.
    std::optional<std::string> registration_text, registration_name;
    // --start-at "X,Y": where the tool stands when the job starts, machine coordinates.
    std::optional<std::string> start_at;
    std::string work_zero_from;  // where the work zero came from, when not the owner's option
    std::optional<std::string> again_because;  // compensate a marked job again, for this reason
    std::string date;                          // for the mark: the caller's clock
    jobs::CompensateSettings settings;
    // Keep where the job means the tool to go (the report's path_mm): to draw it on the bed.
    bool keep_path = false;
};

struct CompensatedJob {
    std::string text;  // the compensated job, its mark first
    jobs::CompensateReport report;
    std::string frame_line;  // which frame it was placed in, in one line
    std::string summary;     // lines, moves, pieces, arcs, holes
    std::string held_line;   // "" or how many points took the measured area's edge correction
};

// Throws JobError with one line naming the job or the result, the place and the figure.
CompensatedJob compensate_job(const JobRequest& request);

// "X,Y" -> G54's zero; "G55=X,Y ..." -> each; "measured" -> `measured_mm`. Throws JobError.
std::array<std::optional<geometry::Point2>, jobs::kWorkSystems> parse_work_zero(
    const std::string& spec, geometry::Point2 measured_mm);

}  // namespace calbox::modes
