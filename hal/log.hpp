#pragma once
// Where a part of the box tells what it does, each line with how much it matters: under systemd
// the journal keeps the level (`journalctl -p warning` finds what went wrong), the console and
// the page show the text.
#include <concepts>
#include <cstddef>
#include <functional>
#include <string>
#include <utility>

namespace calbox::hal {

// syslog's levels, by their numbers: what the journal files a line under.
enum class LogLevel { error = 3, warning = 4, info = 6 };

class Log {
  public:
    using Sink = std::function<void(LogLevel, const std::string&)>;
    Log() = default;
    Log(std::nullptr_t) {}  // NOLINT(google-explicit-constructor): nobody listens
    template <class LevelSink>
    requires std::invocable<LevelSink&, LogLevel, const std::string&> Log(
        LevelSink sink)  // NOLINT(google-explicit-constructor)
        : sink_(std::move(sink)) {}
    // A listener that keeps only the text (a test's list of lines, a console's notices).
    template <class TextSink>
    requires std::invocable<TextSink&, const std::string&> &&
        (!std::invocable<TextSink&, LogLevel, const std::string&>)&&(!std::same_as<TextSink, Log>)
            Log(TextSink text)  // NOLINT(google-explicit-constructor)
        : sink_([text = std::move(text)](LogLevel, const std::string& line) mutable {
              text(line);
          }) {}

    // What the box does (the common case, hence the call operator).
    void operator()(const std::string& line) const { write(LogLevel::info, line); }
    // Something went wrong and the box goes on (a window that did not open, a link lost and
    // opened again, a request refused).
    void warning(const std::string& line) const { write(LogLevel::warning, line); }
    // Something an owner must act on: a cycle that stopped, a result not written.
    void error(const std::string& line) const { write(LogLevel::error, line); }
    void write(LogLevel level, const std::string& line) const {
        if (sink_) sink_(level, line);
    }
    explicit operator bool() const { return static_cast<bool>(sink_); }

  private:
    Sink sink_;
};

}  // namespace calbox::hal
