#pragma once
// The web page's password, kept only as a salted PBKDF2-HMAC-SHA256 hash (OpenSSL): the
// configuration file holds "pbkdf2-sha256:ITERATIONS:SALT:HASH" (hex), never the password.
#include <optional>
#include <string>
#include <string_view>

namespace calbox::drivers {

// A fresh random salt each time. Throws std::invalid_argument for an empty password or one
// longer than 256 bytes, std::runtime_error when the system gives no random bytes.
std::string password_hash(std::string_view password);
// Compares in constant time; false for a malformed `stored`.
bool password_matches(std::string_view password, std::string_view stored);
// `stored` is a hash password_hash() could have written (its form, not its password).
bool is_password_hash(std::string_view stored);

// The password of an HTTP "Authorization: Basic ..." header's value (RFC 7617, the user name
// ignored): none when it is not one.
std::optional<std::string> basic_auth_password(std::string_view header_value);

}  // namespace calbox::drivers
