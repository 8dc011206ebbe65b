#include "board/sim/photo_cache.hpp"

#include <unistd.h>

#include <array>
#include <bit>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

namespace calbox::sim {
namespace {

namespace fs = std::filesystem;

std::optional<fs::path> cache_directory() {
    const char* dir = std::getenv("CALBOX_TWIN_PHOTO_CACHE");
    if (dir == nullptr || *dir == '\0') return std::nullopt;
    return fs::path(dir);
}

// FNV-1a over the bytes, from a given offset basis: two different bases give two independent
// 64-bit digests.
std::uint64_t fnv1a(std::string_view bytes, std::uint64_t basis) {
    std::uint64_t h = basis;
    for (const char c : bytes) {
        h ^= static_cast<unsigned char>(c);
        h *= 1099511628211ULL;
    }
    return h;
}

constexpr std::array<char, 8> kMagic = {'c', 'b', 'x', 'p', 'h', 'o', 't', '1'};

}  // namespace

PhotoKey& PhotoKey::add(double v) {
    const auto bits = std::bit_cast<std::uint64_t>(v);
    bytes_.append(reinterpret_cast<const char*>(&bits), sizeof bits);
    return *this;
}

PhotoKey& PhotoKey::add(std::int64_t v) {
    bytes_.append(reinterpret_cast<const char*>(&v), sizeof v);
    return *this;
}

PhotoKey& PhotoKey::add(std::string_view text) {
    add(static_cast<std::int64_t>(text.size()));
    bytes_.append(text);
    return *this;
}

PhotoKey& PhotoKey::add(const Pose& pose) {
    for (const auto& row : pose.rotation.m)
        for (const double v : row) add(v);
    return add(pose.translation_mm);
}

PhotoKey& PhotoKey::add(const CameraIntrinsics& c) {
    add(static_cast<std::int64_t>(c.model)).add(std::int64_t{c.width_px});
    add(std::int64_t{c.height_px}).add(c.fx).add(c.fy).add(c.cx).add(c.cy);
    add(static_cast<std::int64_t>(c.distortion.size()));
    for (const double k : c.distortion) add(k);
    return *this;
}

PhotoKey& PhotoKey::add(const PhotoSettings& p) {
    add(std::int64_t{p.supersample}).add(p.blur_sigma_px).add(p.noise_sigma_dn);
    add(static_cast<std::int64_t>(p.seed)).add(p.exposure_dn).add(p.lighting_gradient);
    add(p.lighting_direction_deg).add(p.vignetting).add(p.motion_blur_px);
    add(p.motion_blur_direction_deg).add(p.field_curvature_px);
    add(p.glare.peak).add(p.glare.spread_deg).add(p.glare.lamp_from_camera_mm);
    add(p.exposure_time_ratio).add(p.analogue_gain).add(std::int64_t{p.jpeg_quality});
    return *this;
}

PhotoKey& PhotoKey::add(const StrokeSurface& s) {
    return add(s.bed_texture)
        .add(s.bed_texture_grain_mm)
        .add(s.gloss)
        .add(s.light_azimuth_deg)
        .add(s.light_elevation_deg);
}

PhotoKey& PhotoKey::add(const std::vector<StrokeSegment>& strokes) {
    add(static_cast<std::int64_t>(strokes.size()));
    for (const auto& s : strokes) add(s.a_mm).add(s.b_mm).add(s.width_mm);
    return *this;
}

PhotoKey& PhotoKey::add(const std::vector<ReferenceMark>& marks) {
    add(static_cast<std::int64_t>(marks.size()));
    for (const auto& m : marks) add(std::int64_t{m.id}).add(m.centre_mm);
    return *this;
}

std::string PhotoKey::digest() const {
    char hex[33];
    std::snprintf(hex, sizeof hex, "%016llx%016llx",
                  static_cast<unsigned long long>(fnv1a(bytes_, 14695981039346656037ULL)),
                  static_cast<unsigned long long>(fnv1a(bytes_, 0x6c62272e07bb0142ULL)));
    return hex;
}

std::optional<GrayImage> kept_photo(const PhotoKey& key) {
    const auto dir = cache_directory();
    if (!dir) return std::nullopt;
    std::ifstream in(*dir / (key.digest() + ".gray"), std::ios::binary);
    if (!in) return std::nullopt;
    std::array<char, 8> magic{};
    std::int32_t size[2] = {0, 0};
    in.read(magic.data(), magic.size());
    in.read(reinterpret_cast<char*>(size), sizeof size);
    if (!in || magic != kMagic || size[0] <= 0 || size[1] <= 0 || size[0] > 20000 ||
        size[1] > 20000)
        return std::nullopt;
    GrayImage photo{size[0], size[1], {}};
    photo.pixels.resize(static_cast<std::size_t>(size[0]) * static_cast<std::size_t>(size[1]));
    in.read(reinterpret_cast<char*>(photo.pixels.data()),
            static_cast<std::streamsize>(photo.pixels.size()));
    if (in.gcount() != static_cast<std::streamsize>(photo.pixels.size())) return std::nullopt;
    return photo;
}

void keep_photo(const PhotoKey& key, const GrayImage& photo) {
    const auto dir = cache_directory();
    if (!dir) return;
    std::error_code ignored;
    fs::create_directories(*dir, ignored);
    const std::string name = key.digest();
    const fs::path final_path = *dir / (name + ".gray");
    const fs::path temporary =
        *dir / (name + "." + std::to_string(::getpid()) + "." +
                std::to_string(reinterpret_cast<std::uintptr_t>(&photo)) + ".part");
    {
        std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
        const std::int32_t size[2] = {photo.width_px, photo.height_px};
        out.write(kMagic.data(), kMagic.size());
        out.write(reinterpret_cast<const char*>(size), sizeof size);
        out.write(reinterpret_cast<const char*>(photo.pixels.data()),
                  static_cast<std::streamsize>(photo.pixels.size()));
        if (!out) {
            out.close();
            fs::remove(temporary, ignored);
            return;  // a full disk costs the next test a render, nothing more
        }
    }
    fs::rename(temporary, final_path, ignored);
    if (ignored) fs::remove(temporary, ignored);
}

}  // namespace calbox::sim
