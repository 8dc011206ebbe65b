#include "firmware/console/bed_photo_desk.hpp"

#include <charconv>
#include <exception>

#include "core/geometry/calibration.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/modes/planar.hpp"
#include "core/modes/stock.hpp"
#include "core/number_text.hpp"
#include "firmware/console/job_desk.hpp"
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
};

BedPhotoDesk::BedPhotoDesk(EventLoop& loop, Cycle& cycle, hal::Storage& data, Notice notice)
    : cycle_(cycle), data_(data), notice_(std::move(notice)), worker_(loop) {
    news_ = cycle_.subscribe({{}, {}, {}, {}, [this](const hal::Frame& f) { on_frame(f); }});
}

BedPhotoDesk::~BedPhotoDesk() = default;

std::string BedPhotoDesk::start(std::optional<double> surface_height_mm) {
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
    order->surface_height_mm = surface_height_mm.value_or(machine.planar->surface_height_mm);
    if (!cycle_.preview()) return "bed photo: the camera is busy: try again in a moment";
    waiting_ = std::move(order);
    return {};
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
    auto files = std::make_shared<std::optional<std::pair<std::string, std::string>>>();
    auto refused = std::make_shared<std::string>();
    auto sheet = std::make_shared<std::optional<modes::StockOutline>>();
    auto no_sheet = std::make_shared<std::string>();
    worker_.start(
        [order, photo, files, refused, sheet, no_sheet] {
            // A sheet on the bed is found as `calbox view stock` finds it; a bed without one (or
            // one the camera cannot tell) is a photo still.
            try {
                *sheet =
                    modes::find_stock(order->camera, order->plane, photo->photo.view(),
                                      order->solution, order->surface_height_mm, "the bed photo");
            } catch (const modes::StockError& e) {
                *no_sheet = e.what();
            }
            *files = bed_view_files(*photo, order->solution, order->surface_height_mm, *refused,
                                    *sheet ? &**sheet : nullptr);
        },
        [this, order, files, refused, sheet, no_sheet](const std::exception_ptr& error) {
            try {
                if (error) std::rethrow_exception(error);
                if (!*files) {
                    notice_("bed photo: " + *refused + "; nothing written");
                    return;
                }
                // The world file first: a page that reads the new picture finds its place.
                data_.replace_file(kBedViewWorld, (*files)->second);
                data_.replace_file(kBedViewPng, (*files)->first);
                // The sheet of this photo or none: one from an earlier photo may be gone from the
                // bed, and a job placed by it would be cut where nothing lies.
                if (*sheet)
                    data_.replace_file(
                        kFoundStockFile,
                        modes::stock_to_json(**sheet, order->solution.machine_fingerprint));
                else
                    data_.remove_file(kFoundStockFile);
            } catch (const std::exception& e) {
                notice_(std::string("bed photo: ") + e.what() + "; nothing written");
                return;
            }
            std::string line = std::string("bed photo: ") + kBedViewPng + " and " + kBedViewWorld +
                               ": the bed now, the surface " +
                               number_text("%.2f", order->surface_height_mm) + " mm above it; ";
            if (*sheet) {
                const auto& front_left = (*sheet)->corners[0];
                line += std::string("the sheet found (") + kFoundStockFile +
                        "): its front-left corner at machine X" +
                        number_text("%.3f", front_left.machine_mm.x) + " Y" +
                        number_text("%.3f", front_left.machine_mm.y) + " mm (+/-" +
                        number_text("%.3f", front_left.sigma_mm) + "), turned " +
                        number_text("%.3f", (*sheet)->rotation_deg) + " deg";
            } else {
                line += "no sheet told: " + *no_sheet;
            }
            notice_(line);
        });
}

ConsoleCommand BedPhotoDesk::command() {
    return {"bed photo", "bed photo [SURFACE_MM]",
            "a photo of the bed now, in the machine's coordinates through the correction in force "
            "(bed-view.png and its world file bed-view.pgw, shown on the page's Place screen); "
            "SURFACE_MM: the height seen above the bed, the stock's top (default: the machine "
            "file's)",
            [this](const std::vector<std::string>& words, std::string_view, ConsoleReply& reply) {
                std::optional<double> surface;
                std::vector<std::string> given;
                for (std::size_t i = 2; i < words.size(); ++i)
                    if (words[i] != "--json") given.push_back(words[i]);
                if (given.size() > 1) throw ConsoleRefused("usage: bed photo [SURFACE_MM]");
                if (!given.empty()) {
                    double v = 0;
                    const auto& w = given.front();
                    const auto [end, ec] = std::from_chars(w.data(), w.data() + w.size(), v);
                    if (ec != std::errc() || end != w.data() + w.size() || !(v >= 0) || v > 200)
                        throw ConsoleRefused("bed photo: '" + w +
                                             "' is not a height in millimetres (0 to 200): the "
                                             "stock's top above the bed");
                    surface = v;
                }
                const std::string refused = start(surface);
                if (!refused.empty()) throw ConsoleRefused(refused);
                reply.text = "photographing the bed";
                reply.data = {{"png", kBedViewPng}, {"world_file", kBedViewWorld}};
            }};
}

}  // namespace calbox::firmware
