#pragma once
// hal::Network on the system's sockets: Beast and OpenSSL for HTTP, libmosquitto for MQTT,
// OpenSSL's PBKDF2 for the password.
#include <memory>

#include "hal/network.hpp"

namespace calbox::drivers {

std::unique_ptr<hal::Network> system_network();

}  // namespace calbox::drivers
