#pragma once
// Inside the SVG reader (core/drawings/svg.cpp, svg_path.cpp): numbers as SVG writes them, and
// curves flattened into points within a tolerance. Not for use outside core/drawings.
#include <cctype>
#include <charconv>
#include <cmath>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/drawings/svg.hpp"

namespace calbox::drawings::svg_path {

using geometry::Point2;

// ---------------------------------------------------------------------------------------------
// Numbers as SVG writes them: "1.5.5" is 1.5 then .5, "-1-2" is -1 then -2.

class Scanner {
  public:
    explicit Scanner(std::string_view s) : s_(s) {}
    void skip_separators() {
        while (i_ < s_.size() &&
               (std::isspace(static_cast<unsigned char>(s_[i_])) || s_[i_] == ','))
            ++i_;
    }
    bool at_end() {
        skip_separators();
        return i_ >= s_.size();
    }
    char peek() {
        skip_separators();
        return i_ < s_.size() ? s_[i_] : '\0';
    }
    char take() { return s_[i_++]; }
    bool at_number() {
        const char c = peek();
        return std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == '+' || c == '.';
    }
    std::optional<double> number() {
        skip_separators();
        const std::size_t start = i_;
        if (i_ < s_.size() && (s_[i_] == '+' || s_[i_] == '-')) ++i_;
        bool digits = false;
        while (i_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i_])))
            ++i_, digits = true;
        if (i_ < s_.size() && s_[i_] == '.') {
            ++i_;
            while (i_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i_])))
                ++i_, digits = true;
        }
        if (!digits) {
            i_ = start;
            return std::nullopt;
        }
        if (i_ < s_.size() && (s_[i_] == 'e' || s_[i_] == 'E')) {
            std::size_t j = i_ + 1;
            if (j < s_.size() && (s_[j] == '+' || s_[j] == '-')) ++j;
            if (j < s_.size() && std::isdigit(static_cast<unsigned char>(s_[j]))) {
                i_ = j;
                while (i_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i_]))) ++i_;
            }
        }
        std::string text(s_.substr(start, i_ - start));
        if (text[0] == '+') text.erase(0, 1);
        double v = 0;
        const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
        if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v)) {
            i_ = start;
            return std::nullopt;
        }
        return v;
    }
    std::optional<bool> flag() {
        skip_separators();
        if (i_ < s_.size() && (s_[i_] == '0' || s_[i_] == '1')) return s_[i_++] == '1';
        return std::nullopt;
    }
    std::size_t position() const { return i_; }

  private:
    std::string_view s_;
    std::size_t i_ = 0;
};

// A cubic Bezier's points (user units, its start left out) within `tolerance` after `m`.
void flatten_cubic(const Affine& m, Point2 p0, Point2 p1, Point2 p2, Point2 p3, double tolerance,
                   std::vector<Point2>& out, int depth = 0);
// Points along an elliptical arc (centre form, radii along the rotated axes), excluding its start.
void flatten_arc(const Affine& m, Point2 centre, double rx, double ry, double phi, double theta1,
                 double delta, double tolerance, std::vector<Point2>& out);
// SVG's endpoint arc (spec F.6.5) to centre form, then flattened.
void arc_to(const Affine& m, Point2 p1, double rx, double ry, double phi_deg, bool large,
            bool sweep, Point2 p2, double tolerance, std::vector<Point2>& out);

}  // namespace calbox::drawings::svg_path
