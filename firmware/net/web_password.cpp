#include "firmware/net/web_password.hpp"

#include <stdexcept>

namespace calbox::firmware {

ConsoleCommand web_password_row(Configuration& config, hal::PasswordHasher& passwords,
                                std::function<void()> config_changed) {
    return {"web password", "web password PASSWORD",
            "the web page's password, kept as its hash (--clear: none; config save keeps it)",
            [&config, &passwords, config_changed = std::move(config_changed)](
                const std::vector<std::string>& words, std::string_view line, ConsoleReply& r) {
                if (words.size() < 3) throw ConsoleRefused("usage: web password PASSWORD|--clear");
                const bool clear = words.size() == 3 && words[2] == "--clear";
                std::string hash;
                if (!clear) {
                    try {
                        hash = passwords.hash(console_words_after(line, 2));
                    } catch (const std::exception& e) {
                        throw ConsoleRefused(std::string("web password: ") + e.what());
                    }
                }
                config.set("web.password", hash);
                if (config_changed) config_changed();
                r.text = clear ? "web password cleared: the page changes nothing"
                               : "web password set (config save keeps it)";
                r.data = {{"password_set", !clear}};
            }};
}

}  // namespace calbox::firmware
