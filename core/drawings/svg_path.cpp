// SVG path data ("M 0 0 L 10 0 C ..."), read as a browser does, flattened into contours.
#include "core/drawings/svg_path.hpp"

#include <algorithm>
#include <numbers>

#include "core/number_text.hpp"

namespace calbox::drawings {
namespace svg_path {

// ---------------------------------------------------------------------------------------------
// Flattening

void flatten_cubic(const Affine& m, Point2 p0, Point2 p1, Point2 p2, Point2 p3, double tolerance,
                   std::vector<Point2>& out, int depth) {
    // Work on the mapped control points: an affine map keeps a Bezier curve a Bezier curve.
    const Point2 a = m.apply(p0), b = m.apply(p1), c = m.apply(p2), d = m.apply(p3);
    const auto distance_to_chord = [&](Point2 q) {
        const double dx = d.x - a.x, dy = d.y - a.y, len = std::hypot(dx, dy);
        if (len < 1e-12) return std::hypot(q.x - a.x, q.y - a.y);
        return std::abs((q.x - a.x) * dy - (q.y - a.y) * dx) / len;
    };
    // The curve lies within the control polygon's hull; 3/4 of the control distance bounds it.
    if (depth >= 18 || 0.75 * std::max(distance_to_chord(b), distance_to_chord(c)) <= tolerance) {
        out.push_back(p3);
        return;
    }
    const auto mid = [](Point2 u, Point2 v) { return Point2{(u.x + v.x) / 2, (u.y + v.y) / 2}; };
    const Point2 p01 = mid(p0, p1), p12 = mid(p1, p2), p23 = mid(p2, p3);
    const Point2 p012 = mid(p01, p12), p123 = mid(p12, p23), p0123 = mid(p012, p123);
    flatten_cubic(m, p0, p01, p012, p0123, tolerance, out, depth + 1);
    flatten_cubic(m, p0123, p123, p23, p3, tolerance, out, depth + 1);
}

void flatten_arc(const Affine& m, Point2 centre, double rx, double ry, double phi, double theta1,
                 double delta, double tolerance, std::vector<Point2>& out) {
    const double r_mm = std::max(rx, ry) * m.scale();
    double step = std::numbers::pi / 2;
    if (r_mm > tolerance) step = std::min(step, 2 * std::acos(1 - tolerance / r_mm));
    // A million points is a 60 km arc at the default tolerance: more is a broken number, and
    // past int the count itself would be undefined (found by tests/fuzz under UBSan).
    constexpr double kMaxArcPoints = 1e6;
    const double count = std::ceil(std::abs(delta) / step);
    if (!std::isfinite(count) || count > kMaxArcPoints) {
        throw SvgError("an arc of radius " + number_text("%.3g", r_mm) +
                       " mm is too large to flatten");
    }
    const int n = std::max(1, static_cast<int>(count));
    const double cp = std::cos(phi), sp = std::sin(phi);
    for (int k = 1; k <= n; ++k) {
        const double t = theta1 + delta * k / n;
        const double x = rx * std::cos(t), y = ry * std::sin(t);
        out.push_back({centre.x + cp * x - sp * y, centre.y + sp * x + cp * y});
    }
}

namespace {

double vector_angle(double ux, double uy, double vx, double vy) {
    return std::atan2(ux * vy - uy * vx, ux * vx + uy * vy);
}

}  // namespace

void arc_to(const Affine& m, Point2 p1, double rx, double ry, double phi_deg, bool large,
            bool sweep, Point2 p2, double tolerance, std::vector<Point2>& out) {
    if (p1.x == p2.x && p1.y == p2.y) return;
    rx = std::abs(rx);
    ry = std::abs(ry);
    if (rx == 0 || ry == 0) {
        out.push_back(p2);
        return;
    }
    const double phi = phi_deg * std::numbers::pi / 180, cp = std::cos(phi), sp = std::sin(phi);
    const double dx = (p1.x - p2.x) / 2, dy = (p1.y - p2.y) / 2;
    const double x1 = cp * dx + sp * dy, y1 = -sp * dx + cp * dy;
    const double lambda = x1 * x1 / (rx * rx) + y1 * y1 / (ry * ry);
    if (lambda > 1) {
        rx *= std::sqrt(lambda);
        ry *= std::sqrt(lambda);
    }
    const double num = rx * rx * ry * ry - rx * rx * y1 * y1 - ry * ry * x1 * x1;
    const double den = rx * rx * y1 * y1 + ry * ry * x1 * x1;
    double coef = std::sqrt(std::max(0.0, num / den));
    if (large == sweep) coef = -coef;
    const double cx1 = coef * rx * y1 / ry, cy1 = -coef * ry * x1 / rx;
    const Point2 centre{cp * cx1 - sp * cy1 + (p1.x + p2.x) / 2,
                        sp * cx1 + cp * cy1 + (p1.y + p2.y) / 2};
    const double theta1 = vector_angle(1, 0, (x1 - cx1) / rx, (y1 - cy1) / ry);
    double delta =
        vector_angle((x1 - cx1) / rx, (y1 - cy1) / ry, (-x1 - cx1) / rx, (-y1 - cy1) / ry);
    if (!sweep && delta > 0) delta -= 2 * std::numbers::pi;
    if (sweep && delta < 0) delta += 2 * std::numbers::pi;
    flatten_arc(m, centre, rx, ry, phi, theta1, delta, tolerance, out);
    out.back() = p2;  // land exactly on the endpoint
}

namespace {

// The path data's reader: the pen, the subpath being drawn, the command in force.
class PathReader {
  public:
    PathReader(std::string_view d, const Affine& m, double tolerance)
        : s_(d), m_(m), tolerance_(tolerance) {}

    std::vector<Contour> read() {
        while (!s_.at_end()) {
            next_command();
            const char op = static_cast<char>(std::toupper(static_cast<unsigned char>(command_)));
            // A drawing command after Z starts a new subpath at the pen.
            if (op != 'M' && op != 'Z' && user_.empty()) user_.push_back(pen_);
            draw(op);
            previous_ = op;
        }
        finish(false);
        return std::move(contours_);
    }

  private:
    // The command letter where one stands, else the one in force repeats.
    void next_command() {
        if (std::isalpha(static_cast<unsigned char>(s_.peek()))) {
            command_ = s_.take();
            if (std::string_view("MmLlHhVvCcSsQqTtAaZz").find(command_) == std::string_view::npos)
                throw SvgError(std::string("path data: unknown command '") + command_ +
                               "' at character " + std::to_string(s_.position()));
        } else if (command_ == 0) {
            bad("numbers before the first command");
        } else if (command_ == 'Z' || command_ == 'z') {
            bad("numbers after Z");
        }
        relative_ = std::islower(static_cast<unsigned char>(command_)) != 0;
    }

    void draw(char op) {
        switch (op) {
            case 'M':
                finish(false);
                pen_ = start_ = point();
                user_.push_back(pen_);
                command_ = relative_ ? 'l' : 'L';  // further pairs are lines
                break;
            case 'L':
                pen_ = point();
                user_.push_back(pen_);
                break;
            case 'H':
                pen_.x = relative_ ? pen_.x + num() : num();
                user_.push_back(pen_);
                break;
            case 'V':
                pen_.y = relative_ ? pen_.y + num() : num();
                user_.push_back(pen_);
                break;
            case 'C':
            case 'S':
                cubic(op);
                break;
            case 'Q':
            case 'T':
                quadratic(op);
                break;
            case 'A':
                arc();
                break;
            case 'Z':
                if (!user_.empty()) finish(true);
                pen_ = start_;
                break;
        }
    }

    // The control point a smooth curve (S, T) mirrors from the last one of its own kind.
    Point2 mirrored_control(bool smooth) const {
        return smooth ? Point2{2 * pen_.x - last_control_.x, 2 * pen_.y - last_control_.y} : pen_;
    }

    void cubic(char op) {
        const Point2 c1 =
            op == 'C' ? point() : mirrored_control(previous_ == 'C' || previous_ == 'S');
        const Point2 c2 = point(), end = point();
        // flatten_cubic appends user-unit points: the map is applied at finish().
        flatten_cubic(m_, pen_, c1, c2, end, tolerance_, user_);
        last_control_ = c2;
        pen_ = end;
    }

    void quadratic(char op) {
        const Point2 q =
            op == 'Q' ? point() : mirrored_control(previous_ == 'Q' || previous_ == 'T');
        const Point2 end = point();
        // A quadratic is the cubic with controls two thirds of the way to q.
        const Point2 c1{pen_.x + 2.0 / 3 * (q.x - pen_.x), pen_.y + 2.0 / 3 * (q.y - pen_.y)};
        const Point2 c2{end.x + 2.0 / 3 * (q.x - end.x), end.y + 2.0 / 3 * (q.y - end.y)};
        flatten_cubic(m_, pen_, c1, c2, end, tolerance_, user_);
        last_control_ = q;
        pen_ = end;
    }

    void arc() {
        const double rx = num(), ry = num(), phi = num();
        const auto large = s_.flag();
        const auto sweep = large ? s_.flag() : std::nullopt;
        if (!large || !sweep) bad("arc flags must be 0 or 1");
        const Point2 end = point();
        arc_to(m_, pen_, rx, ry, phi, *large, *sweep, end, tolerance_, user_);
        pen_ = end;
    }

    void finish(bool closed) {
        if (user_.size() >= 2) {
            Contour c;
            for (const auto& p : user_) c.points.push_back(m_.apply(p));
            c.closed = closed;
            contours_.push_back(std::move(c));
        }
        user_.clear();
    }

    [[noreturn]] void bad(const std::string& why) const {
        throw SvgError("path data: " + why + " at character " + std::to_string(s_.position() + 1));
    }
    double num() {
        const auto v = s_.number();
        if (!v) bad(std::string("expected a number after ") + command_);
        return *v;
    }
    Point2 point() {
        const double x = num(), y = num();
        return relative_ ? Point2{pen_.x + x, pen_.y + y} : Point2{x, y};
    }

    Scanner s_;
    const Affine& m_;
    double tolerance_;
    std::vector<Contour> contours_;
    std::vector<Point2> user_;  // the current subpath in user units
    Point2 pen_{0, 0}, start_{0, 0}, last_control_{0, 0};
    char command_ = 0, previous_ = 0;
    bool relative_ = false;
};

}  // namespace
}  // namespace svg_path

std::vector<Contour> parse_path_data(std::string_view d, const Affine& m, double tolerance) {
    return svg_path::PathReader(d, m, tolerance).read();
}

}  // namespace calbox::drawings
