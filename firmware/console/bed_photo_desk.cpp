#include "firmware/console/bed_photo_desk.hpp"

#include <algorithm>
#include <charconv>
#include <exception>

#include "core/geometry/calibration.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/modes/compensate_job.hpp"
#include "core/modes/planar.hpp"
#include "core/modes/registration.hpp"
#include "core/modes/stock.hpp"
#include "core/modes/stock_top.hpp"
#include "core/number_text.hpp"
#include "firmware/console/job_desk.hpp"
#include "firmware/console/stock_probe_desk.hpp"
#include "firmware/cycle/photos.hpp"
#include "firmware/modes/planar_mode.hpp"

namespace calbox::firmware {

constexpr const char* kBedViewPng = "bed-view.png";
constexpr const char* kBedViewWorld = "bed-view.pgw";

struct BedPhotoDesk::Order {
    modes::PlanarSolution solution;
    geometry::CameraModel camera;
    geometry::BedPlane plane;
    double surface_height_mm = 0;
    std::string surface_from;  // "given", "the machine file's", or the probe's file
    // `marks ...`: a printed drawing's registration marks looked for too (print and cut).
    std::optional<modes::RegistrationRequest> marks;
};

BedPhotoDesk::BedPhotoDesk(EventLoop& loop, Cycle& cycle, hal::Storage& data, Notice notice)
    : cycle_(cycle), data_(data), notice_(std::move(notice)), worker_(loop) {
    news_ = cycle_.subscribe({{}, {}, {}, {}, [this](const hal::Frame& f) { on_frame(f); }});
}

BedPhotoDesk::~BedPhotoDesk() = default;

// The height seen above the bed: the one given, else the stock's top the machine's probe
// measured (stock-top.json), else the machine file's.
std::pair<double, std::string> BedPhotoDesk::surface_height(std::optional<double> given,
                                                            const models::MachineFile& machine) {
    if (given) return {*given, "as given"};
    if (const auto probed = data_.read_file(kProbedStockTopFile))
        return {modes::stock_top_from_json(*probed, kProbedStockTopFile).surface_height_mm,
                std::string("probed, ") + kProbedStockTopFile};
    return {machine.planar->surface_height_mm, "the machine file's"};
}

std::string BedPhotoDesk::start(std::optional<double> surface_height_mm,
                                std::optional<modes::RegistrationRequest> marks) {
    if (waiting_ || worker_.busy()) return "bed photo: already taking one";
    if (cycle_.state() != CycleState::idle)
        return "bed photo: the camera is the cycle's until it ends (now " +
               std::string(state_name(cycle_.state())) + ")";
    const auto kept = cycle_.mode().kept_result_text();
    if (!kept)
        return "bed photo: no correction in force: the bed is put in the machine's coordinates "
               "through a planar result (calibrate the machine first)";
    auto order = std::make_unique<Order>();
    try {
        order->solution = modes::planar_result_from_json(*kept, "the correction in force");
        const auto camera = data_.read_file("camera.yaml");
        const auto plane = data_.read_file("plane.yaml");
        if (!camera || !plane)
            return std::string("bed photo: no ") + (camera ? "plane.yaml" : "camera.yaml") +
                   " in the data directory: the set-up makes it (run a cycle)";
        order->camera = geometry::camera_from_yaml(*camera);
        order->plane = geometry::plane_from_yaml(*plane);
    } catch (const std::exception& e) {
        return std::string("bed photo: ") + e.what();
    }
    const auto& machine = cycle_.machine();
    if (!machine.planar)
        return "bed photo: a " + machine.kind + " has no flat bed to place a job on";
    try {
        const auto [height, from] = surface_height(surface_height_mm, machine);
        order->surface_height_mm = height;
        order->surface_from = from;
    } catch (const std::exception& e) {
        return std::string("bed photo: ") + e.what();
    }
    if (marks) {
        marks->surface_height_mm = order->surface_height_mm;
        order->marks = std::move(marks);
    }
    if (!cycle_.preview()) return "bed photo: the camera is busy: try again in a moment";
    waiting_ = std::move(order);
    return {};
}

struct BedPhotoDesk::Developed {
    std::optional<std::pair<std::string, std::string>> files;
    std::string refused;
    std::optional<modes::StockOutline> sheet;
    std::string no_sheet;
    std::optional<modes::Registration> placed;
    std::string no_marks;
};

void BedPhotoDesk::develop(const Order& order, const BedPhoto& photo, Developed& developed) {
    // The printed marks, when asked for, as `calbox view marks` finds them; a photo
    // whose marks cannot be told keeps none, so that no job is placed by older ones.
    if (order.marks) {
        try {
            developed.placed = modes::register_marks(order.camera, order.plane, photo.photo.view(),
                                                     order.solution, *order.marks, "the bed photo");
        } catch (const modes::RegistrationError& e) {
            developed.no_marks = e.what();
        }
    }
    // A sheet on the bed is found as `calbox view stock` finds it; a bed without one (or
    // one the camera cannot tell) is a photo still.
    try {
        developed.sheet =
            modes::find_stock(order.camera, order.plane, photo.photo.view(), order.solution,
                              order.surface_height_mm, "the bed photo");
    } catch (const modes::StockError& e) {
        developed.no_sheet = e.what();
    }
    developed.files =
        bed_view_files(photo, order.solution, order.surface_height_mm, developed.refused,
                       developed.sheet ? &*developed.sheet : nullptr);
}

void BedPhotoDesk::keep(const Order& order, const Developed& developed) {
    // The world file first: a page that reads the new picture finds its place.
    data_.replace_file(kBedViewWorld, (developed.files)->second);
    data_.replace_file(kBedViewPng, (developed.files)->first);
    // The sheet of this photo or none: one from an earlier photo may be gone from the
    // bed, and a job placed by it would be cut where nothing lies.
    if (developed.sheet) {
        data_.replace_file(
            kFoundStockFile,
            modes::stock_to_json(*developed.sheet, order.solution.machine_fingerprint));
    } else {
        data_.remove_file(kFoundStockFile);
        // The probed top goes with the sheet it was probed on.
        data_.remove_file(kProbedStockTopFile);
    }
    if (developed.placed)
        data_.replace_file(
            kFoundMarksFile,
            modes::registration_to_json(*developed.placed, order.solution.machine_fingerprint));
    else
        data_.remove_file(kFoundMarksFile);
}

std::string BedPhotoDesk::notice_of(const Order& order, const Developed& developed) {
    std::string line = std::string("bed photo: ") + kBedViewPng + " and " + kBedViewWorld +
                       ": the bed now, the surface " +
                       number_text("%.3f", order.surface_height_mm) + " mm above it (" +
                       order.surface_from + "); ";
    if (developed.sheet) {
        const auto& front_left = (developed.sheet)->corners[0];
        line += std::string("the sheet found (") + kFoundStockFile +
                "): its front-left corner at machine X" +
                number_text("%.3f", front_left.machine_mm.x) + " Y" +
                number_text("%.3f", front_left.machine_mm.y) + " mm (+/-" +
                number_text("%.3f", front_left.sigma_mm) + "), turned " +
                number_text("%.3f", (developed.sheet)->rotation_deg) + " deg";
    } else {
        line += "no sheet told: " + developed.no_sheet;
    }
    if (developed.placed) {
        const auto& r = *developed.placed;
        line += std::string("; the drawing's marks found (") + kFoundMarksFile +
                "): " + std::to_string(r.marks.size()) + " marks, its zero at machine X" +
                number_text("%.3f", r.origin_mm.x) + " Y" + number_text("%.3f", r.origin_mm.y) +
                " mm, turned " + number_text("%.3f", r.rotation_deg) + " deg, scale " +
                number_text("%.5f", r.scale) + ", worst mark " +
                number_text("%.4f", r.worst_residual_mm) + " mm";
    } else if (order.marks) {
        line += "; no marks placed: " + developed.no_marks;
    }
    return line;
}

void BedPhotoDesk::on_frame(const hal::Frame& frame) {
    if (!waiting_) return;
    std::shared_ptr<Order> order = std::move(waiting_);
    if (const auto s =
            geometry::photo_size_mismatch(order->camera, frame.width_px, frame.height_px);
        !s.empty()) {
        notice_("bed photo: the camera's frame is " + s + " (camera.yaml); nothing written");
        return;
    }
    auto photo =
        std::make_shared<BedPhoto>(bed_photo_of(view_of(frame), order->camera, order->plane));
    auto developed = std::make_shared<Developed>();
    worker_.start([order, photo, developed] { develop(*order, *photo, *developed); },
                  [this, order, developed](const std::exception_ptr& error) {
                      try {
                          if (error) std::rethrow_exception(error);
                          if (!developed->files) {
                              notice_("bed photo: " + developed->refused + "; nothing written");
                              return;
                          }
                          keep(*order, *developed);
                      } catch (const std::exception& e) {
                          notice_(std::string("bed photo: ") + e.what() + "; nothing written");
                          return;
                      }
                      notice_(notice_of(*order, *developed));
                  });
}

namespace {

// A word that is a number from `least` to `most` (the stock's top above the bed, a mark's
// diameter, in millimetres), or nothing.
std::optional<double> number_in(const std::string& w, double least, double most) {
    double v = 0;
    const auto [end, ec] = std::from_chars(w.data(), w.data() + w.size(), v);
    if (ec != std::errc() || end != w.data() + w.size() || !(v >= least) || v > most)
        return std::nullopt;
    return v;
}

// `marks X,Y X,Y X,Y [X,Y] [diameter MM]`: the drawing's marks (filled circles) in its own
// frame, and their diameter (5 mm unless given).
modes::RegistrationRequest marks_of(const std::vector<std::string>& words) {
    modes::RegistrationRequest r;
    for (std::size_t i = 0; i < words.size(); ++i) {
        if (words[i] == "diameter") {
            const auto d = i + 2 == words.size() ? number_in(words[i + 1], 1, 50) : std::nullopt;
            if (!d) throw ConsoleRefused("bed photo: marks ... diameter MM (1 to 50), last");
            r.mark_diameter_mm = *d;
            break;
        }
        const auto mark = one_xy_of(words[i]);
        if (!mark)
            throw ConsoleRefused("bed photo: mark '" + words[i] +
                                 "' is not X,Y (its centre in the drawing's frame, mm)");
        r.marks_drawing_mm.push_back(*mark);
    }
    if (r.marks_drawing_mm.size() < 3 || r.marks_drawing_mm.size() > 4)
        throw ConsoleRefused("bed photo: marks: three or four X,Y, " +
                             std::to_string(r.marks_drawing_mm.size()) + " given");
    return r;
}

}  // namespace

ConsoleCommand BedPhotoDesk::command() {
    return {"bed photo", "bed photo [SURFACE_MM] [marks X,Y X,Y X,Y [X,Y] [diameter MM]]",
            "a photo of the bed now, in the machine's coordinates through the correction in force "
            "(bed-view.png and its world file bed-view.pgw, shown on the page's Place screen); "
            "SURFACE_MM: the height seen above the bed, the stock's top (default: the one `probe "
            "stock` measured, else the machine file's); marks: a printed drawing's registration "
            "marks (filled circles, their "
            "centres in the drawing's frame) found too, the drawing's place kept as marks.json "
            "for `compensate JOB marks`",
            [this](const std::vector<std::string>& words, std::string_view, ConsoleReply& reply) {
                std::vector<std::string> given;
                for (std::size_t i = 2; i < words.size(); ++i)
                    if (words[i] != "--json") given.push_back(words[i]);
                const auto marks_at = std::find(given.begin(), given.end(), "marks");
                std::optional<modes::RegistrationRequest> marks;
                if (marks_at != given.end()) {
                    marks = marks_of({marks_at + 1, given.end()});
                    given.erase(marks_at, given.end());
                }
                if (given.size() > 1)
                    throw ConsoleRefused(
                        "usage: bed photo [SURFACE_MM] [marks X,Y X,Y X,Y [X,Y] [diameter MM]]");
                std::optional<double> surface;
                if (!given.empty()) {
                    surface = number_in(given.front(), 0, 200);
                    if (!surface)
                        throw ConsoleRefused("bed photo: '" + given.front() +
                                             "' is not a height in millimetres (0 to 200): the "
                                             "stock's top above the bed");
                }
                const std::string refused = start(surface, std::move(marks));
                if (!refused.empty()) throw ConsoleRefused(refused);
                reply.text = "photographing the bed";
                reply.data = {{"png", kBedViewPng}, {"world_file", kBedViewWorld}};
            }};
}

}  // namespace calbox::firmware
