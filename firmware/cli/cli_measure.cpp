// calbox measure delta: photos of the printed target -> measurements.json.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "core/geometry/camera_model.hpp"
#include "core/modes/delta.hpp"
#include "core/modes/delta_records.hpp"
#include "core/modes/galvo.hpp"
#include "core/modes/planar.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/cli_images.hpp"
#include "firmware/cycle/overlays.hpp"

namespace calbox::cli {
namespace {

// What every measure command reads first: the camera, the bed plane and the machine.
struct SetUp {
    geometry::CameraModel camera;
    geometry::BedPlane plane;
    models::MachineFile machine;
};
SetUp read_set_up(const Args& args) {
    const std::string machine_path = args.require("--machine");
    return {
        geometry::camera_from_yaml(read_input_file(args.require("--camera"), "camera file")),
        geometry::plane_from_yaml(read_input_file(args.require("--plane"), "plane file")),
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path)};
}

int measure_delta(const Args& args) {
    const std::string out = args.require("-o");
    const auto [camera, plane, machine] = read_set_up(args);
    std::vector<cv::Mat> images;
    std::vector<vision::GrayView> views;
    images.reserve(args.positional().size());
    views.reserve(args.positional().size());
    for (const auto& path : args.positional()) images.push_back(load_gray_image(path));
    for (const auto& image : images) views.push_back(view_of(image));
    std::optional<double> photo_bed_temperature_c;
    if (args.get("--bed-temperature")) {
        photo_bed_temperature_c = args.number("--bed-temperature", 0);
        if (*photo_bed_temperature_c < -50 || *photo_bed_temperature_c > 200)
            throw UsageError("--bed-temperature must be -50..200 degrees C");
    }
    const auto measured =
        modes::measure_delta(machine, camera, plane, views, photo_bed_temperature_c);
    write_output_file(
        out, modes::measurements_to_json(modes::record_of(measured, machine, args.positional())));
    std::printf("%s: %zu corners of %zu markers from %zu photo(s)\n", out.c_str(),
                measured.features.size(), measured.target.markers.size(), views.size());
    if (!measured.heights_from_fit) std::printf("heights: %s\n", measured.heights_fallback.c_str());
    for (const auto& why : measured.bars_unmeasured) std::printf("not measured: %s\n", why.c_str());
    for (const auto& why : measured.markers_unread) std::printf("not read: %s\n", why.c_str());
    for (const auto& why : measured.rings_unmeasured)
        std::printf("not measured: %s\n", why.c_str());
    const auto unrefined = std::count_if(measured.features.begin(), measured.features.end(),
                                         [](const auto& f) { return !f.refined; });
    if (unrefined > 0) {
        std::printf("%ld corners kept as the detector found them (refined: false):\n",
                    static_cast<long>(unrefined));
        for (std::size_t f = 0; f < measured.frames.size(); ++f) {
            for (const auto& m : measured.frames[f]) {
                if (!m.refined)
                    std::printf("  photo %zu, marker %d: %s\n", f + 1, m.id,
                                m.unrefined_because.c_str());
            }
        }
    }
    for (const auto& b : measured.bars) {
        std::printf("bar %c: %.3f mm between its end ticks (+/- %.3f), commanded %.3f\n", b.tower,
                    b.measured_mm, b.sigma_mm, b.commanded_mm);
    }
    if (const auto overlay = args.get("--overlay"))
        write_output_file(*overlay,
                          firmware::delta_overlay_png(views.front(), measured, camera, plane));
    return 0;
}

int measure_galvo(const Args& args) {
    const std::string out = args.require("-o");
    const auto [camera, plane, machine] = read_set_up(args);
    modes::GalvoMeasureSettings settings;
    const double grid = args.number("--grid", 31);
    if (grid != std::floor(grid)) throw UsageError("--grid must be a whole number");
    settings.target.grid_count = static_cast<int>(grid);
    const cv::Mat image = load_gray_image(args.positional()[0]);
    auto measured = modes::measure_galvo(machine, camera, plane, view_of(image), settings);
    measured.photos = args.positional();
    write_output_file(out, modes::galvo_measurements_to_json(measured));
    double sigma = 0;
    for (const auto& n : measured.nodes) sigma = std::max(sigma, n.sigma_mm);
    std::printf(
        "%s: %zu of %d marks measured (%s marks), %zu missing, %zu extra blobs; largest "
        "uncertainty %.5f mm\n",
        out.c_str(), measured.nodes.size(), measured.grid_count * measured.grid_count,
        measured.dark_marks ? "dark" : "light", measured.missing.size(), measured.extra_mm.size(),
        sigma);
    for (const auto& m : measured.missing)
        std::printf("  missing: column %d row %d\n", m.column, m.row);
    if (const auto overlay = args.get("--overlay"))
        write_output_file(*overlay, firmware::galvo_overlay_png(view_of(image), measured, machine,
                                                                camera, plane));
    return 0;
}

int measure_planar(const Args& args) {
    const std::string out = args.require("-o");
    const auto [camera, plane, machine] = read_set_up(args);
    modes::PlanarMeasureSettings settings;
    if (args.get("--design")) {
        const double n = args.number("--design", 0);
        if (n != std::floor(n) || n < 1) throw UsageError("--design must be a whole number");
        settings.target.only_nodes =
            modes::planar_design_nodes(machine, static_cast<std::size_t>(n));
    }
    std::vector<geometry::Point2> offsets(args.positional().size());
    if (const auto text = args.get("--offsets")) {
        offsets.clear();
        std::size_t start = 0;
        while (start <= text->size()) {
            const std::size_t end = std::min(text->find(';', start), text->size());
            const std::string pair = text->substr(start, end - start);
            double x = 0, y = 0;
            char tail = 0;
            if (std::sscanf(pair.c_str(), "%lf,%lf%c", &x, &y, &tail) != 2 || !std::isfinite(x) ||
                !std::isfinite(y))
                throw UsageError("--offsets takes X,Y pairs separated by ';', not '" + pair + "'");
            offsets.push_back({x, y});
            start = end + 1;
        }
        if (offsets.size() != args.positional().size())
            throw UsageError("--offsets gives " + std::to_string(offsets.size()) +
                             " positions for " + std::to_string(args.positional().size()) +
                             " photos");
    } else if (args.positional().size() > 1) {
        throw UsageError("several photos need --offsets: where the machine put the camera");
    }
    std::vector<cv::Mat> images;
    for (const auto& path : args.positional()) images.push_back(load_gray_image(path));
    std::vector<modes::PlanarView> views;
    for (std::size_t i = 0; i < images.size(); ++i)
        views.push_back({view_of(images[i]), offsets[i]});
    const cv::Mat& image = images.front();
    auto measured = modes::measure_planar_views(machine, camera, plane, views, settings);
    measured.photos = args.positional();
    write_output_file(out, modes::planar_measurements_to_json(measured));
    double sigma = 0;
    for (const auto& h : measured.holes) sigma = std::max(sigma, h.sigma_mm);
    std::printf(
        "%s: %zu holes measured, %zu missing, %zu extra blobs%s; largest uncertainty "
        "%.5f mm\n",
        out.c_str(), measured.holes.size(), measured.missing.size(), measured.extra_mm.size(),
        measured.mirrored ? " (the photo's frame mirrored)" : "", sigma);
    for (const auto& m : measured.missing)
        std::printf("  missing: column %d row %d\n", m.column, m.row);
    if (const auto overlay = args.get("--overlay"))
        write_output_file(*overlay, firmware::planar_overlay_png(view_of(image), measured, machine,
                                                                 camera, plane));
    return 0;
}

}  // namespace

std::vector<Command> measure_commands() {
    const Option camera{"--camera", "camera.yaml", "the camera's calibration", Given::required};
    const Option plane{"--plane", "plane.yaml", "the bed plane", Given::required};
    const Option out{"-o", "measurements.json", "the measurements, written", Given::required};
    return {
        {"measure delta",
         "the delta's printed target in photos",
         {camera,
          plane,
          {"--machine", "printer.toml", "the delta's machine file", Given::required},
          {"IMAGES", "", "photos of the printed target", Given::words},
          out,
          {"--overlay", "overlay.png", "the first photo with what was found drawn on it"},
          {"--bed-temperature", "C", "the bed's temperature when the photos were taken"}},
         R"(Finds the delta target's markers in the photos (the target is regenerated from the machine
file), refines their corners, maps them to the bed and moves each along its ray to the
printed surface's height (from a fit of the corners), and writes each corner's commanded
and measured position with its uncertainty. Several photos are averaged. The three bars
are measured between the centrelines of the single strands across their ends. --bed-temperature: the
bed's temperature when the photos were taken (default: the machine file's
photo_bed_temperature_c), if not the bed_temperature_c it printed at; the print has grown or shrunk with the bed (bed_material) and positions are
given as printed. --overlay draws on the first photo what was found, each corner's error
after the best rotation and translation, magnified 10 to 1000 times (the factor is written
on the picture), and each bar with its length and its difference from the commanded one.)",
         measure_delta},
        {"measure galvo",
         "the burned circle grid in a photo",
         {camera,
          plane,
          {"--machine", "scanner.toml", "the scanner's machine file", Given::required},
          {"PHOTO", "", "the photo of the burned grid", Given::word},
          out,
          {"--grid", "N", "circles a side, as the grid was made (default 31)"},
          {"--overlay", "overlay.png", "the photo with what was found drawn on it"}},
         R"(Finds the burned circle grid (the target is regenerated from the machine file; --grid as
it was made, default 31): dark marks on a light substrate or light on dark, a median
filter against soot, each mark's centre from fixed-point moments, mapped to the bed at
the substrate's height ([galvo] substrate_height_mm). The grid is indexed by growing it
from its middle mark and turned the way its large marks say; misfired marks are listed
as missing, spatter and damaged marks as extra, and neither stops the measurement. Writes
each mark's commanded centre, where it was measured and its uncertainty. --overlay marks
on the photo the marks used (green), the extra blobs (orange) and each mark's index.)",
         measure_galvo},
        {"measure planar",
         "the drilled or printed hole grid in photos",
         {camera,
          plane,
          {"--machine", "machine.toml", "the machine file", Given::required},
          {"PHOTOS", "", "photos of the sheet", Given::words},
          out,
          {"--offsets", "X,Y;X,Y...", "where the machine put the camera for each photo (mm)"},
          {"--design", "N", "the number of holes, as the grid was made"},
          {"--overlay", "overlay.png", "the first photo with what was found drawn on it"}},
         R"(Finds the drilled (or printed) hole grid (the target is regenerated from the machine file;
--design as it was made): each hole's centre from fixed-point moments, mapped to the bed at
the sheet's top ([planar] surface_height_mm); the grid placed by its two large holes (all
four ways round are tried) and every hole matched where the placement puts it. Holes with
a chip or a burr (elongated, or 5 % off their kind's size) are listed as extra and their
node as missing; two holes where the grid has one, a photo of another grid, or one that
shows under three quarters of it: one line, nothing written. A sheet larger than one view:
several photos from a camera the machine carries, --offsets giving where the machine put
it for each (machine mm; the first photo shows the two large holes and is the one --plane
was taken from). The offsets only say which hole is which; the photos are stitched through
the holes they share (each photo's rotation and shift fitted), so the machine's own errors
in moving the camera do not enter. --overlay marks, on the first photo, the holes used
(green), the extra blobs (orange) and the large holes' indices.)",
         measure_planar},
    };
}

}  // namespace calbox::cli
