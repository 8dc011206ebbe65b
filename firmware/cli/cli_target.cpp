// calbox target svg: a job for any machine from a drawing.
#include <cstdio>
#include <filesystem>

#include "core/drawings/drawing.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_file.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/mode_verbs.hpp"

namespace calbox::cli {
namespace {

constexpr std::uintmax_t kMaxSvgBytes = std::uintmax_t{10} * 1024 * 1024;

int target_svg(const Args& args) {
    const std::string svg_path = args.positional()[0];
    const std::string machine_path = args.require("--machine");
    const std::string out = args.require("-o");
    jobs::SvgJobSettings settings;
    if (args.get("--spacing")) settings.spacing_mm = args.number("--spacing", 0);
    if (args.get("--angle")) settings.angle_deg = args.number("--angle", 0);
    if (args.get("--feed")) settings.feed_mm_s = args.number("--feed", 0);
    if (args.get("--scale")) settings.scale = args.number("--scale", 0);
    if (args.get("--fit")) settings.fit_mm = args.number("--fit", 0);
    settings.perimeters = static_cast<int>(args.number("--perimeters", 1));
    if (const auto rule = args.get("--fill-rule")) {
        if (*rule != "nonzero" && *rule != "evenodd")
            throw UsageError("--fill-rule must be nonzero or evenodd");
        settings.fill_rule =
            *rule == "evenodd" ? drawings::FillRule::evenodd : drawings::FillRule::nonzero;
    }
    const auto machine =
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path);
    std::error_code error;
    const auto size = std::filesystem::file_size(svg_path, error);
    if (!error && size > kMaxSvgBytes) {
        throw std::runtime_error(svg_path + ": the document is " + std::to_string(size) +
                                 " bytes, over the limit of " + std::to_string(kMaxSvgBytes));
    }
    drawings::SvgDocument document;
    try {
        document = drawings::read_drawing(read_input_file(svg_path, "drawing"));
    } catch (const drawings::SvgError& e) {
        throw std::runtime_error(svg_path + ": " + e.what());
    }
    for (const auto& warning : document.warnings)
        std::fprintf(stderr, "calbox: warning: %s: %s\n", svg_path.c_str(), warning.c_str());
    // Whatever the drawing cannot become is said of the drawing.
    const auto job = [&] {
        try {
            return jobs::plan_svg_job(document, machine, settings);
        } catch (const std::runtime_error& e) {
            throw std::runtime_error(svg_path + ": " + e.what());
        }
    }();
    if (job.shapes_cut_at_page > 0)
        std::fprintf(stderr,
                     "calbox: warning: %s: %d shapes reach past the drawing's page and were cut at "
                     "its edge, as a browser shows them\n",
                     svg_path.c_str(), job.shapes_cut_at_page);
    write_output_file(
        out, jobs::write_gcode(
                 job, machine,
                 "calbox target svg " + std::filesystem::path(svg_path).filename().string()));
    std::printf("%s: %.2f x %.2f mm, %zu moves, path %.1f mm, travel %.1f mm, about %.0f s\n",
                out.c_str(), job.max_x - job.min_x, job.max_y - job.min_y,
                job.toolpath.moves.size(), job.toolpath.working_length_mm(),
                job.toolpath.travel_length_mm(), job.estimated_time_s(machine));
    if (const auto preview = args.get("--preview")) draw_preview(*preview, job, machine);
    return 0;
}

}  // namespace

std::vector<Command> target_commands() {
    std::vector<Command> commands;
    for (auto& verbs : mode_verbs()) commands.push_back(std::move(verbs.target));
    commands.push_back(
        {"target svg",
         "a job for the machine from a drawing",
         {{"FILE.svg", "", "the drawing", Given::word},
          {"--machine", "FILE", "the machine file", Given::required},
          {"-o", "JOB", "the job, written", Given::required},
          {"--spacing", "MM", "infill lines apart (default: the line width)"},
          {"--angle", "DEG", "the infill's direction"},
          {"--feed", "MM_S", "the working feed"},
          {"--scale", "S", "the drawing's own size times S"},
          {"--fit", "MM", "the drawing's larger side, in mm"},
          {"--fill-rule", "nonzero|evenodd", "for every filled shape (default: each shape's own)"},
          {"--perimeters", "N", "perimeters around each filled shape (default 1)"},
          {"--preview", "PNG", "the job's paths, drawn"}},
         R"(A job for the machine from a drawing, read as a browser paints it (librsvg: its CSS,
<use> and <symbol>, text in the font it names, clip paths). Filled shapes are filled as SVG
means it (their fill-rule, or --fill-rule for all): perimeters inset by half the line width,
then infill lines --spacing apart (default: the line width; printers accept their line width
to ten times it) at --angle degrees, in a zigzag. Strokes are traced along their middle. The
drawing is centred on the bed and reads as drawn seen from above; --fit makes its larger
side that many mm, --scale multiplies its own size. --preview draws perimeters (blue),
infill (green), traces (purple) and travel (red) with path length, travel and time.)",
         target_svg});
    return commands;
}

}  // namespace calbox::cli
