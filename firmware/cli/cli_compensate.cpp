// calbox compensate: a job sent through a solve's correction, where the machine really is.
#include <ctime>
#include <iostream>
#include <string>

#include "core/modes/compensate_job.hpp"
#include "firmware/cli/cli_args.hpp"

namespace calbox::cli {
namespace {

std::string today() {
    const std::time_t now = std::time(nullptr);
    std::tm utc{};
    gmtime_r(&now, &utc);
    char text[32];
    std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
    return text;
}

int compensate(const Args& args) {
    modes::JobRequest request;
    request.job_name = args.positional()[0];
    const std::string out = args.require("-o");
    request.result_name = args.require("--result");
    request.settings.max_segment_mm = args.number("--segment", 1.0);
    if (!(request.settings.max_segment_mm >= 0.01 && request.settings.max_segment_mm <= 100))
        throw UsageError("--segment must be 0.01 to 100 mm");
    if (args.get("--tool-radius")) {
        const double r = args.number("--tool-radius", 0);
        if (!(r > 0 && r <= 100))
            throw UsageError("--tool-radius must be above 0 and at most 100 mm");
        request.settings.tool_radius_mm = r;
    }
    request.work_zero = args.get("--work-zero");
    if (const auto stock = args.get("--stock")) {
        request.stock_name = *stock;
        request.stock_text = read_input_file(*stock, "stock file");
    }
    if (const auto marks = args.get("--register")) {
        request.registration_name = *marks;
        request.registration_text = read_input_file(*marks, "registration file");
    }
    if (const auto corner = args.get("--corner")) {
        if (!(request.work_zero && *request.work_zero == "camera"))
            throw UsageError("--corner names the sheet's corner for --work-zero camera",
                             "calbox compensate");
        request.stock_corner = *corner;
    }
    request.start_at = args.get("--start-at");
    request.again_because = args.get("--again");
    if (request.again_because && request.again_because->empty())
        throw UsageError("--again needs the reason");
    request.result_text = read_input_file(request.result_name, "result");
    request.job_text = read_input_file(request.job_name, "job");
    request.date = today();
    const auto done = modes::compensate_job(request);
    write_output_file(out, done.text);
    std::cout << out << ": " << done.summary << "\n" << done.frame_line << "\n";
    if (!done.held_line.empty())
        std::cerr << "calbox: " << request.job_name << ": " << done.held_line << "\n";
    return 0;
}

}  // namespace

std::vector<Command> compensate_commands() {
    return {
        {"compensate",
         "a job sent through a solve's correction",
         {{"--result", "result.json", "a galvo or planar result (calbox solve)", Given::required},
          {"IN", "", "the job: G-code, or a scanner job (x_mm,y_mm,power lines)", Given::word},
          {"-o", "OUT", "the compensated job, written", Given::required},
          {"--work-zero", "X,Y|measured|camera|\"G54=X,Y G55=X,Y\"",
           "where the job's work zero is in machine coordinates (a planar result)"},
          {"--stock", "stock.json",
           "the sheet the camera found (calbox view stock), for --work-zero camera"},
          {"--register", "marks.json",
           "the drawing's place its printed marks gave (calbox view marks): the job is in the "
           "drawing's frame"},
          {"--corner", "NAME",
           "its corner the job's zero goes to: front-left, front-right, back-right, back-left or "
           "nearest (the default: the one nearest the machine's zero)"},
          {"--start-at", "X,Y",
           "where the tool stands when the job starts (machine coordinates): for a job that "
           "sets G92 before its first move"},
          {"--again", "REASON", "compensate a job that already went through a correction"},
          {"--segment", "MM", "the longest piece a move is split into (default 1)"},
          {"--tool-radius", "MM",
           "the cutter's radius, for a LinuxCNC job's cutter radius compensation by the tool "
           "table (G41 / G42 D<tool>)"}},
         R"(Sends every XY position of a job through the correction a solve found, so that the
machine marks where the job meant: a galvo result (calbox solve galvo), whose table gives
the scanner command for each intended point, or a planar result (calbox solve planar),
whose error model e gives X_c = X_t - e(X_c) (the rigid part of e left to the work's zero
and heading).
The frame: a planar result records the machine coordinates of the work zero its target
ran with, and the machine's travel. A printer's job is in machine coordinates (its G92
tracked). A router's or laser's job is written around its own work zero: --work-zero X,Y
gives G54's zero in machine coordinates, --work-zero measured says it is the frame the
result was measured in, "G55=X,Y ..." gives other work systems, --work-zero camera puts it
at a corner of the sheet the camera found (--stock stock.json, --corner NAME) and turns the
job with the sheet's front edge (such a job keeps to G54, without G10 or G92 offsets); without
it the job is refused. --register marks.json instead places a job written in a printed
drawing's frame where its marks were found (turned, and scaled with four marks). G10 L2 / L20 in the job set work offsets, and are tracked. A point beyond the
travel is refused, naming the line; between the measured area and the travel a point
takes the correction at the area's nearest edge (held, never extrapolated), counted on
standard error. One line says which frame was used.
IN is G-code as slicers, CAM and LinuxCNC write it (inches, relative moves, G92, arcs and
helices, numbered and checksummed lines, canned cycles G73 and G81-G89 with G98/G99 and L
repeats: kept for LinuxCNC, written out as moves for grbl and printers; LinuxCNC's
parameters, expressions, O-word subroutines and loops, and polar words, evaluated into
plain G-code) or a plain scanner job (its first line x_mm,y_mm,power). Moves are split into
pieces of at most --segment mm (default 1) and arcs traced by chords within 0.002 mm; an R
arc short of its half chord by no more than the file's written precision is a half circle.
On printers G10 / G11 are firmware retraction, passed as written.
The output's first line names the result it went through (its digest and date); a job
carrying that line is refused unless --again gives the reason.
Cutter radius compensation on LinuxCNC (G41 / G42 with --tool-radius, or G41.1 / G42.1
with the diameter on the line; G40 off) is carried out as LinuxCNC's interpreter does it,
for straight moves in G17 under G90: the path the controller would cut is written out (an
arc about each outside corner, inside corners cut where the offset paths cross) and
corrected like any other.
Refused, naming the line and the figure, nothing written: cutter compensation on grbl and
printers, or with arcs, G91, another plane or offsets under it; a lathe job (G7, G8, G76), an arc no controller could cut, a point beyond the travel, a
move in a work system whose zero is not given, moves under block delete.)",
         compensate}};
}

}  // namespace calbox::cli
