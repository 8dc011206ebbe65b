#include "drivers/libcamera_camera.hpp"

#include <libcamera/libcamera.h>
#include <libcamera/version.h>
#include <sys/mman.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "hal/notifier.hpp"

namespace calbox::drivers {
namespace {

// libcamera 0.5 replaced the one AeEnable switch by a manual mode per control (Raspberry Pi OS
// ships releases past it, Debian 12 the 0.0.3 before it): the only API difference this driver
// meets, kept here. The names of one release do not exist in the other, hence the preprocessor.
void set_manual_exposure(libcamera::ControlList& c, bool manual) {
#if LIBCAMERA_VERSION_MAJOR > 0 || LIBCAMERA_VERSION_MINOR >= 5
    c.set(libcamera::controls::ExposureTimeMode, manual
                                                     ? libcamera::controls::ExposureTimeModeManual
                                                     : libcamera::controls::ExposureTimeModeAuto);
    c.set(libcamera::controls::AnalogueGainMode, manual
                                                     ? libcamera::controls::AnalogueGainModeManual
                                                     : libcamera::controls::AnalogueGainModeAuto);
#else
    c.set(libcamera::controls::AeEnable, !manual);
#endif
}

// One frame buffer's planes, mapped once for the camera's life.
struct MappedBuffer {
    libcamera::FrameBuffer* buffer = nullptr;
    const std::uint8_t* y_plane = nullptr;
    void* mapping = nullptr;
    std::size_t mapping_length = 0;
};

class LibcameraCamera final : public hal::Camera {
  public:
    explicit LibcameraCamera(const LibcameraSettings& settings);
    LibcameraCamera(const LibcameraCamera&) = delete;
    LibcameraCamera& operator=(const LibcameraCamera&) = delete;
    ~LibcameraCamera() override;

    void start_capture(const hal::CaptureRequest& request) override;
    int completion_fd() const override { return done_.fd(); }
    hal::CaptureResult take_frames() override;

  private:
    void completed(libcamera::Request* request);  // on libcamera's thread
    void set_controls(libcamera::Request& request) const;
    void finish(std::string error);  // with mutex_ held

    std::unique_ptr<libcamera::CameraManager> manager_;
    std::shared_ptr<libcamera::Camera> camera_;
    std::unique_ptr<libcamera::CameraConfiguration> configuration_;
    std::unique_ptr<libcamera::FrameBufferAllocator> allocator_;
    libcamera::Stream* stream_ = nullptr;
    int width_px_ = 0, height_px_ = 0, stride_bytes_ = 0;
    std::vector<MappedBuffer> buffers_;
    std::vector<std::unique_ptr<libcamera::Request>> requests_;
    bool started_ = false;

    hal::Notifier done_;
    std::mutex mutex_;
    bool running_ = false;
    hal::CaptureRequest asked_;
    int frames_queued_ = 0;
    hal::CaptureResult result_;
    bool result_ready_ = false;
};

LibcameraCamera::LibcameraCamera(const LibcameraSettings& settings) {
    // libcamera's own log shares standard error with the box's lines: errors only, unless the
    // owner asks for more (LIBCAMERA_LOG_LEVELS, read when libcamera first logs).
    ::setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", 0);
    manager_ = std::make_unique<libcamera::CameraManager>();
    if (manager_->start() != 0)
        throw std::runtime_error("libcamera: the camera manager did not start");
    if (manager_->cameras().empty()) throw std::runtime_error("libcamera found no camera");
    camera_ = manager_->cameras().front();
    const std::string id = camera_->id();
    if (camera_->acquire() != 0)
        throw std::runtime_error("libcamera: camera " + id + " is in use by another program");
    configuration_ = camera_->generateConfiguration({libcamera::StreamRole::StillCapture});
    if (!configuration_ || configuration_->size() != 1)
        throw std::runtime_error("libcamera: camera " + id + " has no still capture stream");
    libcamera::StreamConfiguration& stream = configuration_->at(0);
    stream.pixelFormat = libcamera::formats::YUV420;  // its first plane is the grey picture
    stream.size = {static_cast<unsigned int>(settings.width_px),
                   static_cast<unsigned int>(settings.height_px)};
    stream.bufferCount = static_cast<unsigned int>(std::max(1, settings.buffer_count));
    if (configuration_->validate() == libcamera::CameraConfiguration::Invalid ||
        stream.pixelFormat != libcamera::formats::YUV420) {
        throw std::runtime_error("libcamera: camera " + id + " refuses YUV420 still captures");
    }
    if (camera_->configure(configuration_.get()) != 0)
        throw std::runtime_error("libcamera: camera " + id + " refused its configuration");
    stream_ = stream.stream();
    width_px_ = static_cast<int>(stream.size.width);
    height_px_ = static_cast<int>(stream.size.height);
    stride_bytes_ = static_cast<int>(stream.stride);

    allocator_ = std::make_unique<libcamera::FrameBufferAllocator>(camera_);
    if (allocator_->allocate(stream_) < 0)
        throw std::runtime_error("libcamera: camera " + id + ": no frame buffers");
    for (const auto& buffer : allocator_->buffers(stream_)) {
        const auto& planes = buffer->planes();
        if (planes.empty()) throw std::runtime_error("libcamera: a frame buffer without planes");
        // The planes share one dmabuf: map it once, up to the end of its last plane.
        std::size_t length = 0;
        for (const auto& p : planes) length = std::max<std::size_t>(length, p.offset + p.length);
        void* mapping = ::mmap(nullptr, length, PROT_READ, MAP_SHARED, planes[0].fd.get(), 0);
        if (mapping == MAP_FAILED)
            throw std::runtime_error("libcamera: camera " + id + ": cannot map a frame buffer");
        buffers_.push_back({buffer.get(),
                            static_cast<const std::uint8_t*>(mapping) + planes[0].offset, mapping,
                            length});
        auto request = camera_->createRequest(requests_.size());
        if (!request || request->addBuffer(stream_, buffer.get()) != 0)
            throw std::runtime_error("libcamera: camera " + id + ": cannot make a request");
        requests_.push_back(std::move(request));
    }
    camera_->requestCompleted.connect(this, &LibcameraCamera::completed);
    if (camera_->start() != 0)
        throw std::runtime_error("libcamera: camera " + id + " did not start");
    started_ = true;
}

LibcameraCamera::~LibcameraCamera() {
    if (started_) camera_->stop();  // cancels what is queued; completions end before it returns
    camera_->requestCompleted.disconnect(this);
    requests_.clear();
    for (const auto& b : buffers_) ::munmap(b.mapping, b.mapping_length);
    allocator_.reset();
    if (camera_) camera_->release();
    camera_.reset();
    manager_->stop();
}

void LibcameraCamera::set_controls(libcamera::Request& request) const {
    auto& c = request.controls();
    const bool manual = asked_.exposure.has_value() || asked_.analogue_gain.has_value();
    set_manual_exposure(c, manual);
    if (asked_.exposure)
        c.set(libcamera::controls::ExposureTime,
              static_cast<std::int32_t>(asked_.exposure->count()));
    if (asked_.analogue_gain)
        c.set(libcamera::controls::AnalogueGain, static_cast<float>(*asked_.analogue_gain));
}

void LibcameraCamera::start_capture(const hal::CaptureRequest& request) {
    if (request.frame_count < 1) throw std::invalid_argument("a capture takes at least one frame");
    const std::lock_guard lock(mutex_);
    if (running_) throw std::logic_error("a capture is already running");
    running_ = true;
    result_ = {};
    result_ready_ = false;
    asked_ = request;
    frames_queued_ = 0;
    for (auto& r : requests_) {
        if (frames_queued_ == request.frame_count) break;
        r->reuse(libcamera::Request::ReuseBuffers);
        set_controls(*r);
        if (camera_->queueRequest(r.get()) != 0) {
            finish("libcamera: the camera refused a request (gone?)");
            return;
        }
        ++frames_queued_;
    }
}

void LibcameraCamera::finish(std::string error) {
    if (!error.empty()) {
        result_.frames.clear();
        result_.error = std::move(error);
    }
    running_ = false;
    result_ready_ = true;
    done_.signal();
}

void LibcameraCamera::completed(libcamera::Request* request) {
    const std::lock_guard lock(mutex_);
    if (!running_) return;
    if (request->status() == libcamera::Request::RequestCancelled) {
        finish("libcamera: the capture was cancelled (the camera stopped or is gone)");
        return;
    }
    libcamera::FrameBuffer* buffer = request->buffers().begin()->second;
    if (buffer->metadata().status != libcamera::FrameMetadata::FrameSuccess) {
        finish("libcamera: a frame failed (frame " + std::to_string(result_.frames.size() + 1) +
               ")");
        return;
    }
    const auto mapped = std::find_if(buffers_.begin(), buffers_.end(),
                                     [&](const MappedBuffer& b) { return b.buffer == buffer; });
    hal::Frame frame;
    frame.width_px = width_px_;
    frame.height_px = height_px_;
    frame.stride_bytes = width_px_;
    frame.format = hal::PixelFormat::gray8;
    frame.pixels.resize(static_cast<std::size_t>(width_px_) * static_cast<std::size_t>(height_px_));
    for (int y = 0; y < height_px_; ++y) {
        std::memcpy(
            frame.pixels.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(width_px_),
            mapped->y_plane + static_cast<std::size_t>(y) * static_cast<std::size_t>(stride_bytes_),
            static_cast<std::size_t>(width_px_));
    }
    const auto& metadata = request->metadata();
    if (const auto e = metadata.get(libcamera::controls::ExposureTime))
        frame.metadata.exposure = std::chrono::microseconds(*e);
    if (const auto g = metadata.get(libcamera::controls::AnalogueGain))
        frame.metadata.analogue_gain = *g;
    if (const auto t = metadata.get(libcamera::controls::SensorTimestamp))
        frame.metadata.timestamp = std::chrono::nanoseconds(*t);
    frame.metadata.sequence = buffer->metadata().sequence;
    result_.frames.push_back(std::move(frame));
    if (static_cast<int>(result_.frames.size()) == asked_.frame_count) {
        finish({});
        return;
    }
    if (frames_queued_ < asked_.frame_count) {
        request->reuse(libcamera::Request::ReuseBuffers);
        set_controls(*request);
        if (camera_->queueRequest(request) != 0) {
            finish("libcamera: the camera refused a request (gone?)");
            return;
        }
        ++frames_queued_;
    }
}

hal::CaptureResult LibcameraCamera::take_frames() {
    done_.take();
    const std::lock_guard lock(mutex_);
    if (!result_ready_) return {{}, "no capture has finished"};
    result_ready_ = false;
    return std::exchange(result_, {});
}

}  // namespace

std::unique_ptr<hal::Camera> open_libcamera_camera(const LibcameraSettings& settings) {
    return std::make_unique<LibcameraCamera>(settings);
}

}  // namespace calbox::drivers
