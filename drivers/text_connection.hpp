#pragma once
// hal::TextConnection over a POSIX TCP socket: a non-blocking connect and every read and write
// waited for with poll, so that no wait outlasts the timeout it was given.
#include <chrono>
#include <memory>
#include <string>

#include "hal/network.hpp"

namespace calbox::drivers {

std::unique_ptr<hal::TextConnection> connect_text(const std::string& host, int port,
                                                  std::chrono::milliseconds timeout);

}  // namespace calbox::drivers
