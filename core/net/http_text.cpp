#include "core/net/http_text.hpp"

#include <openssl/evp.h>

#include <array>

namespace calbox::net {
namespace {

std::string hex(const std::vector<unsigned char>& bytes) {
    static constexpr char digits[] = "0123456789abcdef";
    std::string out;
    out.reserve(2 * bytes.size());
    for (const unsigned char b : bytes) {
        out += digits[b >> 4];
        out += digits[b & 15];
    }
    return out;
}

std::optional<std::vector<unsigned char>> unhex(std::string_view text) {
    if (text.size() % 2 != 0) return std::nullopt;
    std::vector<unsigned char> out;
    for (std::size_t i = 0; i < text.size(); i += 2) {
        int v = 0;
        for (const char c : text.substr(i, 2)) {
            v <<= 4;
            if (c >= '0' && c <= '9')
                v |= c - '0';
            else if (c >= 'a' && c <= 'f')
                v |= c - 'a' + 10;
            else
                return std::nullopt;
        }
        out.push_back(static_cast<unsigned char>(v));
    }
    return out;
}

}  // namespace

FormBody multipart_form(const std::string& file_field, const std::string& file_name,
                        const std::string& file_contents, const Headers& fields) {
    const auto held_anywhere = [&](const std::string& boundary) {
        if (file_contents.find(boundary) != std::string::npos) return true;
        for (const auto& [name, value] : fields)
            if (value.find(boundary) != std::string::npos) return true;
        return false;
    };
    std::string boundary;
    for (unsigned long n = 0;; ++n) {
        boundary = "calbox-" + std::to_string(n);
        if (!held_anywhere(boundary)) break;
    }
    std::string body;
    const auto part = [&body, &boundary](const std::string& disposition) {
        body.append("--").append(boundary).append("\r\nContent-Disposition: form-data; ");
        body.append(disposition);
    };
    for (const auto& [name, value] : fields) {
        part("name=\"" + name + "\"\r\n\r\n");
        body.append(value).append("\r\n");
    }
    part("name=\"" + file_field + "\"; filename=\"" + file_name +
         "\"\r\nContent-Type: application/octet-stream\r\n\r\n");
    body.append(file_contents).append("\r\n--").append(boundary).append("--\r\n");
    return {"multipart/form-data; boundary=" + boundary, std::move(body)};
}

std::optional<std::string> basic_auth_password(std::string_view value) {
    constexpr std::string_view scheme = "Basic ";
    if (value.size() <= scheme.size() || value.substr(0, scheme.size()) != scheme ||
        value.size() > 2048)
        return std::nullopt;
    value.remove_prefix(scheme.size());
    if (value.size() % 4 != 0) return std::nullopt;
    std::string decoded(value.size() / 4 * 3, '\0');
    const int n = EVP_DecodeBlock(reinterpret_cast<unsigned char*>(decoded.data()),
                                  reinterpret_cast<const unsigned char*>(value.data()),
                                  static_cast<int>(value.size()));
    if (n < 0) return std::nullopt;
    // EVP_DecodeBlock counts the padding's zero bytes in: take them off.
    std::size_t length = static_cast<std::size_t>(n);
    for (std::size_t pad = 0; pad < 2 && !value.empty() && value[value.size() - 1 - pad] == '=';
         ++pad)
        --length;
    decoded.resize(length);
    const auto colon = decoded.find(':');
    if (colon == std::string::npos) return std::nullopt;
    return decoded.substr(colon + 1);
}

std::string StoredPassword::text() const {
    return std::string(kScheme) + ":" + std::to_string(iterations) + ":" + hex(salt) + ":" +
           hex(hash);
}

std::optional<StoredPassword> parse_stored_password(std::string_view stored) {
    std::array<std::string_view, 4> parts;
    for (std::size_t i = 0; i < parts.size(); ++i) {
        const auto colon = stored.find(':');
        if ((colon == std::string_view::npos) != (i + 1 == parts.size())) return std::nullopt;
        parts[i] = stored.substr(0, colon);
        if (colon != std::string_view::npos) stored.remove_prefix(colon + 1);
    }
    if (parts[0] != StoredPassword::kScheme || parts[1].empty() || parts[1].size() > 7)
        return std::nullopt;
    StoredPassword s;
    for (const char c : parts[1]) {
        if (c < '0' || c > '9') return std::nullopt;
        s.iterations = s.iterations * 10 + (c - '0');
    }
    auto salt = unhex(parts[2]);
    auto hash = unhex(parts[3]);
    if (s.iterations < 1000 || !salt || salt->size() < 8 || !hash ||
        hash->size() != StoredPassword::kHashBytes)
        return std::nullopt;
    s.salt = std::move(*salt);
    s.hash = std::move(*hash);
    return s;
}

}  // namespace calbox::net
