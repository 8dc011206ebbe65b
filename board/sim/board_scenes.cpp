// The twin's printed boards (BoardScene: chessboards, ChArUco boards, dot grids and ArUco grids)
// and the fixed reference stickers around the bed (ReferenceMarksScene), board/sim/scenes.hpp.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>
#include <stdexcept>

#include "board/sim/scene_sampling.hpp"
#include "board/sim/scenes.hpp"

namespace calbox::sim {

using namespace scene_sampling;

// ---------------------------------------------------------------------------------------------
// Boards

struct BoardScene::Layout {
    geometry::PatternSpec spec;
    Surroundings surroundings = Surroundings::grey;
    struct Marker {
        int id;
        Vec2 origin_mm;  // corner 0 (smallest x and y) in the board frame
        cv::Mat bits;    // 1 = white, row 0 along the marker's corners 0 and 1
        std::array<Vec3, 4> corners_mm;
    };
    std::map<std::pair<int, int>, Marker> markers;  // by square (charuco) or grid cell (aruco)
    int white_parity = 1;
    std::vector<Vec3> charuco_corners_mm;
    std::vector<Vec3> dot_centres_mm;
    double dot_radius_mm = 0;
    double cell_pitch_mm = 0;                 // aruco: marker plus gap
    double extent_x_mm = 0, extent_y_mm = 0;  // the pattern's own area, from the origin

    bool chessboard() const { return spec.kind == geometry::PatternSpec::Kind::chessboard; }

    // Board squares (chessboard, charuco), then a one-square white margin, then background.
    double square_albedo(int i, int j) const {
        const int columns = chessboard() ? spec.columns + 1 : spec.columns;
        const int rows = chessboard() ? spec.rows + 1 : spec.rows;
        const int first = chessboard() ? -1 : 0;
        const int ci = i - first, cj = j - first;
        if (ci >= 0 && cj >= 0 && ci < columns && cj < rows) {
            const int parity = ((i + j) % 2 + 2) % 2;
            if (chessboard()) return parity == 0 ? kBlack : kWhite;
            return parity == white_parity ? kWhite : kBlack;
        }
        if (ci >= -1 && cj >= -1 && ci <= columns && cj <= rows) return kWhite;  // margin
        return background(i, j);
    }

    // Beyond the paper, by board-square cell.
    double background(int i, int j) const {
        switch (surroundings) {
            case Surroundings::grey:
                return kBackground;
            case Surroundings::dark:
                return 0.03;
            case Surroundings::bright:
                return 0.95;
            case Surroundings::cluttered: {
                // A fixed hash of the cell: the same clutter in every view.
                auto h = static_cast<std::uint32_t>(i) * 73856093U ^
                         static_cast<std::uint32_t>(j) * 19349663U;
                h ^= h >> 13;
                h *= 0x5bd1e995U;
                h ^= h >> 15;
                return 0.05 + 0.85 * static_cast<double>(h % 1000U) / 999.0;
            }
        }
        return kBackground;
    }

    // White paper with a margin of `margin` around the pattern's area, on the background.
    bool on_paper(Vec2 p, double margin) const {
        return p.x >= -margin && p.y >= -margin && p.x <= extent_x_mm + margin &&
               p.y <= extent_y_mm + margin;
    }

    void add_marker(const cv::Ptr<cv::aruco::Dictionary>& dictionary, int id,
                    const std::vector<cv::Point3f>& c, std::pair<int, int> where) {
        Marker m;
        m.id = id;
        for (int n = 0; n < 4; ++n)
            m.corners_mm[static_cast<std::size_t>(n)] = Vec3{c[n].x, c[n].y, c[n].z};
        // OpenCV 4.6 lays a marker with corner 0 at its top-left, x along the marker's rows and
        // y down its columns (the board frame's y runs down the printed board).
        if (!(c[1].x > c[0].x && c[3].y > c[0].y && c[1].y == c[0].y && c[3].x == c[0].x)) {
            throw std::logic_error("unexpected ArUco board layout in this OpenCV version");
        }
        m.origin_mm = {c[0].x, c[0].y};
        m.bits = cv::aruco::Dictionary::getBitsFromByteList(
            dictionary->bytesList.rowRange(id, id + 1), dictionary->markerSize);
        markers.emplace(where, std::move(m));
    }
};

namespace {

double marker_albedo(const Footprint& f, const BoardScene::Layout::Marker& m, double marker_mm,
                     int s) {
    const int cells = m.bits.rows + 2;
    return grid_albedo(f, m.origin_mm, marker_mm / cells, s, [&](int ci, int cj) {
        if (ci < 0 || cj < 0 || ci >= cells || cj >= cells) return kWhite;
        if (ci == 0 || cj == 0 || ci == cells - 1 || cj == cells - 1) return kBlack;
        return m.bits.at<unsigned char>(cj - 1, ci - 1) != 0 ? kWhite : kBlack;
    });
}

}  // namespace

BoardScene::BoardScene(const geometry::PatternSpec& spec, int supersample,
                       Surroundings surroundings)
    : layout_(std::make_unique<Layout>()), supersample_(std::max(1, supersample)) {
    Layout& l = *layout_;
    l.spec = spec;
    l.surroundings = surroundings;
    using Kind = geometry::PatternSpec::Kind;
    if (spec.kind == Kind::chessboard) return;
    if (spec.is_circles()) {
        const double p = spec.square_mm;
        for (int r = 0; r < spec.rows; ++r) {
            for (int c = 0; c < spec.columns; ++c) {
                const double x = spec.kind == Kind::acircles ? (2 * c + r % 2) * p : c * p;
                l.dot_centres_mm.push_back(Vec3{x, r * p, 0});
                l.extent_x_mm = std::max(l.extent_x_mm, x);
            }
        }
        l.extent_y_mm = (spec.rows - 1) * p;
        l.dot_radius_mm = 0.25 * p;
        return;
    }
    const auto dictionary =
        cv::aruco::getPredefinedDictionary(geometry::aruco_dictionary_id(spec.dictionary));
    std::vector<std::vector<cv::Point3f>> marker_corners;
    std::vector<int> ids;
    if (spec.kind == Kind::charuco) {
        const auto board = cv::aruco::CharucoBoard::create(
            spec.columns, spec.rows, static_cast<float>(spec.square_mm),
            static_cast<float>(spec.marker_mm), dictionary);
        marker_corners = board->objPoints;
        ids = board->ids;
        for (const auto& p : board->chessboardCorners)
            l.charuco_corners_mm.push_back(Vec3{p.x, p.y, p.z});
    } else {
        const auto board = cv::aruco::GridBoard::create(
            spec.columns, spec.rows, static_cast<float>(spec.marker_mm),
            static_cast<float>(spec.gap_mm), dictionary);
        marker_corners = board->objPoints;
        ids = board->ids;
        l.cell_pitch_mm = spec.marker_mm + spec.gap_mm;
        l.extent_x_mm = spec.columns * l.cell_pitch_mm - spec.gap_mm;
        l.extent_y_mm = spec.rows * l.cell_pitch_mm - spec.gap_mm;
    }
    if (ids.empty() || ids.back() >= dictionary->bytesList.rows) {
        throw std::invalid_argument("the board needs more markers than " + spec.dictionary +
                                    " has");
    }
    for (std::size_t k = 0; k < ids.size(); ++k) {
        const auto& c = marker_corners[k];
        const double cx = (c[0].x + c[2].x) / 2, cy = (c[0].y + c[2].y) / 2;
        const double pitch = spec.kind == Kind::charuco ? spec.square_mm : l.cell_pitch_mm;
        const std::pair<int, int> where{static_cast<int>(std::floor(cx / pitch)),
                                        static_cast<int>(std::floor(cy / pitch))};
        if (spec.kind == Kind::charuco) l.white_parity = (where.first + where.second) % 2;
        l.add_marker(dictionary, ids[k], c, where);
    }
}

BoardScene::~BoardScene() = default;

double BoardScene::albedo(const Footprint& f) const {
    const Layout& l = *layout_;
    using Kind = geometry::PatternSpec::Kind;
    const Extent e = half_extent(f);
    const int s = supersample_;
    if (l.spec.kind == Kind::chessboard) {
        return grid_albedo(f, {0, 0}, l.spec.square_mm, s,
                           [&](int i, int j) { return l.square_albedo(i, j); });
    }
    if (l.spec.kind == Kind::charuco) {
        const double sq = l.spec.square_mm;
        const double gx = f.centre_mm.x / sq, gy = f.centre_mm.y / sq;
        const int i = static_cast<int>(std::floor(gx)), j = static_cast<int>(std::floor(gy));
        const bool near_square_edge = std::min(gx - i, i + 1 - gx) * sq < e.x_mm ||
                                      std::min(gy - j, j + 1 - gy) * sq < e.y_mm;
        const auto marker = l.markers.find({i, j});
        if (near_square_edge || marker == l.markers.end()) {
            return grid_albedo(f, {0, 0}, sq, s,
                               [&](int a, int b) { return l.square_albedo(a, b); });
        }
        return marker_albedo(f, marker->second, l.spec.marker_mm, s);
    }
    // Markers or dots on white paper with a margin of one pitch (or one gap plus a quarter marker).
    const double margin =
        l.spec.is_circles() ? l.spec.square_mm : l.spec.gap_mm + l.spec.marker_mm / 4;
    const double cell = l.spec.is_circles() ? l.spec.square_mm : l.cell_pitch_mm;
    const auto paper = [&](Vec2 q) {
        if (l.on_paper(q, margin)) return kWhite;
        return l.background(static_cast<int>(std::floor(q.x / cell)),
                            static_cast<int>(std::floor(q.y / cell)));
    };
    if (l.spec.kind == Kind::aruco) {
        // Cells split in the middle of the gaps, so a pixel on a marker's rim finds that marker.
        const double half_gap = l.spec.gap_mm / 2;
        const int i = static_cast<int>(std::floor((f.centre_mm.x + half_gap) / l.cell_pitch_mm));
        const int j = static_cast<int>(std::floor((f.centre_mm.y + half_gap) / l.cell_pitch_mm));
        const auto marker = l.markers.find({i, j});
        if (marker != l.markers.end()) return marker_albedo(f, marker->second, l.spec.marker_mm, s);
        return average_over_subpixels(f, s, paper);
    }
    // Dots: the nearest centre decides; its rim gets exact coverage.
    const auto nearest = [&](Vec2 q) {
        double best = std::numeric_limits<double>::infinity();
        Vec2 normal{1, 0};
        for (const auto& c : l.dot_centres_mm) {
            const double dx = q.x - c.x, dy = q.y - c.y;
            if (std::abs(dx) > 2 * l.spec.square_mm || std::abs(dy) > 2 * l.spec.square_mm)
                continue;
            const double d = std::hypot(dx, dy);
            if (d - l.dot_radius_mm < best) {
                best = d - l.dot_radius_mm;
                normal = d > 1e-12 ? Vec2{dx / d, dy / d} : Vec2{1, 0};
            }
        }
        return std::make_pair(best, normal);
    };
    const auto centre = nearest(f.centre_mm);
    const double reach = 2 * std::max(e.x_mm, e.y_mm);
    if (centre.first > reach) return average_over_subpixels(f, 1, paper);
    if (centre.first < -reach) return kBlack;
    return average_over_subpixels(f, s, [&](Vec2 q) {
        const auto n = nearest(q);
        const double dark = inside_fraction(n.first, n.second, f.jacobian, s);
        return dark * kBlack + (1 - dark) * paper(q);
    });
}

std::vector<BoardScene::Feature> BoardScene::features() const {
    const Layout& l = *layout_;
    std::vector<Feature> out;
    if (l.spec.kind == geometry::PatternSpec::Kind::chessboard) {
        for (int r = 0; r < l.spec.rows; ++r)
            for (int c = 0; c < l.spec.columns; ++c)
                out.push_back({r * l.spec.columns + c, -1,
                               Vec3{c * l.spec.square_mm, r * l.spec.square_mm, 0}});
        return out;
    }
    for (std::size_t k = 0; k < l.dot_centres_mm.size(); ++k)
        out.push_back({static_cast<int>(k), -1, l.dot_centres_mm[k]});
    for (std::size_t k = 0; k < l.charuco_corners_mm.size(); ++k)
        out.push_back({static_cast<int>(k), -1, l.charuco_corners_mm[k]});
    std::vector<const Layout::Marker*> by_id;
    for (const auto& [where, m] : l.markers) by_id.push_back(&m);
    std::sort(by_id.begin(), by_id.end(), [](auto* a, auto* b) { return a->id < b->id; });
    for (const auto* m : by_id)
        for (int n = 0; n < 4; ++n)
            out.push_back({m->id, n, m->corners_mm[static_cast<std::size_t>(n)]});
    return out;
}

namespace {
constexpr int kStickerMarginCells = 2;
}

double reference_sticker_half_side_mm(const std::string& dictionary, double marker_mm) {
    const int cells =
        cv::aruco::getPredefinedDictionary(geometry::aruco_dictionary_id(dictionary))->markerSize +
        2;
    return marker_mm / 2 + kStickerMarginCells * marker_mm / cells;
}

struct ReferenceMarksScene::Sticker {
    BoardScene::Layout::Marker marker;
    double half_side_mm;  // the sticker's: the marker and two cells of white around it
    Vec2 centre_mm;
};

ReferenceMarksScene::ReferenceMarksScene(const Scene& inner,
                                         const std::vector<ReferenceMark>& marks,
                                         const std::string& dictionary_name, double marker_mm,
                                         int supersample, const double inner_to_bed[2][2],
                                         Vec2 inner_origin_on_bed)
    : inner_(inner),
      marker_mm_(marker_mm),
      supersample_(std::max(1, supersample)),
      a_{{inner_to_bed[0][0], inner_to_bed[0][1]}, {inner_to_bed[1][0], inner_to_bed[1][1]}},
      b_(inner_origin_on_bed) {
    const auto dictionary =
        cv::aruco::getPredefinedDictionary(geometry::aruco_dictionary_id(dictionary_name));
    const int cells = dictionary->markerSize + 2;
    for (const auto& m : marks) {
        if (m.id >= dictionary->bytesList.rows)
            throw std::invalid_argument("more reference marks than " + dictionary_name + " has");
        Sticker s;
        s.marker.id = m.id;
        s.marker.origin_mm = {0, 0};
        s.marker.bits = cv::aruco::Dictionary::getBitsFromByteList(
            dictionary->bytesList.rowRange(m.id, m.id + 1), dictionary->markerSize);
        s.half_side_mm = marker_mm / 2 + kStickerMarginCells * marker_mm / cells;
        s.centre_mm = m.centre_mm;
        stickers_.push_back(std::move(s));
    }
}

ReferenceMarksScene::~ReferenceMarksScene() = default;

double ReferenceMarksScene::albedo(const Footprint& f) const {
    const Vec2 c{a_[0][0] * f.centre_mm.x + a_[0][1] * f.centre_mm.y + b_.x,
                 a_[1][0] * f.centre_mm.x + a_[1][1] * f.centre_mm.y + b_.y};
    for (const auto& s : stickers_) {
        if (std::abs(c.x - s.centre_mm.x) > s.half_side_mm ||
            std::abs(c.y - s.centre_mm.y) > s.half_side_mm)
            continue;
        // The marker's own frame (OpenCV's: y down the printed marker) lies face up on the bed,
        // its origin at the marker's corner of least x and greatest y.
        const double to_marker[2][2] = {{a_[0][0], a_[0][1]}, {-a_[1][0], -a_[1][1]}};
        Footprint on_marker = f;
        on_marker.centre_mm = {c.x - (s.centre_mm.x - marker_mm_ / 2),
                               (s.centre_mm.y + marker_mm_ / 2) - c.y};
        for (int col = 0; col < 2; ++col)
            for (int row = 0; row < 2; ++row)
                on_marker.jacobian[row][col] =
                    to_marker[row][0] * f.jacobian[0][col] + to_marker[row][1] * f.jacobian[1][col];
        return marker_albedo(on_marker, s.marker, marker_mm_, supersample_);
    }
    return inner_.albedo(f);
}

}  // namespace calbox::sim
