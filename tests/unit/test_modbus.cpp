#include <CppUTest/TestHarness.h>
#include <CppUTestExt/MockSupport.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "core/models/register_words.hpp"
#include "drivers/modbus_link.hpp"
#include "firmware/app/box_config.hpp"
#include "firmware/modes/galvo_mode.hpp"
#include "firmware/plc/plc_link.hpp"
#include "tests/mocks/hal_mocks.hpp"
#include "tests/support/device_errors.hpp"

using namespace calbox;
using Words = std::vector<std::uint16_t>;

TEST_GROUP(RegisterWords){};

TEST(RegisterWords, float_test_vector_in_each_word_order) {
    // 123456.0f is 0x47F12000 (IEEE 754): bytes A=47 B=F1 C=20 D=00.
    auto w = models::pack_float(123456.0f, models::WordOrder::abcd);
    CHECK_EQUAL(0x47F1, w[0]);
    CHECK_EQUAL(0x2000, w[1]);
    w = models::pack_float(123456.0f, models::WordOrder::cdab);
    CHECK_EQUAL(0x2000, w[0]);
    CHECK_EQUAL(0x47F1, w[1]);
    w = models::pack_float(123456.0f, models::WordOrder::badc);
    CHECK_EQUAL(0xF147, w[0]);
    CHECK_EQUAL(0x0020, w[1]);
    w = models::pack_float(123456.0f, models::WordOrder::dcba);
    CHECK_EQUAL(0x0020, w[0]);
    CHECK_EQUAL(0xF147, w[1]);
    for (const auto order : {models::WordOrder::abcd, models::WordOrder::cdab,
                             models::WordOrder::badc, models::WordOrder::dcba}) {
        CHECK_EQUAL(-0.0123f, models::unpack_float(models::pack_float(-0.0123f, order), order));
    }
    CHECK_EQUAL(-1.0f, models::unpack_float({0xBF80, 0x0000}, models::WordOrder::abcd));
    CHECK_THROWS(std::invalid_argument, models::parse_word_order("ABCD-ish"));
}

TEST_GROUP(ModbusEndpoint){};

TEST(ModbusEndpoint, parses_tcp_and_rtu_and_names_what_is_wrong) {
    const auto tcp = net::parse_modbus_endpoint("tcp:127.0.0.1:1502");
    CHECK(tcp.kind == net::ModbusEndpoint::Kind::tcp);
    STRCMP_EQUAL("127.0.0.1", tcp.host.c_str());
    CHECK_EQUAL(1502, tcp.port);
    const auto rtu = net::parse_modbus_endpoint("rtu:/dev/ttyUSB0:19200");
    STRCMP_EQUAL("/dev/ttyUSB0", rtu.device.c_str());
    CHECK_EQUAL(19200, rtu.baud);
    STRCMP_CONTAINS("not tcp:HOST:PORT", test::construction_error([] {
                                             net::parse_modbus_endpoint("localhost");
                                         }).c_str());
    STRCMP_CONTAINS("port 'x' is not a number", test::construction_error([] {
                                                    net::parse_modbus_endpoint("tcp:h:x");
                                                }).c_str());
    STRCMP_CONTAINS("'udp' is not tcp or rtu", test::construction_error([] {
                                                   net::parse_modbus_endpoint("udp:h:1");
                                               }).c_str());
    STRCMP_CONTAINS("port out of range", test::construction_error([] {
                                             net::parse_modbus_endpoint("tcp:h:70000");
                                         }).c_str());
}

TEST_GROUP(ResultRegisterMap){};

TEST(ResultRegisterMap, reads_a_map_and_refuses_unknown_names_and_overlaps) {
    const auto map = firmware::ResultRegisterMap::from_toml(
        "diagonal_rod_mm = 100\nradius_mm = 102\n", "map.toml");
    CHECK_EQUAL(2U, map.registers.size());
    STRCMP_CONTAINS("map.toml:2: 'radius' is not a result value",
                    test::construction_error([] {
                        firmware::ResultRegisterMap::from_toml(
                            "diagonal_rod_mm = 100\nradius = 4\n", "map.toml");
                    }).c_str());
    STRCMP_CONTAINS("map.toml:2: radius_mm: register 101 is already diagonal_rod_mm's",
                    test::construction_error([] {
                        firmware::ResultRegisterMap::from_toml(
                            "diagonal_rod_mm = 100\nradius_mm = 101\n", "map.toml");
                    }).c_str());
    STRCMP_CONTAINS("a holding register 0 to 65534", test::construction_error([] {
                                                         firmware::ResultRegisterMap::from_toml(
                                                             "radius_mm = -3\n", "map.toml");
                                                     }).c_str());
    const auto whole = firmware::ResultRegisterMap::whole_block(10);
    CHECK_EQUAL(18U, whole.registers.size());
    CHECK_EQUAL(10 + 2 * 17, whole.registers.back().second);
    CHECK_EQUAL(4 + 36, firmware::input_register_count());
}

TEST_GROUP(GalvoTableRegisters){void teardown() override{mock().clear();
}
}
;

TEST(GalvoTableRegisters, the_kept_table_follows_the_result_block_in_stated_registers) {
    mock().ignoreOtherCalls();
    firmware::CycleReport report;
    report.applied = true;
    models::CorrectionTable t;
    t.nodes = 3;
    t.min_x_mm = -50.5, t.min_y_mm = -49.25, t.max_x_mm = 50.125, t.max_y_mm = 51;
    for (int i = 0; i < 9; ++i) t.command_mm.push_back({-50 + 12.5 * i, 0.001 * i - 3});
    mocks::MockRegisterLink registers_link;
    auto map = firmware::ResultRegisterMap::from_toml(
        "measured_xy_rms_mm = 0\ngalvo_table = 2000\n", "map.toml");
    firmware::ResultWriter writer(registers_link, map, models::WordOrder::cdab,
                                  [](const std::string&) {});
    writer.write(report, {{}, firmware::table_registers(t), "galvo_table"});
    while (!writer.idle()) {
        registers_link.results.push_back({});
        writer.on_completion();
    }
    std::map<int, std::uint16_t> registers;
    for (const auto& [first, words] : registers_link.written) {
        CHECK(words.size() <= 123u);
        for (std::size_t i = 0; i < words.size(); ++i)
            registers[first + static_cast<int>(i)] = words[i];
    }
    const auto value = [&](int address) {
        return models::unpack_float({registers.at(address), registers.at(address + 1)},
                                    models::WordOrder::cdab);
    };
    CHECK_EQUAL(2u + 2u * (5u + 18u), registers.size());
    DOUBLES_EQUAL(3, value(2000), 0);
    DOUBLES_EQUAL(-50.5, value(2002), 0);
    DOUBLES_EQUAL(-49.25, value(2004), 0);
    DOUBLES_EQUAL(50.125, value(2006), 0);
    DOUBLES_EQUAL(51, value(2008), 0);
    for (int i = 0; i < 9; ++i) {
        DOUBLES_EQUAL(-50 + 12.5 * i, value(2010 + 4 * i), 1e-5);
        DOUBLES_EQUAL(0.001 * i - 3, value(2012 + 4 * i), 1e-6);
    }
    STRCMP_CONTAINS("overlaps the galvo table", test::construction_error([] {
                                                    firmware::ResultRegisterMap::from_toml(
                                                        "radius_mm = 1500\n", "map.toml");
                                                }).c_str());
    STRCMP_CONTAINS("galvo_table: a holding register",
                    test::construction_error([] {
                        firmware::ResultRegisterMap::from_toml(
                            "radius_mm = 1\ngalvo_table = 60000\n", "map.toml");
                    }).c_str());
}

namespace {

int free_tcp_port() {
    const int s = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t size = sizeof a;
    ::getsockname(s, reinterpret_cast<sockaddr*>(&a), &size);
    ::close(s);
    return ntohs(a.sin_port);
}

// A process started for the test and killed at its end.
struct Process {
    pid_t pid = -1;
    explicit Process(std::vector<std::string> argv) {
        pid = ::fork();
        if (pid == 0) {
            std::vector<char*> args;
            for (auto& a : argv) args.push_back(a.data());
            args.push_back(nullptr);
            ::execv(args[0], args.data());
            ::_exit(127);
        }
    }
    ~Process() {
        ::kill(pid, SIGKILL);
        ::waitpid(pid, nullptr, 0);
    }
    Process(const Process&) = delete;
    Process& operator=(const Process&) = delete;
};

hal::RegisterResult wait_result(hal::RegisterLink& link, int timeout_ms = 8000) {
    pollfd p{link.completion_fd(), POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) != 1) return {{}, "no completion within the test's wait"};
    return link.take_result();
}

// Retries a read until the peer has started listening.
void wait_until_serving(drivers::ModbusClient& client) {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(15);
    while (std::chrono::steady_clock::now() < give_up) {
        client.start_read_registers(0, 1);
        if (wait_result(client).ok()) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    FAIL("the peer never answered");
}

std::string python_peer() {
    return std::string(CALBOX_SOURCE_DIR) + "/tests/modbus/pymodbus_server.py";
}

}  // namespace

TEST_GROUP(ModbusClient){};

TEST(ModbusClient, writes_and_reads_back_through_pymodbus_over_tcp_with_exceptions) {
    const int port = free_tcp_port();
    Process peer({"/usr/bin/python3", python_peer(), "tcp", std::to_string(port)});
    drivers::ModbusClient client(
        net::parse_modbus_endpoint("tcp:127.0.0.1:" + std::to_string(port)), {});
    wait_until_serving(client);

    const auto w = models::pack_float(123456.0f, models::WordOrder::abcd);
    client.start_write_registers(10, {w[0], w[1], 7});
    auto r = wait_result(client);
    STRCMP_EQUAL("", r.error.c_str());
    client.start_read_registers(9, 5);
    r = wait_result(client);
    STRCMP_EQUAL("", r.error.c_str());
    CHECK(r.values == (Words{0, 0x47F1, 0x2000, 7, 0}));

    // pymodbus holds 100 registers: beyond them is its exception 2, as libmodbus names it.
    client.start_write_registers(99, {1, 2});
    r = wait_result(client);
    STRCMP_CONTAINS("writing holding registers 99+2: Illegal data address", r.error.c_str());
    client.start_read_registers(200, 1);
    r = wait_result(client);
    STRCMP_CONTAINS("Illegal data address", r.error.c_str());
}

TEST(ModbusClient, a_peer_that_never_answers_is_an_error_after_the_response_timeout) {
    // Accepts the connection and reads, never replies: a PLC or controller that hung.
    const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    CHECK_EQUAL(0, ::bind(listener, reinterpret_cast<sockaddr*>(&a), sizeof a));
    CHECK_EQUAL(0, ::listen(listener, 1));
    socklen_t size = sizeof a;
    ::getsockname(listener, reinterpret_cast<sockaddr*>(&a), &size);
    drivers::ModbusClient client(
        net::parse_modbus_endpoint("tcp:127.0.0.1:" + std::to_string(ntohs(a.sin_port))),
        {300, 100});
    const auto started = std::chrono::steady_clock::now();
    client.start_write_registers(0, {1});
    CHECK_THROWS(std::logic_error, client.start_write_coil(0, true));  // one at a time
    const auto r = wait_result(client, 3000);
    const auto took = std::chrono::steady_clock::now() - started;
    STRCMP_CONTAINS("Connection timed out", r.error.c_str());
    CHECK(took >= std::chrono::milliseconds(290));
    CHECK(took < std::chrono::milliseconds(2000));
    ::close(listener);
}

TEST(ModbusClient, nobody_listening_is_one_clear_error) {
    drivers::ModbusClient client(
        net::parse_modbus_endpoint("tcp:127.0.0.1:" + std::to_string(free_tcp_port())), {});
    client.start_write_coil(0, true);
    const auto r = wait_result(client);
    STRCMP_CONTAINS("cannot connect: Connection refused", r.error.c_str());
    STRCMP_CONTAINS("modbus tcp:127.0.0.1:", r.error.c_str());
}

namespace {

// Two linked pseudo-terminals, as a null-modem cable between two serial ports.
struct PtyPair {
    std::string a, b;
    std::unique_ptr<Process> socat;
    PtyPair() {
        char pattern[] = "/tmp/calbox-pty-XXXXXX";
        const std::string dir = ::mkdtemp(pattern);
        a = dir + "/a";
        b = dir + "/b";
        socat = std::make_unique<Process>(std::vector<std::string>{
            "/usr/bin/socat", "pty,raw,echo=0,link=" + a, "pty,raw,echo=0,link=" + b});
        for (int i = 0;
             i < 100 && (::access(a.c_str(), F_OK) != 0 || ::access(b.c_str(), F_OK) != 0); ++i) {
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
    }
};

}  // namespace

TEST(ModbusClient, writes_to_pymodbus_over_rtu_on_a_pty_pair) {
    PtyPair pty;
    Process peer({"/usr/bin/python3", python_peer(), "rtu", pty.b, "19200"});
    drivers::ModbusClient client(net::parse_modbus_endpoint("rtu:" + pty.a + ":19200"), {});
    wait_until_serving(client);
    client.start_write_registers(0, {0x47F1, 0x2000});
    STRCMP_EQUAL("", wait_result(client).error.c_str());
    client.start_read_registers(0, 2);
    const auto r = wait_result(client);
    STRCMP_EQUAL("", r.error.c_str());
    CHECK(r.values == (Words{0x47F1, 0x2000}));
}

TEST_GROUP(ModbusServer){};

TEST(ModbusServer, our_client_drives_our_server_over_rtu_and_tcp) {
    for (const bool rtu : {false, true}) {
        PtyPair pty;
        const auto server_end = net::parse_modbus_endpoint(rtu ? "rtu:" + pty.a + ":38400"
                                                               : std::string("tcp:127.0.0.1:0"));
        drivers::ModbusServer server(server_end, {4, 2, 0, 6}, {}, nullptr);
        const auto client_end = net::parse_modbus_endpoint(
            rtu ? "rtu:" + pty.b + ":38400" : "tcp:127.0.0.1:" + std::to_string(server.port()));
        drivers::ModbusClient client(client_end, {});
        client.start_write_coil(2, true);
        STRCMP_EQUAL("", wait_result(client).error.c_str());
        pollfd p{server.written_fd(), POLLIN, 0};
        CHECK_EQUAL(1, ::poll(&p, 1, 1000));
        CHECK(server.take_coils_set() == std::vector<int>{2});
        CHECK(server.take_coils_set().empty());
        client.start_write_coil(9, true);  // beyond the four coils
        STRCMP_CONTAINS("Illegal data address", wait_result(client).error.c_str());
    }
}

TEST(ModbusServer, a_port_in_use_a_missing_device_and_permission_denied_name_the_endpoint) {
    drivers::ModbusServer first(net::parse_modbus_endpoint("tcp:127.0.0.1:0"), {1, 1, 0, 1}, {},
                                nullptr);
    const std::string taken = "tcp:127.0.0.1:" + std::to_string(first.port());
    STRCMP_CONTAINS(
        ("modbus " + taken + ": cannot listen: Address already in use").c_str(),
        test::construction_error([&] {
            drivers::ModbusServer(net::parse_modbus_endpoint(taken), {1, 1, 0, 1}, {}, nullptr);
        }).c_str());
    STRCMP_CONTAINS(
        "modbus rtu:/dev/ttyCALBOX97:19200: cannot open the serial device: No such file",
        test::construction_error([] {
            drivers::ModbusServer(net::parse_modbus_endpoint("rtu:/dev/ttyCALBOX97:19200"),
                                  {1, 1, 0, 1}, {}, nullptr);
        }).c_str());
    test::ScratchFile device("");
    STRCMP_CONTAINS(
        ("modbus rtu:" + device.path + ":19200: cannot open the serial device: Permission denied")
            .c_str(),
        test::error_as_unprivileged_user([&] {
            drivers::ModbusServer(net::parse_modbus_endpoint("rtu:" + device.path + ":19200"),
                                  {1, 1, 0, 1}, {}, nullptr);
        }).c_str());
}

TEST(ModbusClient, a_serial_device_it_may_not_open_is_one_line) {
    test::ScratchFile device("");
    const std::string error = test::error_as_unprivileged_user([&] {
        drivers::ModbusClient client(net::parse_modbus_endpoint("rtu:" + device.path + ":9600"),
                                     {});
        client.start_write_coil(0, true);
        pollfd p{client.completion_fd(), POLLIN, 0};
        ::poll(&p, 1, 5000);
        throw std::runtime_error(client.take_result().error);
    });
    STRCMP_CONTAINS(
        ("modbus rtu:" + device.path + ":9600: cannot connect: Permission denied").c_str(),
        error.c_str());
}
