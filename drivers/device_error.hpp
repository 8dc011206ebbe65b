#pragma once
// One clear line for a device that cannot be used: the device's name, what was attempted and
// the system's reason (missing, permission denied, gone mid-use).
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>

namespace calbox::drivers {

inline std::runtime_error device_error(const std::string& device, const std::string& action,
                                       int error_number = errno) {
    std::string why = std::strerror(error_number);
    if (error_number == EACCES || error_number == EPERM) {
        why += " (is the user in the device's group? see the README's Devices section)";
    }
    return std::runtime_error(device + ": " + action + ": " + why);
}

}  // namespace calbox::drivers
