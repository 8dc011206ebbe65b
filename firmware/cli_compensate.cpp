// calbox compensate: a job sent through a solve's correction.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>

#include "core/modes/galvo.hpp"
#include "core/modes/planar.hpp"
#include "core/targets/compensate.hpp"
#include "firmware/cli_args.hpp"

namespace calbox::cli {
namespace {

constexpr const char* kCompensateHelp = R"(usage:
  calbox compensate --result result.json IN -o OUT [--segment MM]
      Sends every XY position of a job through the correction a solve found, so that the
      machine marks where the job meant: a galvo result (calbox solve galvo), whose table gives
      the scanner command for each intended point, or a planar result (calbox solve planar),
      whose error model e gives X_c = X_t - e(X_c) (the rigid part of e left to the work's zero
      and heading). IN is G-code as slicers and CAM write it (modal words alone on a line,
      either comment, % delimiters; inches G20, relative G91, G92 offsets, arcs in G17/G18/G19
      and helices, numbered and checksummed lines renumbered: each carried and written back as
      the job had it) or a plain scanner job (its first line x_mm,y_mm,power). Moves are split
      into pieces of at most --segment mm (default 1: the table's bilinear correction then
      bends less than 0.0001 mm between pieces on scanners of the size tested) and arcs are
      traced by chords within 0.002 mm; every other word, comment and line is kept as written.
      Points outside the table's area take the edge's correction (a planar model extrapolates
      beyond its measured holes) and are counted on standard error. Refused, naming the line,
      nothing written: cutter compensation (G41/G42), canned cycles (G73, G76, G81-G89), work
      offsets held by the controller (G55-G59, G10), G53 moves with X or Y, moves under block
      delete, absolute arc centres (G90.1), LinuxCNC parameters and O-words, polar words.
)";

int compensate(const std::vector<std::string>& words) {
    const Args args(words, {"--result", "-o", "--segment"}, {});
    if (args.positional().size() != 1) throw UsageError("compensate takes one job file");
    const std::string in = args.positional()[0];
    const std::string out = args.require("-o");
    const std::string result_path = args.require("--result");
    targets::CompensateSettings settings;
    settings.max_segment_mm = args.number("--segment", 1.0);
    if (!(settings.max_segment_mm >= 0.01 && settings.max_segment_mm <= 100))
        throw UsageError("--segment must be 0.01 to 100 mm");
    const std::string result_text = read_input_file(result_path, "result");
    // Which mode's result it is: its schema says.
    std::string schema;
    try {
        const auto j = nlohmann::json::parse(result_text);
        if (j.is_object() && j.contains("schema") && j["schema"].is_string())
            schema = j["schema"].get<std::string>();
    } catch (const nlohmann::json::exception&) {
        throw std::runtime_error(result_path + ": not a result file (malformed JSON)");
    }
    targets::Correction correct;
    targets::Covers covers;
    std::optional<modes::GalvoSolution> galvo;
    std::optional<modes::PlanarSolution> planar;
    if (schema.rfind("calbox.planar-result/", 0) == 0) {
        planar = modes::planar_result_from_json(result_text, result_path);
        correct = [&](geometry::Point2 p) { return modes::planar_command_for(*planar, p); };
        covers = [&](geometry::Point2 p) { return modes::planar_covers(*planar, p); };
    } else {
        galvo = modes::galvo_result_from_json(result_text, result_path);
        const auto& table = galvo->fit.table;
        correct = [&table](geometry::Point2 p) { return table.command_for(p); };
        covers = [&table](geometry::Point2 p) { return table.covers(p); };
    }
    const std::string job = read_input_file(in, "job");
    targets::CompensateReport report;
    std::string compensated;
    try {
        compensated = job.rfind("x_mm,y_mm,power", 0) == 0
                          ? targets::compensate_scanner_csv(job, correct, covers, settings, report)
                          : targets::compensate_gcode(job, correct, covers, settings, report);
    } catch (const targets::CompensateError& e) {
        throw std::runtime_error(in + ": " + e.what());
    }
    write_output_file(out, compensated);
    std::printf("%s: %ld lines, %ld moves corrected as %ld pieces, %ld arcs traced\n", out.c_str(),
                report.lines, report.moves, report.pieces, report.arcs);
    if (report.outside > 0)
        std::cerr << "calbox: " << in << ": " << report.outside
                  << (planar ? " points lie outside the measured holes' area (the model "
                               "extrapolates there)\n"
                             : " points lie outside the table's area and took its edge's "
                               "correction\n");
    return 0;
}

}  // namespace

int run_compensate(const std::vector<std::string>& words) {
    for (const auto& w : words)
        if (w == "--help" || w == "-h") {
            std::cout << kCompensateHelp;
            return 0;
        }
    if (words.empty()) {
        std::cerr << kCompensateHelp;
        return 2;
    }
    return compensate(words);
}

}  // namespace calbox::cli
