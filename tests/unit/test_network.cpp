// The box's windows on the network, piece by piece: the password's hash against Python's PBKDF2,
// HTTP Basic decoding, HOST:PORT, the server's limits as a client meets them, the drift history
// and /metrics against hand-worked figures, the live view's guide where the geometry puts it, and
// the loop's inbox. The whole (a browser, a broker) is tests/network.
#include <CppUTest/TestHarness.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <initializer_list>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "drivers/file_storage.hpp"
#include "drivers/http_client.hpp"
#include "drivers/http_server.hpp"
#include "drivers/tls.hpp"
#include "drivers/network.hpp"
#include "drivers/password.hpp"
#include "firmware/cycle/overlays.hpp"
#include "firmware/loop/event_loop.hpp"
#include "firmware/net/box_news.hpp"
#include "firmware/net/live_view.hpp"
#include "firmware/net/web_tls.hpp"
#include "firmware/net/web_window.hpp"

using namespace calbox;
using namespace std::chrono_literals;

namespace {

// hashlib.pbkdf2_hmac("sha256", b"correct horse", bytes(range(16)), 100000), in Python.
constexpr const char* kPythonHash =
    "pbkdf2-sha256:100000:000102030405060708090a0b0c0d0e0f:"
    "57f2c2f0739748d516419b062a884666323c583ea4ae165504a81f7b53c62a09";

std::filesystem::path fresh_directory() {
    char pattern[] = "/tmp/calbox-network-XXXXXX";
    return ::mkdtemp(pattern);
}

// A TCP connection to 127.0.0.1:port that sends `bytes` and reads what comes until the server
// closes or `within` passes.
std::string exchange(int port, const std::string& bytes, std::chrono::milliseconds within = 3s) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in at{};
    at.sin_family = AF_INET;
    at.sin_port = htons(static_cast<std::uint16_t>(port));
    at.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd, reinterpret_cast<sockaddr*>(&at), sizeof at) != 0) {
        ::close(fd);
        return "connect failed";
    }
    timeval tv{static_cast<time_t>(within.count() / 1000),
               static_cast<suseconds_t>((within.count() % 1000) * 1000)};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    if (!bytes.empty()) (void)::write(fd, bytes.data(), bytes.size());
    std::string out;
    char buffer[4096];
    for (;;) {
        const ssize_t n = ::read(fd, buffer, sizeof buffer);
        if (n <= 0) break;
        out.append(buffer, static_cast<std::size_t>(n));
    }
    ::close(fd);
    return out;
}

firmware::HistoryEntry entry(int cycle, const std::string& result, std::optional<double> before_rms,
                             std::optional<double> after_rms, std::int64_t at,
                             std::optional<double> before_mean = {}) {
    firmware::HistoryEntry e;
    e.cycle = cycle;
    e.mode = "delta";
    e.result = result;
    e.finished_unix_s = at;
    if (before_rms) e.before = modes::ErrorFigures{before_mean, *before_rms, 2 * *before_rms};
    e.in_force = e.before;  // a delta's: the error as printed
    if (after_rms) e.after = modes::ErrorFigures{{}, *after_rms, 2 * *after_rms};
    e.seconds = 60;
    return e;
}

// Every one of `lines` in the metrics' text, else a failure showing the text.
void check_metrics_lines(const std::string& text, std::initializer_list<const char*> lines) {
    for (const char* line : lines)
        if (text.find(line) == std::string::npos)
            FAIL(("no line: " + std::string(line) + text).c_str());
}

}  // namespace

TEST_GROUP(Password){};

TEST(Password, matches_a_hash_python_made_and_nothing_else) {
    drivers::Pbkdf2Hasher hasher;
    CHECK_TRUE(net::is_password_hash(kPythonHash));
    CHECK_TRUE(hasher.matches("correct horse", kPythonHash));
    CHECK_FALSE(hasher.matches("correct horsE", kPythonHash));
    CHECK_FALSE(hasher.matches("", kPythonHash));
    // Its own hashes: a fresh salt each time, each verifying.
    const std::string a = hasher.hash("battery staple");
    const std::string b = hasher.hash("battery staple");
    CHECK_TRUE(a != b);
    CHECK_TRUE(hasher.matches("battery staple", a));
    CHECK_TRUE(hasher.matches("battery staple", b));
    CHECK_EQUAL(0u, a.rfind("pbkdf2-sha256:100000:", 0));
}

TEST(Password, refuses_malformed_hashes_and_passwords) {
    drivers::Pbkdf2Hasher hasher;
    for (const char* bad : {"", "plain", "pbkdf2-sha256:100000:0001020304050607",
                            "pbkdf2-sha256:999:000102030405060708090a0b0c0d0e0f:"
                            "57f2c2f0739748d516419b062a884666323c583ea4ae165504a81f7b53c62a09",
                            "pbkdf2-sha1:100000:000102030405060708090a0b0c0d0e0f:"
                            "57f2c2f0739748d516419b062a884666323c583ea4ae165504a81f7b53c62a09",
                            "pbkdf2-sha256:100000:000102030405060708090a0b0c0d0e0f:57f2"}) {
        CHECK_FALSE(net::is_password_hash(bad));
        CHECK_FALSE(hasher.matches("correct horse", bad));
    }
    CHECK_THROWS(std::invalid_argument, hasher.hash(""));
    CHECK_THROWS(std::invalid_argument, hasher.hash(std::string(257, 'x')));
}

TEST(Password, reads_http_basic_authorization) {
    // base64.b64encode(b"calbox:correct horse"), b"x:ab", b"x:a" in Python: no, two, one '='.
    STRCMP_EQUAL("correct horse",
                 net::basic_auth_password("Basic Y2FsYm94OmNvcnJlY3QgaG9yc2U=")->c_str());
    STRCMP_EQUAL("ab", net::basic_auth_password("Basic eDphYg==")->c_str());
    STRCMP_EQUAL("a", net::basic_auth_password("Basic eDph")->c_str());
    CHECK_FALSE(net::basic_auth_password("Bearer eDph").has_value());
    CHECK_FALSE(net::basic_auth_password("Basic !!!!").has_value());
    CHECK_FALSE(net::basic_auth_password("Basic YWJj").has_value());  // "abc": no colon
    CHECK_FALSE(net::basic_auth_password("Basic ").has_value());
}

TEST_GROUP(UploadBody){};

TEST(UploadBody, the_boundary_is_one_no_part_holds_and_every_part_is_framed_by_it) {
    // A file that holds the first two candidates: the third is taken.
    const auto form = net::multipart_form("file", "job.gcode", "G1 X1 ; calbox-0\ncalbox-1\n",
                                          {{"root", "gcodes"}});
    STRCMP_EQUAL("multipart/form-data; boundary=calbox-2", form.content_type.c_str());
    STRCMP_EQUAL(
        "--calbox-2\r\nContent-Disposition: form-data; name=\"root\"\r\n\r\ngcodes\r\n"
        "--calbox-2\r\nContent-Disposition: form-data; name=\"file\"; filename=\"job.gcode\"\r\n"
        "Content-Type: application/octet-stream\r\n\r\nG1 X1 ; calbox-0\ncalbox-1\n\r\n"
        "--calbox-2--\r\n",
        form.body.c_str());
    // A field's value counts too.
    STRCMP_EQUAL(
        "multipart/form-data; boundary=calbox-1",
        net::multipart_form("file", "a", "x", {{"note", "calbox-0"}}).content_type.c_str());
}

TEST_GROUP(HostPort){};

TEST(HostPort, reads_addresses_and_names_where_they_are_allowed) {
    auto hp = net::parse_host_port("127.0.0.1:8080", false);
    STRCMP_EQUAL("127.0.0.1", hp.host.c_str());
    LONGS_EQUAL(8080, hp.port);
    hp = net::parse_host_port("[::1]:9", false);
    STRCMP_EQUAL("::1", hp.host.c_str());
    STRCMP_EQUAL("127.0.0.1", net::parse_host_port("localhost:1", false).host.c_str());
    STRCMP_EQUAL("broker.lan", net::parse_host_port("broker.lan:1883", true).host.c_str());
    CHECK_THROWS(std::invalid_argument, net::parse_host_port("broker.lan:1883", false));
    for (const char* bad : {"1.2.3.4:70000", "1.2.3.4", ":80", "1.2.3.4:", "1.2.3.4:8a", "a b:1"})
        CHECK_THROWS(std::invalid_argument, net::parse_host_port(bad, true));
}

TEST_GROUP(ServerLimits){};

TEST(ServerLimits, refuses_each_excess_with_its_status_and_lets_idle_clients_go) {
    hal::ServerLimits limits;
    limits.max_body_bytes = 1000;
    limits.max_header_bytes = 2000;
    // Long enough that a loaded machine's third client comes well inside it.
    limits.idle_timeout = 1500ms;
    std::atomic<int> served{0};
    const drivers::HttpServer::Handlers echo{
        [&](const hal::ServerRequest& r) {
            ++served;
            return hal::ServerResponse{
                200, "text/plain", std::to_string(r.body.size()), {{"X-Peer", r.peer}}};
        },
        {},
        {}};
    // No connection limit here: a loaded machine may not have let the last request's connection
    // go when the next one comes.
    drivers::HttpServer server("127.0.0.1", 0, echo, limits);
    const auto url = net::parse_url("http://127.0.0.1:" + std::to_string(server.port()) + "/");
    hal::HttpRequest post{"POST", "/", {}, "text/plain", std::string(1000, 'a')};
    const auto fits = drivers::http_request(url, post, 3s);
    LONGS_EQUAL(200, fits.status);
    STRCMP_EQUAL("1000", fits.body.c_str());
    post.body += "a";
    const auto over = drivers::http_request(url, post, 3s);
    LONGS_EQUAL(413, over.status);
    CHECK_TRUE(over.body.find("at most 1000 bytes") != std::string::npos);
    hal::HttpRequest big_header{"GET", "/", {{"X-Big", std::string(3000, 'b')}}, "", ""};
    LONGS_EQUAL(431, drivers::http_request(url, big_header, 3s).status);
    CHECK_EQUAL(0u, exchange(server.port(), "NOT HTTP\r\n\r\n").rfind("HTTP/1.1 400", 0));
    LONGS_EQUAL(1, served.load());

    // Two silent clients hold both connections: a third is told 503; the silent ones are let go
    // after the idle timeout, and then a request is served again.
    limits.max_connections = 2;
    drivers::HttpServer crowded("127.0.0.1", 0, echo, limits);
    const auto crowded_url =
        net::parse_url("http://127.0.0.1:" + std::to_string(crowded.port()) + "/");
    std::string first, second;
    std::thread a([&] { first = exchange(crowded.port(), "", 4s); });
    std::thread b([&] { second = exchange(crowded.port(), "", 4s); });
    std::this_thread::sleep_for(200ms);
    const std::string third = exchange(crowded.port(), "GET / HTTP/1.1\r\nHost: x\r\n\r\n");
    const auto waited = std::chrono::steady_clock::now();
    a.join();
    b.join();
    // Let go by the server at its 1.5 s, not by their own 4 s timeout.
    CHECK_TRUE(std::chrono::steady_clock::now() - waited < 3s);
    CHECK_EQUAL(0u, third.rfind("HTTP/1.1 503", 0));
    CHECK_TRUE(third.find("Retry-After: 2") != std::string::npos);
    STRCMP_EQUAL("", first.c_str());  // closed by the server, before the client's 4 s
    STRCMP_EQUAL("", second.c_str());
    const auto again = drivers::http_request(crowded_url, {"GET", "/", {}, "", ""}, 3s);
    LONGS_EQUAL(200, again.status);
}

TEST_GROUP(BoxNews) {
    std::filesystem::path dir;
    void setup() override {
        dir = fresh_directory();
    }
    void teardown() override {
        std::filesystem::remove_all(dir);
    }
};

TEST(BoxNews, keeps_the_history_and_works_out_the_drift_and_the_need) {
    drivers::FileStorage data(dir);
    firmware::BoxNews news(data, "1.2.3", {});
    CHECK_FALSE(news.drift_mm().has_value());
    CHECK_FALSE(news.needs_calibration().has_value());
    STRCMP_EQUAL("", news.add(entry(1, "applied", 0.2, 0.002, 1'700'000'000)).c_str());
    CHECK_FALSE(news.drift_mm().has_value());  // nothing calibrated before it
    news.add(entry(2, "cancelled", {}, {}, 1'700'000'100));
    news.add(entry(3, "applied", 0.03, 0.001, 1'700'086'400));
    // Cycle 3 measured 0.03 before its correction; cycle 1 had left 0.002: 0.028 of drift.
    DOUBLES_EQUAL(0.028, *news.drift_mm(), 1e-12);
    LONGS_EQUAL(1'700'086'400, *news.last_calibrated_unix_s());
    CHECK_FALSE(*news.needs_calibration());  // 0.03 is within the default 0.05
    news.set_needs_calibration_mm(0.02);
    CHECK_TRUE(*news.needs_calibration());
    // A mode with a mean is judged by its mean.
    news.add(entry(4, "applied", 0.5, 0.001, 1'700'090'000, 0.01));
    CHECK_FALSE(*news.needs_calibration());
    DOUBLES_EQUAL(0.01 - 0.001, *news.drift_mm(), 1e-12);
    // A mode whose correction the box keeps measured the raw machine 0.5 mm off, but jobs go
    // through the kept correction and met 0.004: that is the figure drift and the need ask.
    auto kept = entry(5, "unchanged", 0.5, {}, 1'700'091'000, 0.5);
    kept.in_force = modes::ErrorFigures{0.004, 0.005, 0.01};
    news.add(kept);
    CHECK_FALSE(*news.needs_calibration());
    DOUBLES_EQUAL(0.004 - 0.001, *news.drift_mm(), 1e-12);
    STRCMP_EQUAL("2023-11-15T22:40:00Z", firmware::utc_text(1'700'088'000).c_str());

    // Read back by the next start, line for line.
    firmware::BoxNews again(data, "1.2.3", [](const std::string& why) { FAIL(why.c_str()); });
    LONGS_EQUAL(5, static_cast<long>(again.history().size()));
    CHECK_TRUE(again.history() == news.history());
}

TEST(BoxNews, sets_a_damaged_history_aside_and_begins_anew) {
    drivers::FileStorage data(dir);
    data.replace_file("history.json", "{\"cycles\": [{\"cycle\": ");
    std::string told;
    firmware::BoxNews news(data, "1.2.3", [&](const std::string& why) { told = why; });
    CHECK_TRUE(told.find("history.json does not parse") != std::string::npos);
    CHECK_TRUE(news.history().empty());
    STRCMP_EQUAL("{\"cycles\": [{\"cycle\": ", data.read_file("history.json.damaged")->c_str());
    CHECK_FALSE(data.read_file("history.json").has_value());
}

TEST(BoxNews, keeps_the_last_thousand_lines) {
    drivers::FileStorage data(dir);
    firmware::BoxNews news(data, "1.2.3", {});
    for (int i = 1; i <= 1005; ++i) news.add(entry(i, "applied", 0.1, 0.001, 1'700'000'000 + i));
    LONGS_EQUAL(1000, static_cast<long>(news.history().size()));
    LONGS_EQUAL(6, news.history().front().cycle);
    LONGS_EQUAL(1000, static_cast<long>(firmware::BoxNews(data, "1.2.3", {}).history().size()));
}

TEST(BoxNews, metrics_in_base_units_with_their_types) {
    drivers::FileStorage data(dir);
    firmware::BoxNews news(data, "1.2.3", {});
    news.add(entry(1, "applied", 0.2, 0.002, 1'700'000'000));
    news.add(entry(2, "failed", {}, {}, 1'700'000'100));
    news.add(entry(3, "applied", 0.03, 0.001, 1'700'086'400));
    firmware::CycleReport report;
    report.number = 3;
    report.box_seconds = 1.5;
    report.camera_seconds = 20;
    report.machine_seconds = 600;
    const std::string text = news.metrics(firmware::CycleState::review, report);
    check_metrics_lines(
        text,
        {"# TYPE calbox_cycles_total counter\n",
         "calbox_cycles_total{mode=\"delta\",result=\"applied\"} 2\n",
         "calbox_cycles_total{mode=\"delta\",result=\"failed\"} 1\n",
         "calbox_build_info{version=\"1.2.3\"} 1\n", "calbox_state{state=\"review\"} 1\n",
         "calbox_state{state=\"idle\"} 0\n",
         // 0.03 mm before, 0.06 worst; 0.001 mm after, 0.002 worst: in metres.
         "calbox_last_error_metres{stage=\"before\",figure=\"rms\"} 3e-05\n",
         "calbox_last_error_metres{stage=\"before\",figure=\"max\"} 6e-05\n",
         "calbox_last_error_metres{stage=\"after\",figure=\"rms\"} 1e-06\n",
         "calbox_last_error_metres{stage=\"after\",figure=\"max\"} 2e-06\n",
         "calbox_last_cycle_duration_seconds{part=\"machine\"} 600\n",
         "calbox_drift_metres 2.8e-05\n", "calbox_last_calibration_timestamp_seconds 1700086400\n",
         "calbox_last_completed_cycle_timestamp_seconds 1700086400\n",
         "# TYPE calbox_history_cycles gauge\n",
         "calbox_history_cycles{mode=\"delta\",result=\"applied\"} 2\n",
         "calbox_history_cycles{mode=\"delta\",result=\"failed\"} 1\n",
         "calbox_needs_calibration 0\n"});
    CHECK_TRUE(text.find("figure=\"mean\"") == std::string::npos);  // a delta measures none
}

// A box restarted with its history: the kept history's counts and the last completed cycle (one
// that found the machine within its tolerance counts, and is not a calibration) survive the
// restart; the counter since the start begins again.
TEST(BoxNews, a_restarted_box_reports_its_kept_history) {
    drivers::FileStorage data(dir);
    {
        firmware::BoxNews news(data, "1.2.3", {});
        news.add(entry(1, "applied", 0.2, 0.002, 1'700'000'000));
        news.add(entry(2, "unchanged", 0.004, 0.003, 1'700'050'000));
        news.add(entry(3, "failed", {}, {}, 1'700'090'000));
    }
    const firmware::BoxNews again(data, "1.2.3", {});
    const std::string text = again.metrics(firmware::CycleState::idle, {});
    check_metrics_lines(text, {"calbox_history_cycles{mode=\"delta\",result=\"applied\"} 1\n",
                               "calbox_history_cycles{mode=\"delta\",result=\"unchanged\"} 1\n",
                               "calbox_history_cycles{mode=\"delta\",result=\"failed\"} 1\n",
                               "calbox_last_calibration_timestamp_seconds 1700000000\n",
                               "calbox_last_completed_cycle_timestamp_seconds 1700050000\n"});
    CHECK_TRUE(text.find("calbox_cycles_total{") == std::string::npos);
}

TEST_GROUP(LiveView){};

TEST(LiveView, draws_the_bed_judges_sharpness_and_marks_what_is_clipped_or_black) {
    // A camera 400 mm over the bed looking straight down (turned half round x: the bed's z up is
    // the camera's z into the scene negated), f 500 px: a bed of radius 100 mm is a circle of
    // 500 * 100 / 400 = 125 px round the image's centre.
    hal::Frame frame;
    frame.width_px = 400;
    frame.height_px = 300;
    frame.stride_bytes = 400;
    frame.pixels.assign(400 * 300, 60);
    for (int y = 0; y < 300; ++y)
        for (int x = 0; x < 400; ++x)
            if (((x / 8) + (y / 8)) % 2 == 0)
                frame.pixels[static_cast<std::size_t>(y * 400 + x)] = 120;
    firmware::LiveGuide guide;
    geometry::CameraModel camera;
    camera.image_width = 400;
    camera.image_height = 300;
    camera.camera_matrix = {500, 0, 200, 0, 500, 150, 0, 0, 1};
    camera.distortion = {0, 0, 0, 0, 0};
    geometry::BedPlane plane;
    plane.bed_to_camera.rvec = {M_PI, 0, 0};
    plane.bed_to_camera.tvec_mm = {0, 0, 400};
    guide.camera = camera;
    guide.plane = plane;
    guide.bed_radius_mm = 100;
    const auto sharp = firmware::live_view(frame, guide, 960);
    LONGS_EQUAL(400, sharp.width_px);  // never scaled up
    const cv::Mat image = cv::imdecode(
        std::vector<unsigned char>(sharp.jpeg.begin(), sharp.jpeg.end()), cv::IMREAD_COLOR);
    LONGS_EQUAL(300, image.rows);
    const auto orange = [&](int x, int y) {
        const auto p = image.at<cv::Vec3b>(y, x);  // BGR
        return p[2] > 180 && p[1] > 120 && p[0] < 110;
    };
    CHECK_TRUE(orange(325, 150));  // the circle's right, bottom and left
    CHECK_TRUE(orange(200, 275));
    CHECK_TRUE(orange(75, 150));
    CHECK_FALSE(orange(300, 150));  // inside it, the bed's own grey
    // The same pattern blurred: lower sharpness.
    hal::Frame soft = frame;
    for (int y = 1; y < 299; ++y)
        for (int x = 1; x < 399; ++x) {
            int sum = 0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx)
                    sum += frame.pixels[static_cast<std::size_t>((y + dy) * 400 + x + dx)];
            soft.pixels[static_cast<std::size_t>(y * 400 + x)] = static_cast<std::uint8_t>(sum / 9);
        }
    CHECK_TRUE(firmware::live_view(soft, guide, 200).sharpness < sharp.sharpness / 2);
    LONGS_EQUAL(200, firmware::live_view(soft, guide, 200).width_px);
    CHECK_THROWS(std::invalid_argument, firmware::live_view(hal::Frame{}, guide, 200));
    // Nothing clipped or black in the pattern; a lamp's hot spot (a 100 x 100 square at 255)
    // and a black strip (40 x 300 at 0) are marked and said, in their share of the frame.
    DOUBLES_EQUAL(0, sharp.clipped_share, 0);
    DOUBLES_EQUAL(0, sharp.black_share, 0);
    hal::Frame glare = frame;
    for (int y = 0; y < 300; ++y)
        for (int x = 0; x < 400; ++x) {
            auto& p = glare.pixels[static_cast<std::size_t>(y * 400 + x)];
            if (x >= 250 && x < 350 && y >= 50 && y < 150) p = 255;
            if (x < 40) p = 0;
        }
    const auto marked = firmware::live_view(glare, guide, 400);
    DOUBLES_EQUAL(100.0 * 100 / (400 * 300), marked.clipped_share, 1e-9);
    DOUBLES_EQUAL(40.0 * 300 / (400 * 300), marked.black_share, 1e-9);
    const cv::Mat marked_image = cv::imdecode(
        std::vector<unsigned char>(marked.jpeg.begin(), marked.jpeg.end()), cv::IMREAD_COLOR);
    const auto p = marked_image.at<cv::Vec3b>(100, 300);  // BGR: red
    CHECK_TRUE(p[2] > 200 && p[0] < 90 && p[1] < 90);
    const auto q = marked_image.at<cv::Vec3b>(250, 20);  // blue
    CHECK_TRUE(q[0] > 200 && q[2] < 60);
}

TEST(LiveView, one_drawing_of_the_newest_frame_for_every_viewer_and_again_when_the_guide_grows) {
    firmware::LatestFrame frames;
    firmware::SharedLiveView view;
    firmware::LiveGuide guide;
    CHECK_TRUE(view.of_newest(frames, guide, 200) == nullptr);  // no frame yet
    hal::Frame frame;
    frame.width_px = 64;
    frame.height_px = 48;
    frame.stride_bytes = 64;
    frame.pixels.assign(64 * 48, 90);
    frames.put(frame);
    const std::weak_ptr<const hal::Frame> first = frames.newest();
    const auto drawn = view.of_newest(frames, guide, 200);
    LONGS_EQUAL(1, static_cast<long>(drawn->sequence));
    CHECK_TRUE(view.of_newest(frames, guide, 200) == drawn);  // the same drawing, shared
    // A set-up view taken, no new frame: the guide is drawn again over the same frame.
    guide.views.push_back({{10, 10}, {50, 10}, {50, 40}, {10, 40}});
    guide.coverage = 0.25;
    const auto with_view = view.of_newest(frames, guide, 200);
    CHECK_TRUE(with_view != drawn);
    LONGS_EQUAL(1, static_cast<long>(with_view->sequence));
    CHECK_TRUE(view.of_newest(frames, guide, 200) == with_view);
    // A new frame: drawn from it, and nothing keeps the first frame alive any more (the view
    // holds a frame only while drawing it).
    frame.pixels.assign(64 * 48, 160);
    frames.put(frame);
    LONGS_EQUAL(2, static_cast<long>(view.of_newest(frames, guide, 200)->sequence));
    CHECK_TRUE(first.expired());
    LONGS_EQUAL(2, frames.newest().use_count());  // the latest frame's own copy, and ours
    // A viewer asking past the newest waits (here 50 ms, none coming) and is given the newest.
    frames.wait_past(2, std::chrono::milliseconds(50));
    LONGS_EQUAL(2, static_cast<long>(view.of_newest(frames, guide, 200)->sequence));
}

TEST_GROUP(WebTls){};

TEST(WebTls, the_plain_port_redirects_to_the_same_path_and_never_takes_the_password) {
    hal::ServerRequest r;
    r.target = "/api/status?after=3";
    r.headers["host"] = "192.168.1.23:8080";
    auto a = firmware::plain_port_answer(r, 8443);
    LONGS_EQUAL(308, a.status);
    STRCMP_EQUAL("Location", a.headers.at(0).first.c_str());
    STRCMP_EQUAL("https://192.168.1.23:8443/api/status?after=3", a.headers.at(0).second.c_str());
    r.headers["host"] = "[fe80::1]:80";
    a = firmware::plain_port_answer(r, 443);
    STRCMP_EQUAL("https://[fe80::1]:443/api/status?after=3", a.headers.at(0).second.c_str());
    r.headers["host"] = "calbox.local";
    STRCMP_EQUAL("https://calbox.local:443/api/status?after=3",
                 firmware::plain_port_answer(r, 443).headers.at(0).second.c_str());
    // A password sent in the clear: refused whatever it is, nowhere to follow.
    r.headers["authorization"] = "Basic Y2FsYm94OnNlY3JldA==";
    a = firmware::plain_port_answer(r, 443);
    LONGS_EQUAL(403, a.status);
    CHECK_TRUE(a.headers.empty());
    STRCMP_CONTAINS("not taken over plain http", a.body.c_str());
    // A Host no client could mean (a header smuggled in it, no host at all): no redirect.
    r.headers.erase("authorization");
    r.headers["host"] = "evil.example\r\nSet-Cookie: x";
    LONGS_EQUAL(400, firmware::plain_port_answer(r, 443).status);
    r.headers.erase("host");
    LONGS_EQUAL(400, firmware::plain_port_answer(r, 443).status);
}

TEST(WebTls, the_fingerprint_in_four_lines_of_four_groups_for_the_display) {
    const std::string fp =
        "94:28:29:00:86:63:E6:BB:AD:D0:D3:BB:E3:94:79:9E:AC:53:62:CB:34:D6:"
        "1D:F4:EA:EE:82:C0:D3:BF:C8:46";
    const auto lines = firmware::fingerprint_lines(fp);
    LONGS_EQUAL(4, static_cast<long>(lines.size()));
    STRCMP_EQUAL("9428 2900 8663 E6BB", lines[0].c_str());
    STRCMP_EQUAL("ADD0 D3BB E394 799E", lines[1].c_str());
    STRCMP_EQUAL("AC53 62CB 34D6 1DF4", lines[2].c_str());
    STRCMP_EQUAL("EAEE 82C0 D3BF C846", lines[3].c_str());
    for (const auto& line : lines)
        CHECK_TRUE(line.size() <= static_cast<std::size_t>(firmware::kScreenColumns));
}

TEST(WebTls, the_box_makes_its_own_certificate_once_keeps_it_and_renews_it_before_its_end) {
    namespace fs = std::filesystem;
    const fs::path dir =
        fs::temp_directory_path() / ("calbox-webtls-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    const auto network = drivers::system_network();
    auto& certificates = network->certificates();
    std::vector<std::string> logged;
    const hal::Log log([&](hal::LogLevel, const std::string& line) { logged.push_back(line); });
    firmware::WebSettings settings;
    settings.tls_listen = "192.168.1.23:8443";
    const std::int64_t now = 1'790'000'000;  // 2026-09-21
    const auto first = firmware::web_tls_identity(settings, dir.string(), certificates, now, log);
    CHECK_TRUE(first.self_signed);
    LONGS_EQUAL(1, static_cast<long>(logged.size()));
    STRCMP_CONTAINS(first.facts.sha256_fingerprint.c_str(), logged[0].c_str());
    STRCMP_EQUAL("192.168.1.23", first.facts.subject.c_str());
    LONGS_EQUAL(95, static_cast<long>(first.facts.sha256_fingerprint.size()));
    struct stat key {};
    CHECK_EQUAL(0, ::stat((dir / firmware::kSelfSignedKeyFile).c_str(), &key));
    LONGS_EQUAL(0600, static_cast<long>(key.st_mode & 0777));
    // Made from the wall clock, valid ten years: past now plus nine.
    CHECK_TRUE(first.facts.not_after_unix_s > now + 9LL * 365 * 24 * 3600);
    // The next start: the same certificate, nothing said.
    const auto again = firmware::web_tls_identity(settings, dir.string(), certificates, now, log);
    STRCMP_EQUAL(first.facts.sha256_fingerprint.c_str(), again.facts.sha256_fingerprint.c_str());
    LONGS_EQUAL(1, static_cast<long>(logged.size()));
    // Within 30 days of its end (a clock ten years on, less 20 days): made anew, and said.
    const std::int64_t late = first.facts.not_after_unix_s - 20LL * 24 * 3600;
    const auto renewed =
        firmware::web_tls_identity(settings, dir.string(), certificates, late, log);
    CHECK_TRUE(renewed.facts.sha256_fingerprint != first.facts.sha256_fingerprint);
    LONGS_EQUAL(2, static_cast<long>(logged.size()));
    STRCMP_CONTAINS("the last one ends on", logged[1].c_str());
    // The owner's files: a key that is not the certificate's is refused, naming the key.
    const hal::ServerTls other{(dir / "other.crt").string(), (dir / "other.key").string()};
    certificates.make_self_signed(other, {"127.0.0.1"}, 1);
    settings.tls_cert = (dir / firmware::kSelfSignedCertificateFile).string();
    settings.tls_key = other.key_file;
    try {
        firmware::web_tls_identity(settings, dir.string(), certificates, now, log);
        FAIL("a key that is not the certificate's was taken");
    } catch (const std::runtime_error& e) {
        STRCMP_CONTAINS("other.key: not the key of", e.what());
    }
    // The owner's certificate past its end: served, with a warning.
    settings.tls_cert = other.certificate_file;
    const auto a_day = certificates.check(other);  // valid a day
    const auto ended = firmware::web_tls_identity(settings, dir.string(), certificates,
                                                  a_day.not_after_unix_s + 1, log);
    CHECK_FALSE(ended.self_signed);
    STRCMP_CONTAINS("browsers refuse it", logged.back().c_str());
    fs::remove_all(dir);
}

TEST_GROUP(LoopInbox){};

TEST(LoopInbox, runs_other_threads_jobs_on_the_loops_thread) {
    firmware::EventLoop loop;
    firmware::LoopInbox inbox(loop);
    const auto loop_thread = std::this_thread::get_id();
    std::optional<bool> on_loop;
    std::optional<int> refused;
    bool threw = false;
    std::thread other([&] {
        on_loop = inbox.call<bool>([&] { return std::this_thread::get_id() == loop_thread; }, 5s);
        try {
            inbox.call<int>([]() -> int { throw std::runtime_error("no"); }, 5s);
        } catch (const std::runtime_error&) {
            threw = true;
        }
        loop.stop();
    });
    loop.run();
    other.join();
    CHECK_TRUE(on_loop.has_value() && *on_loop);
    CHECK_TRUE(threw);
    // A loop that does not run: the caller gives up after its wait.
    std::thread late([&] { refused = inbox.call<int>([] { return 1; }, 50ms); });
    late.join();
    CHECK_FALSE(refused.has_value());
}

TEST_GROUP(ErrorField){};

TEST(ErrorField, draws_each_error_magnified_by_a_round_factor_where_it_was_measured) {
    // Two points 100 mm apart each way, errors of 1 mm and 0.5 mm: a twelfth of the span over
    // the largest is 8.3, rounded down to 5. The map's 660 px cover 100 mm: 6.6 px a mm; the
    // point at (0, 0) sits at (70, 730) px and its 1 mm arrow reaches 70 + 5 x 6.6 = 103 px.
    const std::string png =
        firmware::error_field_png({{{0, 0}, {1, 0}}, {{100, 100}, {0, 0.5}}}, "test: two arrows");
    const cv::Mat image =
        cv::imdecode(std::vector<unsigned char>(png.begin(), png.end()), cv::IMREAD_COLOR);
    LONGS_EQUAL(800, image.cols);
    LONGS_EQUAL(800, image.rows);
    const auto red = [&](int x, int y) {
        const auto p = image.at<cv::Vec3b>(y, x);  // BGR
        return p[2] > 150 && p[0] < 120 && p[1] < 120;
    };
    CHECK_TRUE(red(90, 730));
    CHECK_FALSE(red(115, 730));  // past the tip
    // The second: from (730, 70) up by 0.5 x 5 x 6.6 = 16.5 px.
    CHECK_TRUE(red(730, 60));
    CHECK_FALSE(red(730, 45));
    CHECK_THROWS(std::invalid_argument, firmware::error_field_png({}, "none"));
}
