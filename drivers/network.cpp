#include "drivers/network.hpp"

#include <filesystem>
#include <utility>

#include "drivers/durable_file.hpp"
#include "drivers/http_client.hpp"
#include "drivers/http_server.hpp"
#include "drivers/mqtt_client.hpp"
#include "drivers/password.hpp"
#include "drivers/text_connection.hpp"
#include "drivers/tls.hpp"

namespace calbox::drivers {
namespace {

class SystemHttp final : public hal::HttpClient {
  public:
    hal::HttpResponse request(const net::Url& server, const hal::HttpRequest& request,
                              std::chrono::milliseconds timeout) override {
        return http_request(server, request, timeout);
    }
    std::unique_ptr<hal::WebSocket> open_socket(const net::Url& url, const hal::Headers& headers,
                                                std::chrono::milliseconds timeout) override {
        return std::make_unique<WebSocketClient>(url, headers, timeout);
    }
};

class SystemCertificates final : public hal::Certificates {
  public:
    void make_self_signed(const hal::ServerTls& files, const std::vector<std::string>& names,
                          int valid_days) override {
        const auto made = self_signed_certificate(names, valid_days);
        const auto in = [](const std::string& file) {
            const std::filesystem::path path(file);
            return std::pair(
                path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path(),
                path.filename().string());
        };
        // The key first: a certificate is never left without its key.
        const auto [key_dir, key_name] = in(files.key_file);
        replace_file_durably(posix_file_system(), key_dir, key_name, made.private_key_pem,
                             FileAccess::owner_only);
        const auto [cert_dir, cert_name] = in(files.certificate_file);
        replace_file_durably(posix_file_system(), cert_dir, cert_name, made.certificate_pem);
    }
    hal::CertificateFacts check(const hal::ServerTls& files) override {
        return certificate_facts(files);
    }
};

class SystemNetwork final : public hal::Network {
  public:
    hal::HttpClient& http() override { return http_; }
    std::unique_ptr<hal::HttpListener> listen(const std::string& address, int port,
                                              hal::HttpHandlers handlers, hal::ServerLimits limits,
                                              const std::optional<hal::ServerTls>& tls) override {
        return std::make_unique<HttpServer>(address, port, std::move(handlers), limits, tls);
    }
    hal::Certificates& certificates() override { return certificates_; }
    std::unique_ptr<hal::MqttSession> mqtt(const std::string& client_id,
                                           const hal::MqttBroker& broker, hal::MqttWill will,
                                           hal::MqttCallbacks callbacks) override {
        return std::make_unique<MqttClient>(client_id, broker, std::move(will),
                                            std::move(callbacks));
    }
    hal::PasswordHasher& passwords() override { return passwords_; }
    std::unique_ptr<hal::TextConnection> connect_text(const std::string& host, int port,
                                                      std::chrono::milliseconds timeout) override {
        return drivers::connect_text(host, port, timeout);
    }

  private:
    SystemHttp http_;
    Pbkdf2Hasher passwords_;
    SystemCertificates certificates_;
};

}  // namespace

std::unique_ptr<hal::Network> system_network() {
    return std::make_unique<SystemNetwork>();
}

}  // namespace calbox::drivers
