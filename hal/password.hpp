#pragma once
// The web page's password, kept only as a salted hash (core/net/http_text.hpp's stored form).
#include <string>
#include <string_view>

namespace calbox::hal {

class PasswordHasher {
  public:
    virtual ~PasswordHasher() = default;
    // A fresh random salt each time. Throws std::invalid_argument for an empty password or one
    // longer than 256 bytes, std::runtime_error when the system gives no random bytes.
    virtual std::string hash(std::string_view password) = 0;
    // Compares in constant time; false for a malformed `stored`.
    virtual bool matches(std::string_view password, std::string_view stored) = 0;
};

}  // namespace calbox::hal
