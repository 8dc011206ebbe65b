#pragma once
// hal::PasswordHasher as PBKDF2-HMAC-SHA256 through OpenSSL, in the stored form of
// core/net/http_text.hpp.
#include <string>
#include <string_view>

#include "hal/password.hpp"

namespace calbox::drivers {

class Pbkdf2Hasher final : public hal::PasswordHasher {
  public:
    std::string hash(std::string_view password) override;
    bool matches(std::string_view password, std::string_view stored) override;
};

}  // namespace calbox::drivers
