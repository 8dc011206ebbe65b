#include "drivers/modbus_link.hpp"

#include <arpa/inet.h>
#include <errno.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace calbox::drivers {
namespace {

void set_timeouts(modbus_t* ctx, const ModbusTimeouts& t) {
    modbus_set_response_timeout(ctx, t.response_ms / 1000, (t.response_ms % 1000) * 1000);
    modbus_set_byte_timeout(ctx, t.byte_ms / 1000, (t.byte_ms % 1000) * 1000);
}

std::string modbus_error() {
    return modbus_strerror(errno);
}

modbus_t* new_context(const ModbusEndpoint& e) {
    modbus_t* ctx = e.kind == ModbusEndpoint::Kind::tcp
                        ? modbus_new_tcp(e.host.c_str(), e.port)
                        : modbus_new_rtu(e.device.c_str(), e.baud, 'N', 8, 1);
    if (ctx == nullptr) throw std::runtime_error(e.describe() + ": " + modbus_error());
    if (modbus_set_slave(ctx, e.unit_id) < 0) {
        const std::string why = modbus_error();
        modbus_free(ctx);
        throw std::runtime_error(e.describe() + ": unit id " + std::to_string(e.unit_id) + ": " +
                                 why);
    }
    return ctx;
}

}  // namespace

ModbusServer::ModbusServer(const ModbusEndpoint& endpoint, Tables tables, ModbusTimeouts timeouts,
                           Log log)
    : endpoint_(endpoint), log_(std::move(log)) {
    ctx_ = new_context(endpoint);
    set_timeouts(ctx_, timeouts);
    // A frame once begun must end within the response time, or its client is dropped.
    modbus_set_indication_timeout(ctx_, timeouts.response_ms / 1000,
                                  (timeouts.response_ms % 1000) * 1000);
    map_ = modbus_mapping_new_start_address(0, static_cast<unsigned>(tables.coils), 0,
                                            static_cast<unsigned>(tables.discrete_inputs), 0,
                                            static_cast<unsigned>(tables.holding_registers), 0,
                                            static_cast<unsigned>(tables.input_registers));
    if (map_ == nullptr) {
        modbus_free(ctx_);
        throw std::runtime_error(endpoint.describe() + ": cannot allocate the register map");
    }
    auto fail = [&](const std::string& what) {
        const std::string why = modbus_error();
        modbus_mapping_free(map_);
        modbus_free(ctx_);
        return std::runtime_error(endpoint.describe() + ": " + what + ": " + why);
    };
    if (endpoint.kind == ModbusEndpoint::Kind::tcp) {
        listen_fd_ = modbus_tcp_listen(ctx_, 8);
        if (listen_fd_ < 0) throw fail("cannot listen");
        sockaddr_in bound{};
        socklen_t size = sizeof bound;
        if (::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &size) == 0) {
            port_ = ntohs(bound.sin_port);
        }
    } else if (modbus_connect(ctx_) < 0) {
        throw fail("cannot open the serial device");
    }
    thread_ = std::thread([this] {
        if (endpoint_.kind == ModbusEndpoint::Kind::tcp)
            serve();
        else
            serve_rtu();
    });
}

ModbusServer::~ModbusServer() {
    stop_.signal();
    thread_.join();
    if (listen_fd_ >= 0) {
        ::close(listen_fd_);
        modbus_set_socket(ctx_, -1);  // the last client's socket, closed by serve() already
    }
    modbus_close(ctx_);
    modbus_mapping_free(map_);
    modbus_free(ctx_);
}

// One request read and answered: > 0 done, 0 a request for another unit (RTU), < 0 the peer
// failed (closed, timed out mid-frame, a bad checksum).
int ModbusServer::answer(int fd) {
    std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    modbus_set_socket(ctx_, fd);
    const int n = modbus_receive(ctx_, query);
    if (n <= 0) return n;
    bool coil_written = false;
    {
        std::lock_guard lock(mutex_);
        if (modbus_reply(ctx_, query, n, map_) < 0 && log_) {
            log_.warning(endpoint_.describe() + ": reply failed: " + modbus_error());
        }
        for (int i = 0; i < map_->nb_bits; ++i) {
            if (map_->tab_bits[i] != 0) {
                map_->tab_bits[i] = 0;
                coils_set_.push_back(i);
                coil_written = true;
            }
        }
    }
    if (coil_written) written_.signal();
    return n;
}

void ModbusServer::serve() {
    std::vector<int> clients;
    for (;;) {
        fd_set readable;
        FD_ZERO(&readable);
        FD_SET(stop_.fd(), &readable);
        FD_SET(listen_fd_, &readable);
        int top = std::max(stop_.fd(), listen_fd_);
        for (const int c : clients) {
            FD_SET(c, &readable);
            top = std::max(top, c);
        }
        if (::select(top + 1, &readable, nullptr, nullptr, nullptr) < 0) {
            if (errno == EINTR) continue;
            if (log_) log_.error(endpoint_.describe() + ": select failed: " + std::strerror(errno));
            break;
        }
        if (FD_ISSET(stop_.fd(), &readable)) break;
        if (FD_ISSET(listen_fd_, &readable)) {
            const int c = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
            if (c >= 0 && c < FD_SETSIZE) {
                clients.push_back(c);
            } else if (c >= 0) {
                ::close(c);  // beyond what select() can watch
            }
        }
        for (auto it = clients.begin(); it != clients.end();) {
            if (!FD_ISSET(*it, &readable)) {
                ++it;
                continue;
            }
            std::uint8_t peek;
            // A closed connection, or one that sent half a frame and stalled: dropped, so a PLC
            // that vanishes never holds the server.
            const bool open = ::recv(*it, &peek, 1, MSG_PEEK | MSG_DONTWAIT) > 0;
            if (open && answer(*it) > 0) {
                ++it;
                continue;
            }
            ::close(*it);
            it = clients.erase(it);
        }
    }
    for (const int c : clients) ::close(c);
}

void ModbusServer::serve_rtu() {
    const int fd = modbus_get_socket(ctx_);
    for (;;) {
        fd_set readable;
        FD_ZERO(&readable);
        FD_SET(stop_.fd(), &readable);
        FD_SET(fd, &readable);
        if (::select(std::max(fd, stop_.fd()) + 1, &readable, nullptr, nullptr, nullptr) < 0) {
            if (errno == EINTR) continue;
            break;
        }
        if (FD_ISSET(stop_.fd(), &readable)) break;
        if (answer(fd) < 0) modbus_flush(ctx_);  // a broken frame: start clean
    }
}

std::vector<int> ModbusServer::take_coils_set() {
    written_.take();
    std::lock_guard lock(mutex_);
    return std::exchange(coils_set_, {});
}

void ModbusServer::set_discrete_inputs(int first, const std::vector<bool>& values) {
    std::lock_guard lock(mutex_);
    if (first < 0 || first + static_cast<int>(values.size()) > map_->nb_input_bits) {
        throw std::out_of_range("discrete inputs beyond the map");
    }
    for (std::size_t i = 0; i < values.size(); ++i) {
        map_->tab_input_bits[first + static_cast<int>(i)] = values[i] ? 1 : 0;
    }
}

void ModbusServer::set_input_registers(int first, std::span<const std::uint16_t> values) {
    std::lock_guard lock(mutex_);
    if (first < 0 || first + static_cast<int>(values.size()) > map_->nb_input_registers) {
        throw std::out_of_range("input registers beyond the map");
    }
    std::copy(values.begin(), values.end(), map_->tab_input_registers + first);
}

ModbusClient::ModbusClient(const ModbusEndpoint& endpoint, ModbusTimeouts timeouts)
    : endpoint_(endpoint), timeouts_(timeouts) {}

void ModbusClient::start(std::function<hal::RegisterResult(modbus_t*)> request) {
    if (request_.busy()) throw std::logic_error("ModbusClient: a request is already in flight");
    request_.start([this, request = std::move(request)] {
        hal::RegisterResult result;
        modbus_t* ctx = nullptr;
        try {
            ctx = new_context(endpoint_);
            set_timeouts(ctx, timeouts_);
            if (modbus_connect(ctx) < 0) {
                result.error = endpoint_.describe() + ": cannot connect: " + modbus_error();
            } else {
                result = request(ctx);
            }
        } catch (const std::exception& e) {
            result.error = e.what();
        }
        if (ctx != nullptr) {
            modbus_close(ctx);
            modbus_free(ctx);
        }
        return result;
    });
}

void ModbusClient::start_read_registers(int first_address, int count) {
    if (count < 1 || count > MODBUS_MAX_READ_REGISTERS) {
        throw std::invalid_argument("ModbusClient: read 1 to 125 registers");
    }
    start([this, first_address, count](modbus_t* ctx) {
        hal::RegisterResult r;
        r.values.resize(static_cast<std::size_t>(count));
        if (modbus_read_registers(ctx, first_address, count, r.values.data()) != count) {
            r.values.clear();
            r.error = endpoint_.describe() + ": reading holding registers " +
                      std::to_string(first_address) + "+" + std::to_string(count) + ": " +
                      modbus_error();
        }
        return r;
    });
}

void ModbusClient::start_write_registers(int first_address, std::vector<std::uint16_t> values) {
    if (values.empty() || values.size() > MODBUS_MAX_WRITE_REGISTERS) {
        throw std::invalid_argument("ModbusClient: write 1 to 123 registers");
    }
    start([this, first_address, values = std::move(values)](modbus_t* ctx) {
        hal::RegisterResult r;
        const int n = static_cast<int>(values.size());
        if (modbus_write_registers(ctx, first_address, n, values.data()) != n) {
            r.error = endpoint_.describe() + ": writing holding registers " +
                      std::to_string(first_address) + "+" + std::to_string(n) + ": " +
                      modbus_error();
        }
        return r;
    });
}

void ModbusClient::start_write_coil(int address, bool on) {
    start([this, address, on](modbus_t* ctx) {
        hal::RegisterResult r;
        if (modbus_write_bit(ctx, address, on ? 1 : 0) != 1) {
            r.error = endpoint_.describe() + ": writing coil " + std::to_string(address) + ": " +
                      modbus_error();
        }
        return r;
    });
}

hal::RegisterResult ModbusClient::take_result() {
    auto result = request_.take();
    if (!result) return {{}, "ModbusClient: no request has finished"};
    return std::move(*result);
}

}  // namespace calbox::drivers
