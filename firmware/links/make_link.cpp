#include "firmware/links/make_link.hpp"

#include <array>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/models/link_kinds.hpp"
#include "firmware/links/duet_link.hpp"
#include "firmware/links/linuxcnc_link.hpp"
#include "firmware/links/moonraker_link.hpp"
#include "firmware/links/octoprint_link.hpp"

namespace calbox::firmware {
namespace {

std::chrono::milliseconds milliseconds_of(double seconds) {
    return std::chrono::milliseconds(static_cast<long long>(seconds * 1000));
}

// The file's words (a key, or passwords), 1 to `most` of them; never in a message.
std::vector<std::string> read_key_words(const std::string& path, std::size_t most) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("[link] key_file " + path + ": cannot be read");
    std::vector<std::string> words;
    for (std::string word; in >> word;) words.push_back(word);
    if (words.empty()) throw std::runtime_error("[link] key_file " + path + ": empty");
    if (words.size() > most)
        throw std::runtime_error(
            "[link] key_file " + path + ": holds more than " +
            (most == 1 ? std::string("one word") : std::to_string(most) + " words"));
    return words;
}

// The key, whitespace around it dropped; never in a message.
std::string read_key_file(const std::string& path) {
    if (path.empty()) return {};
    return read_key_words(path, 1).front();
}

// What every factory may need: the machine, the board's devices, the serial host's settings.
struct LinkContext {
    const models::MachineFile& machine;
    hal::SerialPort* port;
    hal::Network* network;
    hal::Clock& clock;
    GcodeHostSettings serial;
    const GcodeHost::Log& log;

    const models::MachineLinkSettings& link() const { return machine.link; }
    hal::Network& needs_network() const {
        if (link().url.empty())
            throw std::runtime_error("[link] kind = \"" + link().kind + "\" needs the host's url");
        if (network == nullptr)
            throw std::runtime_error("the machine's link is " + link().kind +
                                     " but the board has no network for it");
        return *network;
    }
    net::Url http_url() const {
        needs_network();
        try {
            net::Url url = net::parse_url(link().url);
            url.ca_file = link().ca_file;
            return url;
        } catch (const std::invalid_argument& e) {
            throw std::runtime_error(std::string("[link] url: ") + e.what());
        }
    }
    // The machine file's url and reply timeout; the rest as HttpHostSettings has them.
    void fill_http_host(HttpHostSettings& s) const {
        s.url = http_url();
        s.reply_timeout = milliseconds_of(link().reply_timeout_s);
    }
};

std::unique_ptr<MachineLink> serial_link(const LinkContext& c) {
    if (c.machine.firmware == "linuxcnc")
        throw std::runtime_error(
            "LinuxCNC reads no G-code over a serial port: give the machine file [link] kind "
            "= \"linuxcnc\" and url = \"HOST:5007\" (its linuxcncrsh server)");
    if (c.port == nullptr)
        throw std::runtime_error("the machine's link is serial but the board has no port for it");
    GcodeHostSettings serial = c.serial;
    serial.numbered_lines = c.machine.firmware != "grbl";
    return std::make_unique<GcodeHost>(*c.port, c.clock, serial, c.log);
}

std::unique_ptr<MachineLink> moonraker_link(const LinkContext& c) {
    MoonrakerSettings s;
    c.fill_http_host(s);
    s.api_key = read_key_file(c.link().key_file);
    s.restart_timeout = milliseconds_of(c.link().restart_timeout_s);
    return std::make_unique<MoonrakerLink>(std::move(s), c.network->http(), c.log);
}

std::unique_ptr<MachineLink> octoprint_link(const LinkContext& c) {
    OctoPrintSettings s;
    c.fill_http_host(s);
    const auto& key_file = c.link().key_file;
    if (key_file.empty())
        throw std::runtime_error(
            "[link] OctoPrint needs key_file (where the console's `link key` keeps the key it "
            "asks OctoPrint for)");
    // Not there yet: the console's `link key` asks OctoPrint for it; until then each request
    // says so.
    std::error_code ec;
    if (std::filesystem::exists(key_file, ec)) s.api_key = read_key_file(key_file);
    s.key_file = key_file;
    return std::make_unique<OctoPrintLink>(std::move(s), c.network->http(), c.log);
}

std::unique_ptr<MachineLink> duet_link(const LinkContext& c) {
    DuetSettings s;
    c.fill_http_host(s);
    s.password = read_key_file(c.link().key_file);
    return std::make_unique<DuetLink>(std::move(s), c.network->http(), c.log);
}

std::unique_ptr<MachineLink> linuxcnc_link(const LinkContext& c) {
    const auto& link = c.link();
    hal::Network& network = c.needs_network();
    LinuxCncSettings s;
    try {
        const auto at = net::parse_host_port(link.url, true);
        s.host = at.host;
        s.port = at.port;
    } catch (const std::invalid_argument& e) {
        throw std::runtime_error(std::string("[link] url: ") + e.what() +
                                 " (linuxcncrsh's HOST:PORT, as cnc.local:5007)");
    }
    if (s.port == 0) throw std::runtime_error("[link] url " + link.url + ": the port is 0");
    if (link.key_file.empty()) {
        c.log.warning(
            "linuxcnc: no key_file: linuxcncrsh's default passwords (give your own with its "
            "--connectpw and --enablepw, and both in a key_file)");
    } else {
        const auto words = read_key_words(link.key_file, 2);
        s.connect_password = words[0];
        if (words.size() == 2) s.enable_password = words[1];
    }
    s.reply_timeout = milliseconds_of(link.reply_timeout_s);
    return std::make_unique<LinuxCncLink>(std::move(s), network, c.log);
}

// One factory per kind of core/models/link_kinds.hpp.
struct LinkFactory {
    std::string_view kind;
    std::unique_ptr<MachineLink> (*make)(const LinkContext&);
};
constexpr std::array<LinkFactory, 5> kFactories{{
    {"serial", serial_link},
    {"moonraker", moonraker_link},
    {"octoprint", octoprint_link},
    {"duet", duet_link},
    {"linuxcnc", linuxcnc_link},
}};
static_assert(models::names_every_link_kind(kFactories),
              "every kind of core/models/link_kinds.hpp needs one factory here, and only those");

}  // namespace

std::unique_ptr<MachineLink> make_machine_link(const models::MachineFile& machine,
                                               hal::SerialPort* port, hal::Network* network,
                                               hal::Clock& clock, GcodeHostSettings serial,
                                               const GcodeHost::Log& log) {
    const LinkContext context{machine, port, network, clock, serial, log};
    for (const auto& factory : kFactories)
        if (factory.kind == machine.link.kind) return factory.make(context);
    throw std::runtime_error("[link] kind '" + machine.link.kind + "' is not one the box speaks");
}

}  // namespace calbox::firmware
