#include "firmware/net/place_view.hpp"

#include <cmath>
#include <nlohmann/json.hpp>

#include "core/modes/compensate_job.hpp"
#include "firmware/console/job_desk.hpp"

namespace calbox::firmware {

nlohmann::json job_outline_json(const std::string& kept_result_text, const std::string& job_text,
                                const std::string& job_name, const std::string& work_zero,
                                const std::optional<std::string>& found_text) {
    modes::JobRequest request;
    request.result_text = kept_result_text;
    request.result_name = "the correction in force";
    request.job_text = job_text;
    request.job_name = job_name;
    set_desk_work_zero(request, work_zero, found_text);
    request.keep_path = true;
    // A drawing needs the job's own points, not the pieces a changing correction is followed by.
    request.settings.max_segment_mm = 1e9;
    const auto done = modes::compensate_job(request);
    const auto& path = done.report.path_mm;
    const std::size_t every = path.size() / kOutlinePointsMax + 1;
    nlohmann::json points = nlohmann::json::array();
    const auto rounded = [](double v) { return std::round(v * 1000) / 1000; };
    for (std::size_t i = 0; i < path.size(); ++i)
        if (i % every == 0 || i + 1 == path.size())
            points.push_back({rounded(path[i].x), rounded(path[i].y)});
    return {{"job", job_name},         {"work_zero", work_zero}, {"frame", done.frame_line},
            {"summary", done.summary}, {"points", points},       {"points_in_job", path.size()}};
}

}  // namespace calbox::firmware
