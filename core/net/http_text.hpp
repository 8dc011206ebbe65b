#pragma once
// HTTP's text forms the box writes and reads: an upload's multipart body, the password of a
// Basic authorization header, and the stored form of the web page's password hash. Text only:
// the hashing itself is hal::PasswordHasher's.
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace calbox::net {

using Headers = std::vector<std::pair<std::string, std::string>>;

// A multipart/form-data body holding one file (an upload's "file" field) and plain fields. The
// boundary is the first "calbox-N" that neither the contents nor a field holds (RFC 2046 asks
// no more of it).
struct FormBody {
    std::string content_type, body;
};
FormBody multipart_form(const std::string& file_field, const std::string& file_name,
                        const std::string& file_contents, const Headers& fields = {});

// The password of an HTTP "Authorization: Basic ..." header's value (RFC 7617, the user name
// ignored): none when it is not one.
std::optional<std::string> basic_auth_password(std::string_view header_value);

// "pbkdf2-sha256:ITERATIONS:SALT:HASH" (hex), as the configuration file keeps the web page's
// password: never the password itself.
struct StoredPassword {
    static constexpr std::string_view kScheme = "pbkdf2-sha256";
    static constexpr std::size_t kHashBytes = 32;
    int iterations = 0;
    std::vector<unsigned char> salt, hash;
    std::string text() const;
};
// None for a text that is not that form (a scheme, at least 1000 iterations, a salt of 8 bytes
// or more, a 32-byte hash).
std::optional<StoredPassword> parse_stored_password(std::string_view text);
inline bool is_password_hash(std::string_view text) {
    return parse_stored_password(text).has_value();
}

}  // namespace calbox::net
