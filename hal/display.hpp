#pragma once
// A 1-bit display (SSD1306 class, 128x64 by default).
#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace calbox::hal {

class MonoBitmap {
  public:
    MonoBitmap(int width_px = 128, int height_px = 64)
        : width_px_(width_px), height_px_(height_px), bits_(checked_size(width_px, height_px)) {}
    int width_px() const { return width_px_; }
    int height_px() const { return height_px_; }
    bool at(int x, int y) const { return inside(x, y) && bits_[index(x, y)] != 0; }
    // Pixels outside the bitmap are clipped, as drawing code expects.
    void set(int x, int y, bool on) {
        if (inside(x, y)) bits_[index(x, y)] = on ? 1 : 0;
    }
    void clear() { std::fill(bits_.begin(), bits_.end(), 0); }
    bool operator==(const MonoBitmap&) const = default;

  private:
    static std::size_t checked_size(int w, int h) {
        if (w <= 0 || h <= 0) throw std::invalid_argument("MonoBitmap: size must be positive");
        return static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    }
    bool inside(int x, int y) const { return x >= 0 && y >= 0 && x < width_px_ && y < height_px_; }
    std::size_t index(int x, int y) const {
        return static_cast<std::size_t>(y) * static_cast<std::size_t>(width_px_) +
               static_cast<std::size_t>(x);
    }
    int width_px_;
    int height_px_;
    std::vector<std::uint8_t> bits_;
};

class Display {
  public:
    virtual ~Display() = default;
    virtual int width_px() const = 0;
    virtual int height_px() const = 0;
    virtual void show(
        const MonoBitmap& frame) = 0;  // throws std::invalid_argument on a size mismatch
};

}  // namespace calbox::hal
