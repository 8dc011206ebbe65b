#include "firmware/links/host_link.hpp"

#include <nlohmann/json.hpp>
#include <thread>

#include "firmware/loop/event_loop.hpp"

namespace calbox::firmware {

std::string http_error_line(const hal::HttpResponse& reply) {
    std::string status = "HTTP " + std::to_string(reply.status);
    const auto j = nlohmann::json::parse(reply.body, nullptr, false);
    if (j.is_discarded() || !j.is_object() || !j.contains("error")) return status;
    const auto& error = j["error"];
    if (error.is_string()) return status + ": " + error.get<std::string>();
    if (error.is_object() && error.contains("message") && error["message"].is_string())
        return status + ": " + error["message"].get<std::string>();
    return status;
}

HostLink::HostLink(std::string name, net::Url url, hal::HttpClient& http, Log log)
    : name_(std::move(name)),
      url_(std::move(url)),
      where_(url_.origin()),
      http_(&http),
      log_(std::move(log)),
      job_(std::make_unique<hal::BackgroundJob<JobOutcome>>()) {}

HostLink::HostLink(std::string name, std::string address, Log log)
    : name_(std::move(name)),
      where_(std::move(address)),
      log_(std::move(log)),
      job_(std::make_unique<hal::BackgroundJob<JobOutcome>>()) {}

hal::HttpClient& HostLink::http_client() const {
    if (http_ == nullptr) throw std::logic_error(describe() + " is not spoken to over HTTP");
    return *http_;
}

void HostLink::attach(EventLoop& loop) {
    loop.watch(job_->fd(), [this] { finished(); });
}

void HostLink::detach(EventLoop& loop) {
    if (job_) loop.unwatch(job_->fd());
}

std::string HostLink::closing_note() const {
    if (printing_ || left_a_print_)
        return "the job in flight on " + describe() + " is left to the host (cancel it there)";
    return "the link to " + describe() + " is closed";
}

void HostLink::start(std::function<JobOutcome()> request, Done done) {
    if (busy()) throw std::logic_error("a request to " + describe() + " is already running");
    done_ = std::move(done);
    cancelled_.clear();
    stopping_ = false;
    left_a_print_ = false;
    job_->start([request = std::move(request)] {
        try {
            return request();
        } catch (const std::exception& e) {
            return JobOutcome{false, e.what(), {}, {}};
        }
    });
}

void HostLink::finish_requests() {
    stopping_ = true;
    job_.reset();  // joins the request thread
}

void HostLink::finished() {
    auto outcome = job_->take();
    if (!outcome || !done_) return;
    if (!cancelled_.empty()) *outcome = JobOutcome{false, cancelled_, {}, {}};
    auto done = std::move(done_);
    done_ = nullptr;
    done(std::move(*outcome));
}

void HostLink::cancel(const std::string& why) {
    if (!busy()) return;
    cancelled_ = why;
    stopping_ = true;
    if (printing_) {
        left_a_print_ = true;
        log_.warning(describe() + ": the print goes on there; cancel it on the host if needed");
    }
}

void HostLink::check_stop() const {
    if (stopping_) throw LinkError("stopped");
}

JobOutcome HostLink::follow_print(std::chrono::milliseconds poll_interval,
                                  std::chrono::milliseconds start_timeout,
                                  const std::function<PrintReport(bool seen_printing)>& poll) {
    const PrintingOnHost printing(*this);
    bool seen_printing = false;
    const auto started = std::chrono::steady_clock::now();
    for (;;) {
        pause(poll_interval);
        const PrintReport report = poll(seen_printing);
        if (report.over) return *report.over;
        if (report.printing)
            seen_printing = true;
        else if (!seen_printing && std::chrono::steady_clock::now() - started > start_timeout)
            throw LinkError("the print never started on the host (" + report.state + ")");
    }
}

void HostLink::pause(std::chrono::milliseconds how_long) const {
    const auto until = std::chrono::steady_clock::now() + how_long;
    for (;;) {
        check_stop();
        const auto now = std::chrono::steady_clock::now();
        if (now >= until) return;
        std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(
            until - now, std::chrono::milliseconds(20)));
    }
}

}  // namespace calbox::firmware
