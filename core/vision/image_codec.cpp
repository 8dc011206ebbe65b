#include "core/vision/image_codec.hpp"

// clang-format off
#include <cstdio>  // before jpeglib.h, which uses FILE without including it
#include <jpeglib.h>
#include <jerror.h>
// clang-format on
#include <png.h>
#include <zlib.h>

#include <algorithm>
#include <csetjmp>
#include <cstdlib>
#include <cstring>

#include "core/vision/image_bytes.hpp"

namespace calbox::vision {
namespace {

void check_rows(const PixelRows& image) {
    if (image.pixels == nullptr || image.width_px <= 0 || image.height_px <= 0 ||
        (image.channels != 1 && image.channels != 3) ||
        image.stride_bytes < image.width_px * image.channels)
        throw ImageCodecError("an image to encode needs 8-bit rows of 1 or 3 channels");
}

// ---------------------------------------------------------------------------------------------
// EXIF: the orientation tag (0x0112) of the first image directory, 1 (upright) when absent.

std::uint32_t read_tiff(const std::uint8_t* p, int bytes, bool big_endian) {
    std::uint32_t v = 0;
    for (int i = 0; i < bytes; ++i)
        v |= static_cast<std::uint32_t>(p[big_endian ? i : bytes - 1 - i]) << (8 * (bytes - 1 - i));
    return v;
}

int exif_orientation(std::span<const std::uint8_t> tiff) {
    if (tiff.size() < 8) return 1;
    const bool big_endian = tiff[0] == 'M' && tiff[1] == 'M';
    if (!big_endian && !(tiff[0] == 'I' && tiff[1] == 'I')) return 1;
    const std::uint32_t ifd = read_tiff(&tiff[4], 4, big_endian);
    if (ifd + 2 > tiff.size()) return 1;
    const std::uint32_t entries = read_tiff(&tiff[ifd], 2, big_endian);
    for (std::uint32_t e = 0; e < entries; ++e) {
        const std::size_t at = ifd + 2 + 12 * static_cast<std::size_t>(e);
        if (at + 12 > tiff.size()) return 1;
        if (read_tiff(&tiff[at], 2, big_endian) != 0x0112) continue;
        const auto value = static_cast<int>(read_tiff(&tiff[at + 8], 2, big_endian));
        return value >= 1 && value <= 8 ? value : 1;
    }
    return 1;
}

// A JPEG's APP1 "Exif" segment, if any, before its first scan.
std::span<const std::uint8_t> jpeg_exif(std::span<const std::uint8_t> bytes) {
    std::size_t i = 2;
    while (i + 4 <= bytes.size() && bytes[i] == 0xFF) {
        const std::uint8_t marker = bytes[i + 1];
        if (marker == 0xDA || marker == 0xD9) break;
        const std::size_t length = (static_cast<std::size_t>(bytes[i + 2]) << 8) | bytes[i + 3];
        if (length < 2 || i + 2 + length > bytes.size()) break;
        if (marker == 0xE1 && length >= 8 && std::memcmp(&bytes[i + 4], "Exif\0\0", 6) == 0)
            return bytes.subspan(i + 10, length - 8);
        i += 2 + length;
    }
    return {};
}

// The picture turned upright: the eight EXIF orientations, as OpenCV applies them.
GrayPixels upright(GrayPixels in, int orientation) {
    if (orientation == 1) return in;
    const bool swap = orientation >= 5;
    GrayPixels out;
    out.width_px = swap ? in.height_px : in.width_px;
    out.height_px = swap ? in.width_px : in.height_px;
    out.pixels.resize(in.pixels.size());
    // After the transpose (5-8), 2 and 6 mirror left to right, 4 and 8 top to bottom, 3 and 7
    // both.
    const bool mirror_x =
        orientation == 2 || orientation == 3 || orientation == 6 || orientation == 7;
    const bool mirror_y =
        orientation == 3 || orientation == 4 || orientation == 7 || orientation == 8;
    for (int y = 0; y < out.height_px; ++y)
        for (int x = 0; x < out.width_px; ++x) {
            const int tx = mirror_x ? out.width_px - 1 - x : x;
            const int ty = mirror_y ? out.height_px - 1 - y : y;
            const int sx = swap ? ty : tx, sy = swap ? tx : ty;
            out.pixels[static_cast<std::size_t>(y) * out.width_px + x] =
                in.pixels[static_cast<std::size_t>(sy) * in.width_px + sx];
        }
    return out;
}

// ---------------------------------------------------------------------------------------------
// PNG

struct PngReadSource {
    std::span<const std::uint8_t> bytes;
    std::size_t at = 0;
};

[[noreturn]] void png_stop(png_structp png, png_const_charp message) {
    auto* reason = static_cast<std::string*>(png_get_error_ptr(png));
    *reason = message;
    png_longjmp(png, 1);
}
void png_quiet(png_structp, png_const_charp) {}

GrayPixels decode_png(std::span<const std::uint8_t> bytes) {
    std::string reason;
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &reason, png_stop, png_quiet);
    if (png == nullptr) throw ImageCodecError("the PNG reader could not start");
    png_infop info = png_create_info_struct(png);
    png_infop end_info = png_create_info_struct(png);
    PngReadSource source{bytes};
    GrayPixels out;
    std::vector<png_bytep> rows;
    std::span<const std::uint8_t> exif;
    if (setjmp(png_jmpbuf(png)) != 0) {
        png_destroy_read_struct(&png, &info, &end_info);
        throw ImageCodecError("not a PNG the reader takes: " + reason);
    }
    if (info == nullptr || end_info == nullptr) png_error(png, "out of memory");
    png_set_read_fn(png, &source, [](png_structp p, png_bytep data, png_size_t length) {
        auto* s = static_cast<PngReadSource*>(png_get_io_ptr(p));
        if (s->bytes.size() - s->at < length) png_error(p, "the file ends early");
        std::memcpy(data, s->bytes.data() + s->at, length);
        s->at += length;
    });
    png_read_info(png, info);
    png_uint_32 width = 0, height = 0;
    int bit_depth = 0, color_type = 0;
    png_get_IHDR(png, info, &width, &height, &bit_depth, &color_type, nullptr, nullptr, nullptr);
    if (width == 0 || height == 0 || width > 50000 || height > 50000)
        png_error(png, "a picture of no size, or over 50000 pixels a side");
    // OpenCV's steps for a gray picture, in its order.
    if (bit_depth == 16) png_set_strip_16(png);
    png_set_strip_alpha(png);
    if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if ((color_type & PNG_COLOR_MASK_COLOR) == 0 && bit_depth < 8)
        png_set_expand_gray_1_2_4_to_8(png);
    png_set_rgb_to_gray(png, 1, 0.299, 0.587);
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    if (png_get_rowbytes(png, info) != width)
        png_error(png, "the reader's rows are not one byte a pixel");
    out.width_px = static_cast<int>(width);
    out.height_px = static_cast<int>(height);
    out.pixels.resize(static_cast<std::size_t>(width) * height);
    rows.resize(height);
    for (png_uint_32 y = 0; y < height; ++y) rows[y] = out.pixels.data() + std::size_t{y} * width;
    png_read_image(png, rows.data());
    png_read_end(png, end_info);
#ifdef PNG_eXIf_SUPPORTED
    png_uint_32 exif_bytes = 0;
    png_bytep exif_data = nullptr;
    if (png_get_valid(png, info, PNG_INFO_eXIf))
        png_get_eXIf_1(png, info, &exif_bytes, &exif_data);
    else if (png_get_valid(png, end_info, PNG_INFO_eXIf))
        png_get_eXIf_1(png, end_info, &exif_bytes, &exif_data);
    const int orientation = exif_data != nullptr ? exif_orientation({exif_data, exif_bytes}) : 1;
#else
    const int orientation = 1;
#endif
    png_destroy_read_struct(&png, &info, &end_info);
    return upright(std::move(out), orientation);
}

struct PngWriteSink {
    std::vector<std::uint8_t> bytes;
};

// ---------------------------------------------------------------------------------------------
// JPEG

struct JpegErrors {
    jpeg_error_mgr manager{};
    std::jmp_buf jump{};
    std::string reason;
};

[[noreturn]] void jpeg_stop(j_common_ptr cinfo) {
    auto* errors = reinterpret_cast<JpegErrors*>(cinfo->err);
    char text[JMSG_LENGTH_MAX];
    (*cinfo->err->format_message)(cinfo, text);
    errors->reason = text;
    std::longjmp(errors->jump, 1);
}
// A warning is corrupt data the decoder went past, the picture made up from there on: kept, to
// refuse the picture by. Bytes after the picture's end (some cameras pad) lose nothing.
void jpeg_note(j_common_ptr cinfo, int level) {
    if (level >= 0 || cinfo->err->msg_code == JWRN_EXTRANEOUS_DATA) return;
    auto* errors = reinterpret_cast<JpegErrors*>(cinfo->err);
    if (cinfo->err->num_warnings++ == 0) {
        char text[JMSG_LENGTH_MAX];
        (*cinfo->err->format_message)(cinfo, text);
        errors->reason = text;
    }
}

GrayPixels decode_jpeg(std::span<const std::uint8_t> bytes) {
    jpeg_decompress_struct cinfo{};
    JpegErrors errors;
    cinfo.err = jpeg_std_error(&errors.manager);
    errors.manager.error_exit = jpeg_stop;
    errors.manager.emit_message = jpeg_note;
    GrayPixels out;
    if (setjmp(errors.jump) != 0) {
        jpeg_destroy_decompress(&cinfo);
        throw ImageCodecError("not a JPEG the reader takes: " + errors.reason);
    }
    jpeg_create_decompress(&cinfo);
    jpeg_mem_src(&cinfo, bytes.data(), static_cast<unsigned long>(bytes.size()));
    jpeg_read_header(&cinfo, TRUE);
    if (cinfo.num_components == 4) {
        jpeg_destroy_decompress(&cinfo);
        throw ImageCodecError("a CMYK JPEG (a print's file, not a camera's photo)");
    }
    cinfo.out_color_space = JCS_GRAYSCALE;
    cinfo.out_color_components = 1;
    jpeg_start_decompress(&cinfo);
    out.width_px = static_cast<int>(cinfo.output_width);
    out.height_px = static_cast<int>(cinfo.output_height);
    out.pixels.resize(static_cast<std::size_t>(out.width_px) * out.height_px);
    while (cinfo.output_scanline < cinfo.output_height) {
        JSAMPROW row = out.pixels.data() + std::size_t{cinfo.output_scanline} * out.width_px;
        jpeg_read_scanlines(&cinfo, &row, 1);
    }
    jpeg_finish_decompress(&cinfo);
    const long warnings = errors.manager.num_warnings;
    jpeg_destroy_decompress(&cinfo);
    // OpenCV returns such a picture with only libjpeg's note on standard error; its pixels past
    // the damage are made up.
    if (warnings > 0) throw ImageCodecError("a damaged JPEG: " + errors.reason);
    return upright(std::move(out), exif_orientation(jpeg_exif(bytes)));
}

}  // namespace

std::vector<std::uint8_t> png_bytes(const PixelRows& image) {
    check_rows(image);
    PngWriteSink sink;
    std::string reason;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &reason, png_stop, png_quiet);
    if (png == nullptr) throw ImageCodecError("the PNG writer could not start");
    png_infop info = png_create_info_struct(png);
    std::vector<png_bytep> rows(static_cast<std::size_t>(image.height_px));
    if (setjmp(png_jmpbuf(png)) != 0) {
        png_destroy_write_struct(&png, &info);
        throw ImageCodecError("PNG encoding failed: " + reason);
    }
    if (info == nullptr) png_error(png, "out of memory");
    png_set_write_fn(
        png, &sink,
        [](png_structp p, png_bytep data, png_size_t length) {
            auto* s = static_cast<PngWriteSink*>(png_get_io_ptr(p));
            s->bytes.insert(s->bytes.end(), data, data + length);
        },
        [](png_structp) {});
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
    png_set_compression_level(png, Z_BEST_SPEED);
    png_set_compression_strategy(png, Z_RLE);
    png_set_IHDR(png, info, static_cast<png_uint_32>(image.width_px),
                 static_cast<png_uint_32>(image.height_px), 8,
                 image.channels == 1 ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    png_set_bgr(png);
    for (int y = 0; y < image.height_px; ++y)
        rows[static_cast<std::size_t>(y)] =
            const_cast<png_bytep>(image.pixels + static_cast<std::size_t>(y) * image.stride_bytes);
    png_write_image(png, rows.data());
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    return std::move(sink.bytes);
}

std::vector<std::uint8_t> jpeg_bytes(const PixelRows& image, int quality) {
    check_rows(image);
    if (quality < 1 || quality > 100) throw ImageCodecError("a JPEG's quality is 1..100");
    jpeg_compress_struct cinfo{};
    JpegErrors errors;
    cinfo.err = jpeg_std_error(&errors.manager);
    errors.manager.error_exit = jpeg_stop;
    // libjpeg's memory destination: its buffer is malloc'd, grown and handed back through these.
    struct Destination {
        unsigned char* buffer = nullptr;
        unsigned long size = 0;
    } destination;
    // OpenCV hands libjpeg its colour rows as red, green, blue.
    std::vector<std::uint8_t> rgb(image.channels == 3 ? static_cast<std::size_t>(image.width_px) * 3
                                                      : 0);
    if (setjmp(errors.jump) != 0) {
        jpeg_destroy_compress(&cinfo);
        std::free(destination.buffer);
        throw ImageCodecError("JPEG encoding failed: " + errors.reason);
    }
    jpeg_create_compress(&cinfo);
    jpeg_mem_dest(&cinfo, &destination.buffer, &destination.size);
    cinfo.image_width = static_cast<JDIMENSION>(image.width_px);
    cinfo.image_height = static_cast<JDIMENSION>(image.height_px);
    cinfo.input_components = image.channels;
    cinfo.in_color_space = image.channels == 1 ? JCS_GRAYSCALE : JCS_RGB;
    jpeg_set_defaults(&cinfo);
    jpeg_set_quality(&cinfo, quality, TRUE);
    jpeg_start_compress(&cinfo, TRUE);
    while (cinfo.next_scanline < cinfo.image_height) {
        const std::uint8_t* source =
            image.pixels + static_cast<std::size_t>(cinfo.next_scanline) * image.stride_bytes;
        JSAMPROW row = const_cast<JSAMPROW>(source);
        if (image.channels == 3) {
            for (int x = 0; x < image.width_px; ++x) {
                rgb[3 * static_cast<std::size_t>(x)] = source[3 * x + 2];
                rgb[3 * static_cast<std::size_t>(x) + 1] = source[3 * x + 1];
                rgb[3 * static_cast<std::size_t>(x) + 2] = source[3 * x];
            }
            row = rgb.data();
        }
        jpeg_write_scanlines(&cinfo, &row, 1);
    }
    jpeg_finish_compress(&cinfo);
    jpeg_destroy_compress(&cinfo);
    std::vector<std::uint8_t> out(destination.buffer, destination.buffer + destination.size);
    std::free(destination.buffer);
    return out;
}

GrayPixels decode_gray(std::span<const std::uint8_t> bytes) {
    if (const auto problem = image_bytes_problem(bytes); !problem.empty())
        throw ImageCodecError(problem);
    static constexpr std::uint8_t kPng[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    if (bytes.size() >= sizeof kPng && std::equal(std::begin(kPng), std::end(kPng), bytes.begin()))
        return decode_png(bytes);
    if (bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF)
        return decode_jpeg(bytes);
    throw ImageCodecError("neither a PNG nor a JPEG");
}

}  // namespace calbox::vision
