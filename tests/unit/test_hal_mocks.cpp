// The mocks stand in for devices in firmware tests; these pin down that they honour the
// contracts of hal/ and that CppUTest's expectations see every call.
#include "tests/mocks/hal_mocks.hpp"

using namespace calbox;

TEST_GROUP(HalMocks){void teardown() override{mock().checkExpectations();
mock().clear();
}
}
;

TEST(HalMocks, serial_port_accepts_partial_writes) {
    mocks::MockSerialPort port;
    port.incoming = "ok\n";
    mock("serial").expectOneCall("write_some").andReturnValue(3u);
    const std::string line = "G28 X\n";
    const auto n =
        port.write_some(std::span(reinterpret_cast<const std::uint8_t*>(line.data()), line.size()));
    CHECK_EQUAL(3u, n);
    STRCMP_EQUAL("G28", port.written.c_str());
    std::uint8_t buffer[8];
    CHECK_EQUAL(3u, port.read_some(buffer));
    CHECK_EQUAL(0u, port.read_some(buffer));
}

TEST(HalMocks, register_link_reports_results) {
    mocks::MockRegisterLink link;
    link.results.push_back(hal::RegisterResult{{1, 2, 3}, ""});
    mock("registers")
        .expectOneCall("start_read_registers")
        .withIntParameter("first", 100)
        .withIntParameter("count", 3);
    mock("registers").expectOneCall("take_result");
    link.start_read_registers(100, 3);
    CHECK_EQUAL(3u, link.take_result().values.size());
}
