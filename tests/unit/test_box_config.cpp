// The box's configuration: the schema's strictness, the console's get/set/reset, and a save that
// a power cut or a killed process never leaves broken.
#include <CppUTest/TestHarness.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <random>

#include "drivers/durable_file.hpp"
#include "drivers/file_storage.hpp"
#include "firmware/app/box_config.hpp"
#include "tests/support/device_errors.hpp"

using namespace calbox;

namespace {

std::string config_error(const std::string& text) {
    return test::construction_error([&] { firmware::BoxConfig::from_toml(text, "calbox.toml"); });
}

}  // namespace

TEST_GROUP(BoxConfig){};

TEST(BoxConfig, reads_every_table_and_names_the_line_of_what_it_does_not_know) {
    const auto config = firmware::BoxConfig::from_toml(
        "[modbus]\nserver = \"tcp:0.0.0.0:502\"\nword_order = \"cdab\"\nbyte_timeout_ms = 200\n"
        "[cycle]\nframes_per_capture = 4\n[setup]\nplane_board_thickness_mm = 3\n"
        "[records]\nkeep_photos = true\n",
        "calbox.toml");
    const auto& modbus = config.settings().modbus;
    CHECK_TRUE(modbus.server.has_value());
    STRCMP_EQUAL("0.0.0.0", modbus.server->host.c_str());
    CHECK_EQUAL(502, modbus.server->port);
    STRCMP_EQUAL("tcp:0.0.0.0:502", config.get("modbus.server").c_str());
    CHECK_FALSE(modbus.client.has_value());
    CHECK(models::WordOrder::cdab == modbus.word_order);
    CHECK_EQUAL(200U, modbus.timeouts.byte_ms);
    CHECK_EQUAL(1000U, modbus.timeouts.response_ms);  // the default
    const auto& settings = config.settings().cycle;
    CHECK_EQUAL(4, settings.frames_per_capture);
    DOUBLES_EQUAL(3.0, settings.plane_board_thickness_mm, 0);  // an integer where a number is
    CHECK_TRUE(settings.records.keep_photos);
    CHECK_EQUAL(50, settings.records.keep_cycles);
    CHECK_EQUAL(500000000U, settings.records.max_bytes);

    STRCMP_CONTAINS("calbox.toml:3: [modbus] sever: unknown key",
                    config_error("[modbus]\nserver = \"\"\nsever = \"tcp:h:1\"\n").c_str());
    STRCMP_CONTAINS("calbox.toml:2: [modbus] server: modbus endpoint 'tcp:h' is not tcp:HOST:PORT",
                    config_error("[modbus]\nserver = \"tcp:h\"\n").c_str());
    STRCMP_CONTAINS("[modbus] word_order: 'ABCD' is not one of abcd|cdab|badc|dcba",
                    config_error("[modbus]\nword_order = \"ABCD\"\n").c_str());
    STRCMP_CONTAINS("[modbus] byte_timeout_ms: '0' is not a whole number 5 to 10000 ms",
                    config_error("[modbus]\nbyte_timeout_ms = 0\n").c_str());
    STRCMP_CONTAINS("[cycle] frames_per_capture: must be a whole number 1 to 16 photos",
                    config_error("[cycle]\nframes_per_capture = 2.5\n").c_str());
    STRCMP_CONTAINS("[records] keep_photos: must be true or false",
                    config_error("[records]\nkeep_photos = \"yes\"\n").c_str());
    STRCMP_CONTAINS("[setup] plane_pattern: ",
                    config_error("[setup]\nplane_pattern = \"chessboard:9x6\"\n").c_str());
    STRCMP_CONTAINS("calbox.toml: [modbus] client_map: needs client",
                    config_error("[modbus]\nclient_map = \"map.toml\"\n").c_str());
    STRCMP_CONTAINS("calbox.toml:1: [gpio] is not a table calbox knows",
                    config_error("[gpio]\nbutton = 3\n").c_str());
    STRCMP_CONTAINS("calbox.toml:2:", config_error("[modbus]\nserver = \n").c_str());
}

TEST(BoxConfig, a_set_is_validated_before_it_takes_and_reset_gives_the_default) {
    firmware::BoxConfig config;
    config.set("cycle.frames_per_capture", "3");
    STRCMP_EQUAL("3", config.get("cycle.frames_per_capture").c_str());
    const firmware::BoxConfig before = config;
    STRCMP_CONTAINS(
        "cycle.frames_per_capture: '17' is not a whole number 1 to 16 photos",
        test::construction_error([&] { config.set("cycle.frames_per_capture", "17"); }).c_str());
    STRCMP_CONTAINS("'3x' is not", test::construction_error([&] {
                                       config.set("cycle.frames_per_capture", "3x");
                                   }).c_str());
    STRCMP_CONTAINS("'cycle.frames' is not a configuration key",
                    test::construction_error([&] { config.set("cycle.frames", "3"); }).c_str());
    STRCMP_CONTAINS(
        "modbus.client_map: [modbus] client_map: needs client",
        test::construction_error([&] { config.set("modbus.client_map", "m.toml"); }).c_str());
    STRCMP_CONTAINS(
        "console.baud: '115201' is not one of",
        test::construction_error([&] { config.set("console.baud", "115201"); }).c_str());
    CHECK_TRUE(config == before);  // nothing changed by the refusals
    config.set("setup.plane_board_thickness_mm", "2.5");
    DOUBLES_EQUAL(2.5, config.settings().cycle.plane_board_thickness_mm, 0);
    config.reset("cycle.frames_per_capture");
    STRCMP_EQUAL("1", config.get("cycle.frames_per_capture").c_str());
}

TEST(BoxConfig, the_network_keys_are_checked_as_the_console_checks_them) {
    firmware::BoxConfig config;
    config.set("web.listen", "0.0.0.0:8080");
    config.set("mqtt.broker", "broker.lan:1883");
    config.set("mqtt.node_id", "bench-2_a");
    config.set("report.needs_calibration_mm", "0.02");
    const firmware::BoxConfig before = config;
    for (const auto& [key, value] :
         std::vector<std::pair<std::string, std::string>>{{"web.listen", "box.local:8080"},
                                                          {"web.listen", "0.0.0.0:99999"},
                                                          {"mqtt.broker", "broker.lan"},
                                                          {"mqtt.node_id", "a/b"},
                                                          {"mqtt.node_id", "+"},
                                                          {"mqtt.discovery_prefix", "home#"},
                                                          {"web.password", "plain text"},
                                                          {"report.needs_calibration_mm", "0"}})
        CHECK_THROWS(firmware::ConfigError, config.set(key, value));
    CHECK_TRUE(config == before);
    const auto again = firmware::BoxConfig::from_toml(config.to_toml(), "saved.toml");
    STRCMP_EQUAL("0.0.0.0:8080", again.settings().web.listen.c_str());
    STRCMP_EQUAL("bench-2_a", again.settings().mqtt.node_id.c_str());
    DOUBLES_EQUAL(0.02, again.settings().report.needs_calibration_mm, 0);
}

TEST(BoxConfig, the_readme_documents_every_key) {
    std::ifstream in(std::string(CALBOX_SOURCE_DIR) + "/docs/appliance.md");
    const std::string readme((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
    CHECK_TRUE(readme.size() > 1000);
    for (const auto& key : firmware::BoxConfig().entries())
        CHECK_TEXT(readme.find("| `" + key.name + "` |") != std::string::npos, key.name.c_str());
}

TEST(BoxConfig, what_it_writes_reads_back_the_same_for_every_key) {
    firmware::BoxConfig config;
    config.set("console.device", "/dev/serial/by-id/usb \"quoted\" \\ name");
    config.set("modbus.client", "tcp:10.0.0.7:502");
    config.set("modbus.client_map", "map.toml");
    config.set("setup.plane_board_thickness_mm", "0.125");
    config.set("records.keep_photos", "true");
    config.set("cycle.long_press_ms", "2250");
    const auto again = firmware::BoxConfig::from_toml(config.to_toml(), "saved.toml");
    CHECK_TRUE(again == config);
    for (const auto& key : config.entries())
        STRCMP_EQUAL(config.get(key.name).c_str(), again.get(key.name).c_str());
    CHECK_FALSE(again == firmware::BoxConfig());
}

// A file system whose cache a power cut loses: data reaches the medium only when its file is
// flushed, a name only when its directory is. `names_first` is the worst real case (ext4's
// journal committed the rename while the data was still in the cache): a cut then keeps the
// directory's newest names but only each file's flushed data.
class PowerCutFileSystem final : public drivers::FileSystemCalls {
  public:
    struct PowerCut {};
    explicit PowerCutFileSystem(bool names_first) : names_first_(names_first) {}
    std::optional<int> cut_before_step;  // the power goes before this call (0: the first)
    int steps = 0;

    void put(const std::string& name, const std::string& contents) {  // an old file, on the medium
        inodes_.push_back({contents, contents});
        cached_[name] = durable_[name] = static_cast<int>(inodes_.size() - 1);
    }
    std::optional<std::string> file(const std::string& name) const {
        const auto it = cached_.find(name);
        if (it == cached_.end()) return std::nullopt;
        return inodes_[static_cast<std::size_t>(it->second)].cached;
    }
    void power_cut() {
        if (!names_first_) cached_ = durable_;
        durable_ = cached_;
        for (auto& inode : inodes_) inode.cached = inode.durable;
    }

    int create_truncated(const std::filesystem::path& path, drivers::FileAccess) override {
        step();
        const auto name = path.filename().string();
        if (const auto it = cached_.find(name); it != cached_.end()) {
            auto& inode = inodes_[static_cast<std::size_t>(it->second)];
            inode.cached.clear();
            if (names_first_) inode.durable.clear();  // the new size is metadata, journaled too
            return it->second;
        }
        inodes_.push_back({});
        return cached_[name] = static_cast<int>(inodes_.size() - 1);
    }
    void write_all(int handle, std::string_view bytes) override {
        // Written in two halves: a cut may fall between them.
        step();
        inodes_[static_cast<std::size_t>(handle)].cached.append(bytes.substr(0, bytes.size() / 2));
        step();
        inodes_[static_cast<std::size_t>(handle)].cached.append(bytes.substr(bytes.size() / 2));
    }
    void flush(int handle) override {
        step();
        auto& inode = inodes_[static_cast<std::size_t>(handle)];
        inode.durable = inode.cached;
    }
    void close(int) override { step(); }
    void rename(const std::filesystem::path& from, const std::filesystem::path& to) override {
        step();
        cached_[to.filename().string()] = cached_.at(from.filename().string());
        cached_.erase(from.filename().string());
    }
    void flush_directory(const std::filesystem::path&) override {
        step();
        durable_ = cached_;
    }
    void remove(const std::filesystem::path& path) noexcept override {
        cached_.erase(path.filename().string());
    }

  private:
    struct Inode {
        std::string cached, durable;
    };
    void step() {
        if (cut_before_step && steps == *cut_before_step) throw PowerCut{};
        ++steps;
    }
    bool names_first_;
    std::vector<Inode> inodes_;
    std::map<std::string, int> cached_, durable_;
};

using Save = std::function<void(drivers::FileSystemCalls&, const std::string&)>;

// Cuts the power before each step of `save` in turn (and once after it returned) and reads the
// file back: the first cut that leaves neither the old contents nor the new, or the save that
// returned but comes back old; "" when every cut is safe.
std::string first_unsafe_cut(const Save& save, bool names_first) {
    const std::string old_text = firmware::BoxConfig().to_toml();
    firmware::BoxConfig changed;
    changed.set("console.device", "/dev/ttyAMA0");
    changed.set("records.keep_cycles", "7");
    const std::string new_text = changed.to_toml();
    for (int cut = 0;; ++cut) {
        PowerCutFileSystem fs(names_first);
        fs.put("calbox.toml", old_text);
        fs.cut_before_step = cut;
        bool returned = false;
        try {
            save(fs, new_text);
            returned = true;
        } catch (const PowerCutFileSystem::PowerCut&) {
        }
        fs.power_cut();
        const auto after = fs.file("calbox.toml");
        const bool whole = after && (*after == old_text || *after == new_text);
        if (!whole) return "a cut before step " + std::to_string(cut) + " broke the file";
        // Every loaded file must parse: the old and the new one both do.
        (void)firmware::BoxConfig::from_toml(*after, "calbox.toml");
        if (returned) {
            if (*after != new_text) return "the save returned but a cut brought the old file back";
            return "";
        }
    }
}

TEST_GROUP(ConfigSave){};

TEST(ConfigSave, a_power_cut_at_any_step_of_a_save_leaves_the_old_file_or_the_new_one) {
    const Save durable = [](drivers::FileSystemCalls& fs, const std::string& text) {
        const auto dir = std::filesystem::temp_directory_path();
        drivers::FileStorage(dir, fs).replace_file("calbox.toml", text);
    };
    STRCMP_EQUAL("", first_unsafe_cut(durable, false).c_str());
    STRCMP_EQUAL("", first_unsafe_cut(durable, true).c_str());
}

TEST(ConfigSave, the_power_cut_double_catches_the_saves_that_are_not_safe) {
    // Writing in place: the truncation is journaled, a cut mid-write leaves an empty file.
    const Save in_place = [](drivers::FileSystemCalls& fs, const std::string& text) {
        const int h = fs.create_truncated("/box/calbox.toml", drivers::FileAccess::shared);
        fs.write_all(h, text);
        fs.flush(h);
        fs.close(h);
    };
    STRCMP_CONTAINS("broke the file", first_unsafe_cut(in_place, true).c_str());
    // Renaming before the data is flushed: the journal keeps the name, the data is lost.
    const Save unflushed = [](drivers::FileSystemCalls& fs, const std::string& text) {
        const int h = fs.create_truncated("/box/calbox.toml.tmp", drivers::FileAccess::shared);
        fs.write_all(h, text);
        fs.close(h);
        fs.rename("/box/calbox.toml.tmp", "/box/calbox.toml");
        fs.flush_directory("/box");
    };
    STRCMP_CONTAINS("broke the file", first_unsafe_cut(unflushed, true).c_str());
    // Not flushing the directory: the save returns, and a cut brings the old file back.
    const Save no_directory_flush = [](drivers::FileSystemCalls& fs, const std::string& text) {
        const int h = fs.create_truncated("/box/calbox.toml.tmp", drivers::FileAccess::shared);
        fs.write_all(h, text);
        fs.flush(h);
        fs.close(h);
        fs.rename("/box/calbox.toml.tmp", "/box/calbox.toml");
    };
    STRCMP_CONTAINS("brought the old file back",
                    first_unsafe_cut(no_directory_flush, false).c_str());
}

TEST(ConfigSave, a_private_file_is_the_owners_alone_from_its_first_byte) {
    char pattern[] = "/tmp/calbox-private-XXXXXX";
    const std::filesystem::path dir = ::mkdtemp(pattern);
    // A sibling an earlier cut left, readable by all: the key does not inherit its mode.
    std::ofstream(dir / "octoprint.key.tmp") << "old";
    std::filesystem::permissions(dir / "octoprint.key.tmp", std::filesystem::perms::all);
    struct Watch final : drivers::FileSystemCalls {
        drivers::FileSystemCalls& real = drivers::posix_file_system();
        std::filesystem::perms written_with{};
        int create_truncated(const std::filesystem::path& p, drivers::FileAccess a) override {
            return real.create_truncated(p, a);
        }
        void write_all(int h, std::string_view bytes) override {
            written_with =
                std::filesystem::status("/proc/self/fd/" + std::to_string(h)).permissions();
            real.write_all(h, bytes);
        }
        void flush(int h) override { real.flush(h); }
        void close(int h) override { real.close(h); }
        void rename(const std::filesystem::path& a, const std::filesystem::path& b) override {
            real.rename(a, b);
        }
        void flush_directory(const std::filesystem::path& d) override { real.flush_directory(d); }
        void remove(const std::filesystem::path& p) noexcept override { real.remove(p); }
    } watch;
    drivers::FileStorage storage(dir, watch);
    storage.replace_private_file("octoprint.key", "0123456789ABCDEF\n");
    const auto owner_only =
        std::filesystem::perms::owner_read | std::filesystem::perms::owner_write;
    CHECK_TRUE(watch.written_with == owner_only);
    CHECK_TRUE(std::filesystem::status(dir / "octoprint.key").permissions() == owner_only);
    STRCMP_EQUAL("0123456789ABCDEF\n", storage.read_file("octoprint.key")->c_str());
    // A record is readable by all, as before.
    storage.replace_file("cycle-0001-result.json", "{}");
    CHECK_TRUE((std::filesystem::status(dir / "cycle-0001-result.json").permissions() &
                std::filesystem::perms::others_read) != std::filesystem::perms::none);
    std::filesystem::remove_all(dir);
}

TEST(ConfigSave, a_process_killed_at_random_moments_while_saving_leaves_a_whole_file_200_times) {
    char pattern[] = "/tmp/calbox-kill-XXXXXX";
    const std::filesystem::path dir = ::mkdtemp(pattern);
    firmware::BoxConfig a, b;
    a.set("console.device", "/dev/ttyAMA0");
    b.set("console.device", "/dev/serial/by-id/usb-FTDI_FT232R_USB_UART_A10K4B2X-if00-port0");
    b.set("records.keep_cycles", "9");
    b.set("modbus.server", "tcp:0.0.0.0:1502");
    const std::string texts[2] = {a.to_toml(), b.to_toml()};
    drivers::FileStorage(dir).replace_file("calbox.toml", texts[0]);
    std::mt19937 random(20261123);
    std::uniform_int_distribution<int> delay_us(0, 4000);
    for (int round = 0; round < 200; ++round) {
        // The child tells when its first save is done, so that the kill, after a random delay
        // from there, lands in its loop of saves however slowly a loaded machine started it.
        int ready[2];
        CHECK_TRUE(::pipe(ready) == 0);
        const pid_t child = ::fork();
        if (child == 0) {
            drivers::FileStorage storage(dir);
            for (unsigned i = static_cast<unsigned>(round);; ++i) {
                storage.replace_file("calbox.toml", texts[i % 2]);
                if (i == static_cast<unsigned>(round)) (void)!::write(ready[1], "s", 1);
            }
        }
        CHECK_TRUE(child > 0);
        ::close(ready[1]);
        char started = 0;
        CHECK_TRUE(::read(ready[0], &started, 1) == 1);
        ::close(ready[0]);
        ::usleep(static_cast<useconds_t>(delay_us(random)));
        ::kill(child, SIGKILL);
        int status = 0;
        ::waitpid(child, &status, 0);
        CHECK_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
        const auto text = drivers::FileStorage(dir).read_file("calbox.toml");
        CHECK_TRUE(text.has_value());
        const bool is_a = *text == texts[0], is_b = *text == texts[1];
        CHECK_TRUE_TEXT(is_a || is_b,
                        ("round " + std::to_string(round) + ": a broken file").c_str());
        const auto loaded = firmware::BoxConfig::from_toml(*text, "calbox.toml");
        CHECK_TRUE(loaded == (is_a ? a : b));
    }
    std::filesystem::remove_all(dir);
}
