#pragma once
// The console's `link key`: asks OctoPrint for an API key for the box through its application
// keys plugin (the owner clicks Allow in OctoPrint's page), off the loop, and keeps it in the
// link's key_file (mode 0600), so that nobody copies a key by hand. The key is never shown: the
// console is told where it went. The link reads the file when the box starts.
#include <functional>
#include <memory>
#include <string>
#include <utility>

#include "core/models/machine_file.hpp"
#include "firmware/console/console.hpp"
#include "hal/background_job.hpp"
#include "hal/http.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

class EventLoop;

class LinkKeyRequest {
  public:
    using Notice = std::function<void(const std::string&)>;
    // Opens the key_file's directory when a key is to be kept (not before: it may not be there
    // yet when the box starts, which is no reason to stop it). Throws std::runtime_error.
    using OpenKeyDirectory = std::function<std::unique_ptr<hal::Storage>()>;
    LinkKeyRequest(EventLoop& loop, models::MachineLinkSettings link, hal::HttpClient& http,
                   OpenKeyDirectory open_key_directory, Notice notice);
    LinkKeyRequest(const LinkKeyRequest&) = delete;
    LinkKeyRequest& operator=(const LinkKeyRequest&) = delete;
    ~LinkKeyRequest();
    // The console's row: `link key [USER]`.
    ConsoleCommand command();

  private:
    void finished();
    EventLoop& loop_;
    models::MachineLinkSettings link_;
    hal::HttpClient& http_;
    OpenKeyDirectory open_key_directory_;
    Notice notice_;
    // The key, or why there is none.
    hal::BackgroundJob<std::pair<bool, std::string>> request_;
};

}  // namespace calbox::firmware
