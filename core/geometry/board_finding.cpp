// Finding a calibration board in a photo: a chessboard (with the corners a glare washed out set
// aside), a grid of dots (dark or bright), or a ChArUco board.
#include <algorithm>
#include <cmath>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "core/geometry/calibration.hpp"
#include "core/geometry/cv_convert.hpp"

namespace calbox::geometry {
namespace {

// A chessboard reads the same turned half a turn, except for its colours: the first inner corner
// is the one with a black square diagonally outside it (as OpenCV draws and the twin renders
// boards). Without this the bed frame could come out turned by 180 degrees.
void put_black_corner_first(const cv::Mat& gray, const PatternSpec& pattern,
                            std::vector<cv::Point2f>& corners) {
    const cv::Point2f first = corners[0];
    const cv::Point2f along = corners[1] - first;
    const cv::Point2f down = corners[static_cast<std::size_t>(pattern.columns)] - first;
    const auto level = [&](cv::Point2f p) {
        cv::Mat patch;
        cv::getRectSubPix(gray, cv::Size(3, 3), p, patch);
        return cv::mean(patch)[0];
    };
    const double outside = level(first - 0.5f * along - 0.5f * down);
    const double beside = level(first + 0.5f * along - 0.5f * down);
    if (outside > beside) std::reverse(corners.begin(), corners.end());
}

// The mean distance between neighbours along the board's rows, in pixels.
double corner_spacing_px(const std::vector<cv::Point2f>& corners, int columns) {
    double spacing = 0;
    int pairs = 0;
    const auto per_row = static_cast<std::size_t>(columns);
    for (std::size_t i = 0; i + 1 < corners.size(); ++i) {
        if ((i + 1) % per_row == 0) continue;  // a row's last corner and the next row's first
        spacing += cv::norm(corners[i + 1] - corners[i]);
        ++pairs;
    }
    return spacing / std::max(1, pairs);
}

// The share of an image's pixels at or above `clipped_from_dn`.
double clipped_share(const cv::Mat& gray, int clipped_from_dn) {
    return cv::countNonZero(gray >= clipped_from_dn) / static_cast<double>(gray.total());
}

int refine_half_window_px(const ChessboardSearch& search, double spacing_px) {
    return std::clamp(static_cast<int>(std::lround(search.refine_window_share * spacing_px)),
                      search.refine_window_min_px, search.refine_window_max_px);
}

// A corner's contrast over its refinement window: the brightest quarter's mean less the darkest
// quarter's, as a share of the brightest's (so that light falling off across the board or a
// vignette, which scale both, leave it as it is); 1 when nothing in the window is clipped white
// (a corner is washed out only by a glare: a blurred or distant corner's low contrast is not).
double glared_contrast(const cv::Mat& gray, cv::Point2f corner, int half_window,
                       int clipped_from_dn) {
    const cv::Rect window(static_cast<int>(std::lround(corner.x)) - half_window,
                          static_cast<int>(std::lround(corner.y)) - half_window,
                          2 * half_window + 1, 2 * half_window + 1);
    const cv::Rect inside = window & cv::Rect(0, 0, gray.cols, gray.rows);
    if (inside.area() < 4) return 0;
    std::vector<std::uint8_t> levels;
    levels.reserve(static_cast<std::size_t>(inside.area()));
    for (int v = inside.y; v < inside.y + inside.height; ++v) {
        const std::uint8_t* row = gray.ptr<std::uint8_t>(v);
        levels.insert(levels.end(), row + inside.x, row + inside.x + inside.width);
    }
    std::sort(levels.begin(), levels.end());
    if (levels.back() < clipped_from_dn) return 1;
    const std::size_t quarter = levels.size() / 4;
    double dark = 0, bright = 0;
    for (std::size_t i = 0; i < quarter; ++i) {
        dark += levels[i];
        bright += levels[levels.size() - 1 - i];
    }
    return bright > 0 ? (bright - dark) / bright : 0;
}

// The corners a glare washed out, by index: those beside clipped white whose contrast is under
// the allowed share of the board's best corners' (the tenth from the top; a corner with nothing
// clipped counts as 1). Under the lamp's reflection the dark squares rise towards the clipped
// white and the saddle is pulled towards the brighter side; a board merely over-exposed keeps its
// corners (its dark squares stay dark), and a blurred or distant one, clipped nowhere, all of
// them.
std::vector<std::size_t> washed_out(const cv::Mat& gray, const std::vector<cv::Point2f>& corners,
                                    int half_window, const ChessboardSearch& search) {
    std::vector<double> contrast;
    contrast.reserve(corners.size());
    for (const auto& c : corners)
        contrast.push_back(glared_contrast(gray, c, half_window, search.clipped_from_dn));
    std::vector<double> sorted = contrast;
    std::sort(sorted.begin(), sorted.end());
    const double best = sorted[sorted.size() - 1 - sorted.size() / 10];
    std::vector<std::size_t> out;
    for (std::size_t i = 0; i < contrast.size(); ++i)
        if (contrast[i] < search.washed_out_contrast_share * best) out.push_back(i);
    return out;
}

// The chessboard's inner corners in OpenCV's order (rows of columns), or empty; `detector`
// says which found them.
std::vector<cv::Point2f> find_chessboard_corners(const cv::Mat& gray, const PatternSpec& pattern,
                                                 const ChessboardSearch& search,
                                                 std::string& detector) {
    const cv::Size size(pattern.columns, pattern.rows);
    const int long_side = std::max(gray.cols, gray.rows);
    const int factor =
        std::max(1, (long_side + search.max_search_side_px - 1) / search.max_search_side_px);
    cv::Mat reduced = gray;
    if (factor > 1)
        cv::resize(gray, reduced, cv::Size(), 1.0 / factor, 1.0 / factor, cv::INTER_AREA);
    // At full size SB's own accuracy pass is affordable and best; reduced, the corners are
    // refined at full resolution below instead.
    const int accuracy = factor == 1 ? cv::CALIB_CB_ACCURACY : 0;
    std::vector<cv::Point2f> corners;
    bool refine = factor > 1;
    if (cv::findChessboardCornersSB(reduced, size, corners, accuracy)) {
        detector = "sb";
    } else if (cv::findChessboardCornersSB(reduced, size, corners,
                                           accuracy | cv::CALIB_CB_NORMALIZE_IMAGE)) {
        detector = "sb-normalized";
    } else {
        // The box's lamp mirrored by a laminated board washes out the squares under it: there
        // they keep a few tens of counts of contrast, which a global normalisation cannot lift
        // beside the rest of the board. Equalised tile by tile (each tile's own histogram, the
        // tiles blended), they show again; the corners found there are refined on the photo.
        // Only where there is a glare to see through (and, below, only a board under it).
        if (!(clipped_share(reduced, search.clipped_from_dn) > search.glare_clipped_share))
            return {};
        // A broad reflection (a camera far above a large laminated board) leaves the squares
        // under it a few tens of counts apart over a third of the board: tiles twice as fine,
        // allowed twice the contrast, see them where the first equalisation does not.
        bool found = false;
        for (const auto& [tiles, clip] :
             {std::pair{search.equalize_tiles, search.equalize_clip_limit},
              std::pair{2 * search.equalize_tiles, 2 * search.equalize_clip_limit}}) {
            cv::Mat equalized;
            cv::createCLAHE(clip, cv::Size(tiles, tiles))->apply(reduced, equalized);
            if (cv::findChessboardCornersSB(equalized, size, corners, cv::CALIB_CB_EXHAUSTIVE)) {
                found = true;
                break;
            }
        }
        if (!found) return {};
        detector = "sb-equalized";
        refine = true;
    }
    if (!refine) return corners;
    // A reduced image's corner, at full resolution: OpenCV's pixel centres are at integers, so
    // a reduced pixel's centre k lies at factor * k + (factor - 1) / 2.
    const float offset = static_cast<float>(factor - 1) / 2;
    for (auto& c : corners) c = c * static_cast<float>(factor) + cv::Point2f(offset, offset);
    const int half_window =
        refine_half_window_px(search, corner_spacing_px(corners, pattern.columns));
    cv::cornerSubPix(gray, corners, cv::Size(half_window, half_window), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 0.001));
    return corners;
}

std::optional<BoardObservation> find_chessboard(const cv::Mat& gray, const PatternSpec& pattern,
                                                const ChessboardSearch& search) {
    BoardObservation obs;
    auto corners = find_chessboard_corners(gray, pattern, search, obs.detector);
    if (corners.empty()) return std::nullopt;
    put_black_corner_first(gray, pattern, corners);
    const auto set_aside = washed_out(
        gray, corners, refine_half_window_px(search, corner_spacing_px(corners, pattern.columns)),
        search);
    // A board found only once equalised must lie under the glare that called for it:
    // elsewhere the equalised image makes grids of whatever it finds (on one of BoofCV's
    // fisheye views, bright screens beside the board, it put a 4x6 grid across the wrong
    // squares).
    if (obs.detector == "sb-equalized" && set_aside.empty()) return std::nullopt;
    for (int r = 0; r < pattern.rows; ++r) {
        for (int c = 0; c < pattern.columns; ++c) {
            const auto index =
                static_cast<std::size_t>(r) * static_cast<std::size_t>(pattern.columns) +
                static_cast<std::size_t>(c);
            const auto& p = corners[index];
            if (std::binary_search(set_aside.begin(), set_aside.end(), index)) {
                obs.set_aside_ids.push_back(r * pattern.columns + c);
                continue;
            }
            obs.image_points.push_back({p.x, p.y});
            obs.object_points.push_back({c * pattern.square_mm, r * pattern.square_mm, 0});
            obs.ids.push_back(r * pattern.columns + c);
        }
    }
    return obs;
}

std::optional<BoardObservation> find_circle_grid(const cv::Mat& gray, const PatternSpec& pattern) {
    BoardObservation obs;
    std::vector<cv::Point2f> centres;
    const cv::Size size(pattern.columns, pattern.rows);
    const int flags = pattern.kind == PatternSpec::Kind::acircles ? cv::CALIB_CB_ASYMMETRIC_GRID
                                                                  : cv::CALIB_CB_SYMMETRIC_GRID;
    cv::SimpleBlobDetector::Params blobs;
    blobs.minArea = 10;
    // OpenCV's default 5000 px^2 is too small for dots seen at 0.07 mm/px; unbounded, the
    // grey surroundings of the board become blobs too. A dot is far smaller than its share.
    blobs.maxArea =
        static_cast<float>(gray.total()) / static_cast<float>(4 * pattern.columns * pattern.rows);
    const auto detector = cv::SimpleBlobDetector::create(blobs);
    bool found = cv::findCirclesGrid(gray, size, centres, flags, detector);
    obs.detector = "circles";
    if (!found) {
        // Bright dots on a dark ground (burned or printed in white): look at the negative.
        cv::Mat negative;
        cv::bitwise_not(gray, negative);
        found = cv::findCirclesGrid(negative, size, centres, flags, detector);
        obs.detector = "circles-negative";
    }
    if (!found) return std::nullopt;
    for (int r = 0; r < pattern.rows; ++r) {
        for (int c = 0; c < pattern.columns; ++c) {
            const auto& p =
                centres[static_cast<std::size_t>(r) * static_cast<std::size_t>(pattern.columns) +
                        static_cast<std::size_t>(c)];
            const double x = pattern.kind == PatternSpec::Kind::acircles
                                 ? (2 * c + r % 2) * pattern.square_mm
                                 : c * pattern.square_mm;
            obs.image_points.push_back({p.x, p.y});
            obs.object_points.push_back({x, r * pattern.square_mm, 0});
            obs.ids.push_back(r * pattern.columns + c);
        }
    }
    return obs;
}

std::optional<BoardObservation> find_charuco(const cv::Mat& gray, const PatternSpec& pattern) {
    BoardObservation obs;
    const auto dictionary =
        cv::aruco::getPredefinedDictionary(aruco_dictionary_id(pattern.dictionary));
    const auto board = cv::aruco::CharucoBoard::create(
        pattern.columns, pattern.rows, static_cast<float>(pattern.square_mm),
        static_cast<float>(pattern.marker_mm), dictionary);
    std::vector<std::vector<cv::Point2f>> marker_corners;
    std::vector<int> marker_ids;
    cv::aruco::detectMarkers(gray, dictionary, marker_corners, marker_ids);
    if (marker_ids.empty()) return std::nullopt;
    std::vector<cv::Point2f> corners;
    std::vector<int> ids;
    cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, gray, board, corners, ids);
    if (ids.size() < 6) return std::nullopt;
    obs.detector = "charuco";
    for (std::size_t i = 0; i < ids.size(); ++i) {
        const auto& o = board->chessboardCorners[static_cast<std::size_t>(ids[i])];
        obs.image_points.push_back({corners[i].x, corners[i].y});
        obs.object_points.push_back({o.x, o.y, o.z});
        obs.ids.push_back(ids[i]);
    }
    return obs;
}

}  // namespace

std::optional<BoardObservation> find_board(const PatternSpec& pattern,
                                           const vision::GrayView& image,
                                           const ChessboardSearch& search) {
    const cv::Mat gray = to_cv(image);
    if (pattern.kind == PatternSpec::Kind::chessboard)
        return find_chessboard(gray, pattern, search);
    if (pattern.is_circles()) return find_circle_grid(gray, pattern);
    if (pattern.kind != PatternSpec::Kind::charuco) {
        throw CalibrationError(
            "an ArUco grid is not a calibration board; use a chessboard, ChArUco board or dot "
            "grid");
    }
    return find_charuco(gray, pattern);
}

std::string board_not_found(const PatternSpec& pattern, const vision::GrayView& image,
                            const ChessboardSearch& search) {
    std::string why = "the board " +
                      std::string(pattern.kind == PatternSpec::Kind::chessboard ? "chessboard"
                                                                                : "ChArUco board") +
                      " was not found in the image";
    // Over a twentieth of the photo clipped white: the likeliest cause is the lamp's glare.
    const double clipped = clipped_share(to_cv(image), search.clipped_from_dn);
    if (clipped > 0.05)
        why += "; " + std::to_string(static_cast<int>(std::lround(100 * clipped))) +
               " % of it is clipped white: tilt the board or diffuse the lamp's light";
    return why;
}

}  // namespace calbox::geometry
