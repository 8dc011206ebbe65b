#pragma once
// A V4L2 capture node in memory that speaks the kernel's streaming protocol (formats, mmap
// buffers queued and dequeued, controls), fills each queued buffer with a known picture while
// streaming, and can fail as a real camera does: unplugged at the n-th frame (ENODEV), frames
// that never come, formats it lacks.
#include <linux/videodev2.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <deque>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <string>
#include <vector>

#include "drivers/v4l2_camera.hpp"

namespace calbox::test {

class FakeV4l2Device final : public drivers::V4l2Device {
  public:
    std::set<std::uint32_t> formats{V4L2_PIX_FMT_YUYV};
    int max_width_px = 1280, max_height_px = 720;
    int gone_at_frame = 0;      // DQBUF fails with ENODEV from this frame on (1-based), 0: never
    bool frames_stall = false;  // streaming gives nothing
    std::map<std::uint32_t, std::int32_t> controls{
        {V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_APERTURE_PRIORITY},
        {V4L2_CID_EXPOSURE_ABSOLUTE, 156},
        {V4L2_CID_GAIN, 32}};
    int streamoff_calls = 0;

    FakeV4l2Device() : ready_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {}
    FakeV4l2Device(const FakeV4l2Device&) = delete;
    FakeV4l2Device& operator=(const FakeV4l2Device&) = delete;
    ~FakeV4l2Device() override { ::close(ready_); }

    // The grey level the fake puts at (x, y) of the frame with this sequence number.
    static std::uint8_t level(int x, int y, std::uint32_t sequence) {
        return static_cast<std::uint8_t>((3 * x + 5 * y + 7 * sequence) & 0xff);
    }

    const std::string& path() const override { return path_; }
    int poll_fd() const override { return ready_; }
    void* map(std::size_t length, std::int64_t offset) override {
        const auto i = static_cast<std::size_t>(offset / kOffsetStep);
        if (i >= buffers_.size() || length != buffers_[i].size()) {
            errno = EINVAL;
            return nullptr;
        }
        return buffers_[i].data();
    }
    void unmap(void*, std::size_t) override { ++unmapped; }
    int unmapped = 0;

    int ioctl(unsigned long request, void* argument) override {
        switch (request) {
            case VIDIOC_S_FMT: {
                auto& pix = static_cast<v4l2_format*>(argument)->fmt.pix;
                if (streaming_) return fail(EBUSY);
                if (formats.count(pix.pixelformat) == 0) pix.pixelformat = *formats.begin();
                pix.width =
                    std::min<std::uint32_t>(pix.width, static_cast<std::uint32_t>(max_width_px));
                pix.height =
                    std::min<std::uint32_t>(pix.height, static_cast<std::uint32_t>(max_height_px));
                pix.bytesperline = pix.pixelformat == V4L2_PIX_FMT_YUYV   ? 2 * pix.width
                                   : pix.pixelformat == V4L2_PIX_FMT_GREY ? pix.width
                                                                          : 0;
                // A compressed frame's buffer: room for the worst JPEG of it.
                pix.sizeimage = pix.bytesperline != 0 ? pix.bytesperline * pix.height
                                                      : 2 * pix.width * pix.height;
                format_ = pix;
                return 0;
            }
            case VIDIOC_REQBUFS: {
                auto& r = *static_cast<v4l2_requestbuffers*>(argument);
                buffers_.assign(r.count, std::vector<std::uint8_t>(format_.sizeimage));
                return 0;
            }
            case VIDIOC_QUERYBUF: {
                auto& b = *static_cast<v4l2_buffer*>(argument);
                if (b.index >= buffers_.size()) return fail(EINVAL);
                b.length = static_cast<std::uint32_t>(buffers_[b.index].size());
                b.m.offset = b.index * kOffsetStep;
                return 0;
            }
            case VIDIOC_QBUF: {
                const auto& b = *static_cast<v4l2_buffer*>(argument);
                if (b.index >= buffers_.size()) return fail(EINVAL);
                queued_.push_back(b.index);
                if (streaming_) fill_queued();
                return 0;
            }
            case VIDIOC_STREAMON:
                streaming_ = true;
                fill_queued();
                return 0;
            case VIDIOC_STREAMOFF:
                ++streamoff_calls;
                streaming_ = false;
                queued_.clear();
                filled_.clear();
                clear_ready();
                return 0;
            case VIDIOC_DQBUF: {
                if (gone_at_frame > 0 && static_cast<int>(sequence_out_) + 1 >= gone_at_frame)
                    return fail(ENODEV);
                if (filled_.empty()) return fail(EAGAIN);
                auto& b = *static_cast<v4l2_buffer*>(argument);
                b.index = filled_.front().index;
                b.bytesused = filled_.front().bytes;
                b.sequence = sequence_out_++;
                b.timestamp = {static_cast<long>(b.sequence), 0};
                filled_.pop_front();
                if (filled_.empty()) clear_ready();
                return 0;
            }
            case VIDIOC_S_CTRL: {
                const auto& c = *static_cast<v4l2_control*>(argument);
                if (controls.count(c.id) == 0) return fail(EINVAL);
                controls[c.id] = c.value;
                return 0;
            }
            case VIDIOC_G_CTRL: {
                auto& c = *static_cast<v4l2_control*>(argument);
                if (controls.count(c.id) == 0) return fail(EINVAL);
                c.value = controls[c.id];
                return 0;
            }
            case VIDIOC_QUERYCTRL: {
                auto& q = *static_cast<v4l2_queryctrl*>(argument);
                if (controls.count(q.id) == 0) return fail(EINVAL);
                q.minimum = 0;
                q.maximum = 255;
                q.default_value = 32;
                q.flags = 0;
                return 0;
            }
            default:
                return fail(ENOTTY);
        }
    }

  private:
    static constexpr std::uint32_t kOffsetStep = 1U << 24;
    struct Filled {
        std::uint32_t index;
        std::uint32_t bytes;
    };

    static int fail(int error) {
        errno = error;
        return -1;
    }
    void clear_ready() {
        std::uint64_t v = 0;
        const ssize_t n = ::read(ready_, &v, sizeof v);
        (void)n;
    }
    void fill_queued() {
        if (frames_stall) return;
        while (!queued_.empty()) {
            const std::uint32_t i = queued_.front();
            queued_.pop_front();
            auto& bytes = buffers_[i];
            const int w = static_cast<int>(format_.width), h = static_cast<int>(format_.height);
            const std::uint32_t sequence = sequence_in_++;
            std::uint32_t used = format_.sizeimage;
            if (format_.pixelformat == V4L2_PIX_FMT_MJPEG) {
                cv::Mat gray(h, w, CV_8U);
                for (int y = 0; y < h; ++y)
                    for (int x = 0; x < w; ++x) gray.at<std::uint8_t>(y, x) = level(x, y, sequence);
                std::vector<std::uint8_t> jpeg;
                cv::imencode(".jpg", gray, jpeg, {cv::IMWRITE_JPEG_QUALITY, 100});
                std::copy(jpeg.begin(), jpeg.end(), bytes.begin());
                used = static_cast<std::uint32_t>(jpeg.size());
            } else {
                for (int y = 0; y < h; ++y) {
                    for (int x = 0; x < w; ++x) {
                        const std::size_t row = static_cast<std::size_t>(y) * format_.bytesperline;
                        if (format_.pixelformat == V4L2_PIX_FMT_GREY) {
                            bytes[row + static_cast<std::size_t>(x)] = level(x, y, sequence);
                        } else {
                            bytes[row + 2 * static_cast<std::size_t>(x)] = level(x, y, sequence);
                            bytes[row + 2 * static_cast<std::size_t>(x) + 1] = 128;
                        }
                    }
                }
            }
            filled_.push_back({i, used});
            const std::uint64_t one = 1;
            const ssize_t n = ::write(ready_, &one, sizeof one);
            (void)n;
        }
    }

    std::string path_ = "/dev/video-fake";
    int ready_;
    v4l2_pix_format format_{};
    std::vector<std::vector<std::uint8_t>> buffers_;
    std::deque<std::uint32_t> queued_;
    std::deque<Filled> filled_;
    bool streaming_ = false;
    std::uint32_t sequence_in_ = 0, sequence_out_ = 0;
};

}  // namespace calbox::test
