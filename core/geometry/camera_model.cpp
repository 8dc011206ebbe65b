#include "core/geometry/camera_model.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/persistence.hpp>
#include <string_view>
#include <vector>

#include "core/geometry/cv_convert.hpp"

namespace calbox::geometry {

std::vector<Point2> undistort_to_normalized(const CameraModel& camera,
                                            const std::vector<Point2>& pixels) {
    if (pixels.empty()) return {};
    const auto in = to_cv(pixels);
    std::vector<cv::Point2d> out;
    const cv::Mat k = camera_matrix_of(camera);
    if (camera.model == LensModel::fisheye) {
        cv::fisheye::undistortPoints(in, out, k, camera.distortion);
    } else {
        // Iterate well past OpenCV's default 5 steps: strong lenses need it for 1e-4 px.
        cv::undistortPoints(
            in, out, k, camera.distortion, cv::noArray(), cv::noArray(),
            cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
    }
    return from_cv(out);
}

std::vector<Point2> distort_from_normalized(const CameraModel& camera,
                                            const std::vector<Point2>& normalized) {
    std::vector<Point3> rays;
    rays.reserve(normalized.size());
    for (const auto& n : normalized) rays.push_back({n.x, n.y, 1.0});
    return project_points(camera, RigidPose{}, rays);
}

std::vector<Point2> project_points(const CameraModel& camera, const RigidPose& pose,
                                   const std::vector<Point3>& points) {
    if (points.empty()) return {};
    std::vector<cv::Point3d> in;
    in.reserve(points.size());
    for (const auto& p : points) in.emplace_back(p.x, p.y, p.z);
    const cv::Vec3d rvec(pose.rvec[0], pose.rvec[1], pose.rvec[2]);
    const cv::Vec3d tvec(pose.tvec_mm[0], pose.tvec_mm[1], pose.tvec_mm[2]);
    std::vector<cv::Point2d> out;
    if (camera.model == LensModel::fisheye) {
        cv::fisheye::projectPoints(in, out, rvec, tvec, camera_matrix_of(camera),
                                   camera.distortion);
    } else {
        cv::projectPoints(in, rvec, tvec, camera_matrix_of(camera), camera.distortion, out);
    }
    return from_cv(out);
}

const char* lens_model_name(LensModel model) {
    return model == LensModel::fisheye ? "fisheye" : "pinhole";
}

std::string photo_size_mismatch(const CameraModel& camera, int width_px, int height_px) {
    if (width_px == camera.image_width && height_px == camera.image_height) return {};
    return std::to_string(width_px) + "x" + std::to_string(height_px) +
           ", the camera was calibrated at " + std::to_string(camera.image_width) + "x" +
           std::to_string(camera.image_height);
}

std::string camera_to_yaml(const CameraModel& camera, const std::vector<double>& per_view_rms_px) {
    cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    fs << "model" << lens_model_name(camera.model);
    fs << "image_width" << camera.image_width;
    fs << "image_height" << camera.image_height;
    fs << "camera_matrix" << camera_matrix_of(camera);
    fs << "distortion_coefficients" << cv::Mat(camera.distortion, true).reshape(1, 1);
    fs << "rms" << camera.rms_px;
    if (!per_view_rms_px.empty()) fs << "per_view_rms" << per_view_rms_px;
    return fs.releaseAndGetString();
}

void rethrow_as_file_format_error() {
    try {
        throw;
    } catch (const FileFormatError&) {
        throw;
    } catch (const cv::Exception& e) {
        throw FileFormatError(std::string("corrupt YAML: ") + e.err);
    } catch (const std::exception& e) {
        throw FileFormatError(std::string("corrupt YAML: ") + e.what());
    }
}

namespace {

// The strict reader of the box's own YAML shapes, one line at a time; see check_yaml_text.
class YamlShape {
  public:
    void line(std::string_view text, int number) {
        number_ = number;
        if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
        if (!open_.empty()) {
            // A flow collection running on: indented, nothing but its own content.
            if (!text.empty() && text.front() != ' ')
                fail("a '" + std::string(1, open_.back()) + "' is never closed");
            flow(text);
            return;
        }
        std::size_t indent = 0;
        while (indent < text.size() && text[indent] == ' ') ++indent;
        const std::string_view rest = text.substr(indent);
        if (rest.empty() || rest.front() == '#') return;
        if (rest.find('\t') != std::string_view::npos && rest.find('\t') < rest.find('#'))
            fail("a tab; the box's files indent with spaces");
        if (indent == 0 && rest.substr(0, 3) == "---")
            fail("a second document; the file holds one");
        place(indent);
        const bool item = rest.front() == '-' && (rest.size() == 1 || rest[1] == ' ');
        Block& block = blocks_.back();
        if (block.kind == Kind::unknown) block.kind = item ? Kind::sequence : Kind::mapping;
        if ((block.kind == Kind::sequence) != item)
            fail("list items and keys mixed at one indentation");
        if (item) return sequence_item(rest.substr(1));
        seen_key_ = true;
        if (key_and_value(rest)) opened_at_line_ = number_;
    }

    // What follows a sequence item's "-": its value, or nothing (the item is a block below it).
    void sequence_item(std::string_view after) {
        if (after.empty() || trailing_comment(after))
            opened_at_line_ = number_;
        else
            value(after.substr(1));
    }

    void end() const {
        if (!open_.empty()) {
            throw FileFormatError("corrupt YAML: a '" + std::string(1, open_.back()) +
                                  "' is never closed");
        }
        if (opened_at_line_ != 0) {
            throw FileFormatError("corrupt YAML: line " + std::to_string(opened_at_line_) +
                                  ": a key without a value");
        }
    }

  private:
    [[noreturn]] void fail(const std::string& why) const {
        throw FileFormatError("corrupt YAML: line " + std::to_string(number_) + ": " + why);
    }

    static bool word_letter(char c) {
        return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '.' ||
               c == '+' || c == '-';
    }

    // `key:` then a value, or nothing (or OpenCV's matrix tag) for a block below it. Returns
    // whether it opened one.
    bool key_and_value(std::string_view text) {
        std::size_t i = 0;
        if (!(std::isalpha(static_cast<unsigned char>(text[0])) != 0 || text[0] == '_'))
            fail("a line that is not 'key: value'");
        while (i < text.size() &&
               (std::isalnum(static_cast<unsigned char>(text[i])) != 0 || text[i] == '_'))
            ++i;
        if (i == text.size() || text[i] != ':') fail("a line that is not 'key: value'");
        std::string_view after = text.substr(i + 1);
        if (after.empty() || trailing_comment(after)) return true;
        if (after.front() != ' ') fail("no space after a key's ':'");
        while (!after.empty() && after.front() == ' ') after.remove_prefix(1);
        if (after.substr(0, 15) == "!!opencv-matrix") {
            if (!after.substr(15).empty() && !trailing_comment(after.substr(15)))
                fail("text after '!!opencv-matrix'");
            matrix_rows_ = matrix_cols_ = 0;
            return true;
        }
        const std::string_view key = text.substr(0, i);
        if (key == "rows" || key == "cols") matrix_size(key == "rows", after);
        value(after);
        return false;
    }

    // OpenCV allocates a matrix for the size it declares before reading its values: a mangled
    // size would ask for gigabytes (libFuzzer found "cols: it1" asking for 48 GB). The box's
    // matrices are 3x3 and smaller; reference mark lists hold hundreds of rows.
    static constexpr long kMaxMatrixValues = 1L << 20;
    void matrix_size(bool rows, std::string_view text) {
        long count = 0;
        std::size_t i = 0;
        while (i < text.size() && text[i] >= '0' && text[i] <= '9')
            count = std::min(count * 10 + (text[i++] - '0'), kMaxMatrixValues + 1);
        if (i == 0 || count == 0 || !trailing_comment(text.substr(i)))
            fail(std::string("a matrix's ") + (rows ? "rows" : "cols") +
                 " that is not a positive whole number");
        (rows ? matrix_rows_ : matrix_cols_) = count;
        if (matrix_rows_ * std::max(matrix_cols_, 1L) > kMaxMatrixValues ||
            matrix_cols_ * std::max(matrix_rows_, 1L) > kMaxMatrixValues)
            fail("a matrix of more than " + std::to_string(kMaxMatrixValues) +
                 " values; the box's files hold small ones");
    }

    // Spaces and then at most a comment.
    static bool trailing_comment(std::string_view text) {
        std::size_t i = 0;
        while (i < text.size() && text[i] == ' ') ++i;
        return i == text.size() || (i > 0 && text[i] == '#');
    }

    // A plain word or number, quoted text, or a flow collection.
    void value(std::string_view text) {
        if (text.empty()) fail("a missing value");
        if (text.front() == '[' || text.front() == '{') {
            flow(text);
            return;
        }
        std::size_t i = 0;
        if (text.front() == '"' || text.front() == '\'') {
            i = quoted(text, 0);
        } else {
            while (i < text.size() && (word_letter(text[i]) || text[i] == ' ')) {
                if (text[i] == ' ' && i + 1 < text.size() && text[i + 1] == '#') break;
                ++i;
            }
            if (i == 0) fail("a value that is neither a word, a number, quoted text nor a list");
        }
        if (!trailing_comment(text.substr(i))) fail("unexpected text after a value");
    }

    // Index past the closing quote of the quoted text starting at `from`.
    std::size_t quoted(std::string_view text, std::size_t from) const {
        const char quote = text[from];
        for (std::size_t i = from + 1; i < text.size(); ++i) {
            if (text[i] == '\\' && quote == '"') {
                ++i;
            } else if (text[i] == quote) {
                return i + 1;
            }
        }
        fail("quoted text that does not close on its line");
    }

    // Flow content: words, numbers, quoted text, `key:` inside braces, commas, nested brackets.
    void flow(std::string_view text) {
        std::size_t i = 0;
        while (i < text.size()) {
            const char c = text[i];
            if (c == '[' || c == '{') {
                if (open_.size() >= 8) fail("lists nested deeper than the box's files nest them");
                open_.push_back(c);
                ++i;
            } else if (c == ']' || c == '}') {
                if (open_.empty() || open_.back() != (c == ']' ? '[' : '{'))
                    fail(std::string(1, '\'') + c + "' closes nothing open");
                open_.pop_back();
                ++i;
                if (open_.empty()) {
                    if (!trailing_comment(text.substr(i))) fail("unexpected text after a list");
                    return;
                }
            } else if (c == ' ' || c == ',') {
                ++i;
            } else if (c == '"' || c == '\'') {
                i = quoted(text, i);
            } else if (c == '#' && i > 0 && text[i - 1] == ' ') {
                return;
            } else if (word_letter(c)) {
                while (i < text.size() && word_letter(text[i])) ++i;
                if (i < text.size() && text[i] == ':') {
                    if (open_.back() != '{') fail("'key:' inside a list");
                    ++i;
                }
            } else {
                fail(std::string("'") + c + "' where a list's content was expected");
            }
        }
    }

    // Where this line's indentation puts it: in the block the line before opened (deeper), in
    // an open block (the same indentation as its lines), or nowhere.
    void place(std::size_t indent) {
        if (opened_at_line_ != 0) {
            if (indent <= blocks_.back().indent) {
                number_ = opened_at_line_;
                fail("a key without a value");
            }
            if (blocks_.size() >= 8) fail("blocks nested deeper than the box's files nest them");
            blocks_.push_back({indent, Kind::unknown});
            opened_at_line_ = 0;
            return;
        }
        while (blocks_.size() > 1 && indent < blocks_.back().indent) blocks_.pop_back();
        if (indent != blocks_.back().indent) {
            fail(seen_key_ ? "an indented line that belongs to no key"
                           : "the document does not start with a key");
        }
    }

    enum class Kind { unknown, mapping, sequence };
    struct Block {
        std::size_t indent;
        Kind kind;
    };
    int number_ = 0;
    bool seen_key_ = false;
    int opened_at_line_ = 0;  // the line of a key or item whose block has not started yet
    std::vector<Block> blocks_{{0, Kind::mapping}};
    std::string open_;                        // flow brackets still open, innermost last
    long matrix_rows_ = 0, matrix_cols_ = 0;  // of the last matrix opened, as declared so far
};

}  // namespace

void check_yaml_text(const std::string& text) {
    // OpenCV writes every file the box keeps with this header; without it a mangled first line
    // hides where the document starts.
    if (text.rfind("%YAML:1.0\n---", 0) != 0 && text.rfind("%YAML:1.0\r\n---", 0) != 0)
        throw FileFormatError("corrupt YAML: it does not start with '%YAML:1.0' and '---'");
    YamlShape shape;
    std::size_t start = 0;
    int number = 0;
    while (start <= text.size()) {
        const std::size_t stop = std::min(text.find('\n', start), text.size());
        ++number;
        std::string_view line(text.data() + start, stop - start);
        if (number == 2) {
            // The document marker line: nothing but '---' (and a comment).
            if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
            if (line.substr(0, 3) != "---" ||
                (line.size() > 3 &&
                 line.substr(3).find_first_not_of(' ') != std::string_view::npos &&
                 line[line.find_first_not_of(' ', 3)] != '#'))
                throw FileFormatError("corrupt YAML: line 2: text after '---'");
        } else if (number > 2) {
            shape.line(line, number);
        }
        if (stop == text.size()) break;
        start = stop + 1;
    }
    shape.end();
}

CameraModel camera_from_yaml(const std::string& text) {
    CameraModel c;
    try {
        check_yaml_text(text);
        cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
        if (!fs.isOpened()) throw FileFormatError("not an OpenCV YAML file");
        const auto node = [&](const char* key) {
            cv::FileNode n = fs[key];
            if (n.empty()) throw FileFormatError(std::string("missing key '") + key + "'");
            return n;
        };
        std::string model;
        node("model") >> model;
        if (model == "pinhole") {
            c.model = LensModel::pinhole;
        } else if (model == "fisheye") {
            c.model = LensModel::fisheye;
        } else {
            throw FileFormatError("model must be pinhole or fisheye, not '" + model + "'");
        }
        node("image_width") >> c.image_width;
        node("image_height") >> c.image_height;
        if (c.image_width <= 0 || c.image_height <= 0)
            throw FileFormatError("image size must be positive");
        cv::Mat k, d;
        node("camera_matrix") >> k;
        node("distortion_coefficients") >> d;
        if (k.rows != 3 || k.cols != 3) throw FileFormatError("camera_matrix must be 3x3");
        k.convertTo(k, CV_64F);
        for (int i = 0; i < 9; ++i)
            c.camera_matrix[static_cast<std::size_t>(i)] = k.at<double>(i / 3, i % 3);
        if (!(c.fx() > 0 && c.fy() > 0))
            throw FileFormatError("camera_matrix needs positive focal lengths");
        d.convertTo(d, CV_64F);
        c.distortion.assign(d.begin<double>(), d.end<double>());
        const std::size_t expected = c.model == LensModel::fisheye ? 4 : 5;
        if (c.distortion.size() != expected &&
            !(c.model == LensModel::pinhole &&
              (c.distortion.size() == 4 || c.distortion.size() == 8))) {
            throw FileFormatError("distortion_coefficients needs " + std::to_string(expected) +
                                  " values for a " + model + " camera");
        }
        for (double v : c.distortion)
            if (!std::isfinite(v)) throw FileFormatError("distortion_coefficients must be finite");
        if (!fs["rms"].empty()) fs["rms"] >> c.rms_px;
    } catch (...) {
        rethrow_as_file_format_error();
    }
    return c;
}

}  // namespace calbox::geometry
