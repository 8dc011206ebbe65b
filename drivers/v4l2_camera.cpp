#include "drivers/v4l2_camera.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "core/vision/image_codec.hpp"
#include "drivers/device_error.hpp"

namespace calbox::drivers {
namespace {

class KernelV4l2Device final : public V4l2Device {
  public:
    KernelV4l2Device(std::string path, int fd) : path_(std::move(path)), fd_(fd) {}
    KernelV4l2Device(const KernelV4l2Device&) = delete;
    KernelV4l2Device& operator=(const KernelV4l2Device&) = delete;
    ~KernelV4l2Device() override { ::close(fd_); }
    const std::string& path() const override { return path_; }
    int ioctl(unsigned long request, void* argument) override {
        int r = 0;
        do {
            r = ::ioctl(fd_, request, argument);
        } while (r == -1 && errno == EINTR);
        return r;
    }
    void* map(std::size_t length, std::int64_t offset) override {
        void* p = ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_,
                         static_cast<off_t>(offset));
        return p == MAP_FAILED ? nullptr : p;
    }
    void unmap(void* address, std::size_t length) override { ::munmap(address, length); }
    int poll_fd() const override { return fd_; }

  private:
    std::string path_;
    int fd_;
};

}  // namespace

std::unique_ptr<V4l2Device> open_v4l2_device(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) throw device_error(path + " (V4L2 camera)", "open");
    auto device = std::make_unique<KernelV4l2Device>(path, fd);
    v4l2_capability caps{};
    if (device->ioctl(VIDIOC_QUERYCAP, &caps) != 0)
        throw device_error(path, "not a V4L2 device (VIDIOC_QUERYCAP)");
    const std::uint32_t have =
        (caps.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? caps.device_caps : caps.capabilities;
    if ((have & V4L2_CAP_VIDEO_CAPTURE) == 0 || (have & V4L2_CAP_STREAMING) == 0) {
        throw std::runtime_error(path + ": not a streaming video capture device (a metadata or " +
                                 "output node of the camera?)");
    }
    return device;
}

V4l2Camera::V4l2Camera(std::unique_ptr<V4l2Device> device, V4l2Settings settings)
    : device_(std::move(device)), settings_(settings) {
    const std::string& path = device_->path();
    if (settings_.buffer_count < 1 || settings_.width_px < 1 || settings_.height_px < 1)
        throw std::invalid_argument("V4L2 settings: size and buffer count must be positive");
    // Grey needs no conversion; YUYV's Y bytes are grey; MJPEG costs a decode per frame.
    for (const std::uint32_t wanted : {V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG}) {
        v4l2_format format{};
        format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        format.fmt.pix.width = static_cast<std::uint32_t>(settings_.width_px);
        format.fmt.pix.height = static_cast<std::uint32_t>(settings_.height_px);
        format.fmt.pix.pixelformat = wanted;
        format.fmt.pix.field = V4L2_FIELD_NONE;
        if (device_->ioctl(VIDIOC_S_FMT, &format) != 0) {
            if (errno == EBUSY)
                throw device_error(path, "set the format (in use by another program?)");
            continue;
        }
        if (format.fmt.pix.pixelformat != wanted) continue;  // the driver chose another
        fourcc_ = wanted;
        width_px_ = static_cast<int>(format.fmt.pix.width);
        height_px_ = static_cast<int>(format.fmt.pix.height);
        stride_bytes_ = static_cast<int>(format.fmt.pix.bytesperline);
        break;
    }
    if (fourcc_ == 0)
        throw std::runtime_error(path + ": offers none of GREY, YUYV or MJPEG at " +
                                 std::to_string(settings_.width_px) + "x" +
                                 std::to_string(settings_.height_px));
    if (stride_bytes_ == 0)
        stride_bytes_ = fourcc_ == V4L2_PIX_FMT_YUYV ? 2 * width_px_ : width_px_;

    v4l2_requestbuffers request{};
    request.count = static_cast<std::uint32_t>(settings_.buffer_count);
    request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    request.memory = V4L2_MEMORY_MMAP;
    if (device_->ioctl(VIDIOC_REQBUFS, &request) != 0) throw device_error(path, "request buffers");
    if (request.count < 1) throw std::runtime_error(path + ": gave no buffers");
    // Mapped once, for the camera's life.
    for (std::uint32_t i = 0; i < request.count; ++i) {
        v4l2_buffer b{};
        b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        b.memory = V4L2_MEMORY_MMAP;
        b.index = i;
        if (device_->ioctl(VIDIOC_QUERYBUF, &b) != 0) throw device_error(path, "query a buffer");
        void* address = device_->map(b.length, b.m.offset);
        if (address == nullptr) throw device_error(path, "map a buffer");
        buffers_.push_back({address, b.length});
    }
}

V4l2Camera::~V4l2Camera() {
    while (capture_.busy()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    for (const auto& b : buffers_) device_->unmap(b.address, b.length);
}

void V4l2Camera::start_capture(const hal::CaptureRequest& request) {
    if (request.frame_count < 1) throw std::invalid_argument("a capture takes at least one frame");
    capture_.start([this, request] { return capture(request); });
}

hal::CaptureResult V4l2Camera::take_frames() {
    auto result = capture_.take();
    if (!result) return {{}, "no capture has finished"};
    return std::move(*result);
}

// Manual exposure where asked (V4L2 counts it in 100 us), gain scaled from the control's
// default (which UVC cameras set at unity); a control the device lacks is an error, not an
// automatic exposure that would let the camera, not the light, set the picture.
void V4l2Camera::set_exposure(const hal::CaptureRequest& request) {
    const std::string& path = device_->path();
    const auto set = [&](std::uint32_t id, std::int32_t value, const char* what) {
        v4l2_control c{id, value};
        if (device_->ioctl(VIDIOC_S_CTRL, &c) != 0)
            throw device_error(path, std::string("set ") + what);
    };
    if (request.exposure) {
        set(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "manual exposure");
        set(V4L2_CID_EXPOSURE_ABSOLUTE,
            static_cast<std::int32_t>(std::max<std::int64_t>(1, request.exposure->count() / 100)),
            "the exposure time");
    }
    if (request.analogue_gain) {
        for (const std::uint32_t id : {static_cast<std::uint32_t>(V4L2_CID_ANALOGUE_GAIN),
                                       static_cast<std::uint32_t>(V4L2_CID_GAIN)}) {
            v4l2_queryctrl q{};
            q.id = id;
            if (device_->ioctl(VIDIOC_QUERYCTRL, &q) != 0 ||
                (q.flags & V4L2_CTRL_FLAG_DISABLED) != 0)
                continue;
            const double unity = std::max(1, q.default_value);
            const auto value = static_cast<std::int32_t>(std::clamp<double>(
                std::lround(unity * *request.analogue_gain), q.minimum, q.maximum));
            set(id, value, "the gain");
            return;
        }
        throw std::runtime_error(path + ": has no gain control for the asked gain");
    }
}

hal::Frame V4l2Camera::to_gray(const Buffer& buffer, std::size_t used_bytes) const {
    hal::Frame frame;
    frame.format = hal::PixelFormat::gray8;
    const auto* bytes = static_cast<const std::uint8_t*>(buffer.address);
    if (fourcc_ == V4L2_PIX_FMT_MJPEG) {
        // A frame the USB link cut short decodes grey at its foot: refused, not measured.
        vision::GrayPixels gray;
        try {
            gray = vision::decode_gray({bytes, used_bytes});
        } catch (const vision::ImageCodecError& e) {
            throw std::runtime_error(device_->path() + ": a frame: " + e.what());
        }
        frame.width_px = gray.width_px;
        frame.height_px = gray.height_px;
        frame.stride_bytes = gray.width_px;
        frame.pixels = std::move(gray.pixels);
        return frame;
    }
    frame.width_px = width_px_;
    frame.height_px = height_px_;
    frame.stride_bytes = width_px_;
    const std::size_t needed =
        static_cast<std::size_t>(stride_bytes_) * static_cast<std::size_t>(height_px_);
    if (used_bytes < needed || buffer.length < needed) {
        throw std::runtime_error(device_->path() + ": a frame of " + std::to_string(used_bytes) +
                                 " bytes, " + std::to_string(needed) + " expected");
    }
    frame.pixels.resize(static_cast<std::size_t>(width_px_) * static_cast<std::size_t>(height_px_));
    for (int y = 0; y < height_px_; ++y) {
        const std::uint8_t* row =
            bytes + static_cast<std::size_t>(y) * static_cast<std::size_t>(stride_bytes_);
        std::uint8_t* out =
            frame.pixels.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(width_px_);
        if (fourcc_ == V4L2_PIX_FMT_GREY) {
            std::memcpy(out, row, static_cast<std::size_t>(width_px_));
        } else {  // YUYV: Y0 U Y1 V
            for (std::size_t x = 0; x < static_cast<std::size_t>(width_px_); ++x)
                out[x] = row[2 * x];
        }
    }
    return frame;
}

hal::CaptureResult V4l2Camera::capture(const hal::CaptureRequest& request) {
    const std::string& path = device_->path();
    hal::CaptureResult result;
    bool streaming = false;
    const auto stop = [&] {
        if (!streaming) return;
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        device_->ioctl(VIDIOC_STREAMOFF, &type);  // also takes every buffer back
        streaming = false;
    };
    try {
        set_exposure(request);
        for (std::uint32_t i = 0; i < buffers_.size(); ++i) {
            v4l2_buffer b{};
            b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
            b.memory = V4L2_MEMORY_MMAP;
            b.index = i;
            if (device_->ioctl(VIDIOC_QBUF, &b) != 0) throw device_error(path, "queue a buffer");
        }
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        if (device_->ioctl(VIDIOC_STREAMON, &type) != 0)
            throw device_error(path, "start streaming");
        streaming = true;
        const int wanted = request.frame_count + settings_.frames_to_settle;
        for (int n = 0; n < wanted;) {
            pollfd p{device_->poll_fd(), POLLIN, 0};
            const int ready = ::poll(&p, 1, static_cast<int>(settings_.frame_timeout.count()));
            if (ready < 0 && errno == EINTR) continue;
            if (ready < 0) throw device_error(path, "wait for a frame");
            if (ready == 0) {
                throw std::runtime_error(path + ": no frame within " +
                                         std::to_string(settings_.frame_timeout.count()) + " ms");
            }
            if ((p.revents & (POLLERR | POLLHUP)) != 0 && (p.revents & POLLIN) == 0) {
                errno = ENODEV;
                throw device_error(path,
                                   "gone during the capture (frame " + std::to_string(n + 1) + ")");
            }
            v4l2_buffer b{};
            b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
            b.memory = V4L2_MEMORY_MMAP;
            if (device_->ioctl(VIDIOC_DQBUF, &b) != 0) {
                if (errno == EAGAIN) continue;
                throw device_error(path, "take frame " + std::to_string(n + 1) + " of the capture");
            }
            if (b.index >= buffers_.size())
                throw std::runtime_error(path + ": a buffer it never gave");
            const bool settled = n >= settings_.frames_to_settle;
            const bool damaged = (b.flags & V4L2_BUF_FLAG_ERROR) != 0;
            if (settled && !damaged) {
                hal::Frame frame = to_gray(buffers_[b.index], b.bytesused);
                frame.metadata.sequence = b.sequence;
                frame.metadata.timestamp = std::chrono::seconds(b.timestamp.tv_sec) +
                                           std::chrono::microseconds(b.timestamp.tv_usec);
                if (request.exposure) {
                    frame.metadata.exposure = *request.exposure;
                } else {
                    // The camera's own: what it chose, read back, so that a metering frame
                    // says what it was taken at (a device without the control leaves 0).
                    v4l2_control c{V4L2_CID_EXPOSURE_ABSOLUTE, 0};
                    if (device_->ioctl(VIDIOC_G_CTRL, &c) == 0 && c.value > 0)
                        frame.metadata.exposure = std::chrono::microseconds(100 * c.value);
                }
                if (request.analogue_gain) frame.metadata.analogue_gain = *request.analogue_gain;
                result.frames.push_back(std::move(frame));
            }
            if (!damaged) ++n;  // a damaged frame is taken again
            if (device_->ioctl(VIDIOC_QBUF, &b) != 0)
                throw device_error(path, "queue a buffer again");
        }
        stop();
    } catch (const std::exception& e) {
        stop();
        result.frames.clear();
        result.error = e.what();
    }
    return result;
}

}  // namespace calbox::drivers
