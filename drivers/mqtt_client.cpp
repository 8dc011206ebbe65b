#include "drivers/mqtt_client.hpp"

#include <mosquitto.h>
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace calbox::drivers {

struct MqttClient::State {
    mosquitto* mosq = nullptr;
    std::string address;  // host:port, for what is told
    std::thread network;
    std::mutex stop_mutex;
    std::condition_variable stop_asked;
    bool stopping = false;  // under stop_mutex
    Callbacks callbacks;
    MqttWill will;
    int protocol_version = 4;
    std::string who;  // " as USER" for a login, empty for anonymous
    std::string tls_check;  // how the broker's certificate is checked, for what is told
    std::atomic<bool> connected{false};
    // One trouble told per spell without a session: the retries after it are silent until the
    // broker takes the box again.
    std::atomic<bool> told{false};

    // The network thread: libmosquitto's loop while there is a socket; without one (the broker
    // not there, gone, or refusing) a wait that doubles from 1 s to 60 s, then another try. Our
    // own rather than mosquitto_loop_start's, which gives up after a first connect that fails.
    void run(bool have_socket) {
        int wait_s = 1;
        for (;;) {
            {
                std::unique_lock lock(stop_mutex);
                if (!have_socket)
                    stop_asked.wait_for(lock, std::chrono::seconds(wait_s),
                                        [&] { return stopping; });
                if (stopping) break;
            }
            if (!have_socket) {
                const int rc = mosquitto_reconnect(mosq);
                have_socket = rc == MOSQ_ERR_SUCCESS;
                if (!have_socket) {
                    unreachable(rc);
                    wait_s = std::min(60, 2 * wait_s);
                }
                continue;
            }
            const int rc = mosquitto_loop(mosq, 200, 1);
            if (rc != MOSQ_ERR_SUCCESS) {
                have_socket = false;
                // Lost after a session: the disconnect callback told it. Never there: say so.
                if (!connected) unreachable(rc);
                wait_s = connected ? 1 : std::min(60, 2 * wait_s);
                connected = false;
            } else if (connected) {
                wait_s = 1;
            }
        }
        if (!connected) return;
        // A goodbye that the will would otherwise say for us, then the disconnect, written out.
        if (!will.goodbye.empty())
            mosquitto_publish(mosq, nullptr, will.topic.c_str(),
                              static_cast<int>(will.goodbye.size()), will.goodbye.data(), 1, true);
        mosquitto_disconnect(mosq);
        for (int i = 0; i < 20 && mosquitto_loop(mosq, 50, 1) == MOSQ_ERR_SUCCESS; ++i) {
        }
    }

    void unreachable(int rc) {
        std::string why = rc == MOSQ_ERR_ERRNO ? std::string(std::strerror(errno))
                                               : std::string(mosquitto_strerror(rc));
        if (rc == MOSQ_ERR_TLS) why += " (its certificate checked against " + tls_check + ")";
        trouble("cannot reach the broker at " + address + ": " + why + " (retried with back-off)");
    }

    std::string refusal(int rc) const {
        return protocol_version == 5 ? mosquitto_reason_string(rc) : mosquitto_connack_string(rc);
    }

    void trouble(const std::string& why) {
        if (told.exchange(true)) return;
        if (callbacks.trouble) callbacks.trouble(why);
    }
};

namespace {

// libmosquitto is initialised once per process, before any client, and never undone while one
// may run.
void library_once() {
    static const int rc = mosquitto_lib_init();
    if (rc != MOSQ_ERR_SUCCESS) throw std::runtime_error("libmosquitto: cannot initialise");
}

MqttClient::State& state_of(void* user) {
    return *static_cast<MqttClient::State*>(user);
}

// The password, from a file its owner alone reads: a password others can read is no secret, and
// the box says so rather than send it.
std::string password_from(const std::string& file) {
    struct stat st {};
    if (::stat(file.c_str(), &st) != 0)
        throw std::runtime_error("mqtt.password_file " + file + ": " + std::strerror(errno));
    if ((st.st_mode & 077) != 0) {
        char mode[8];
        std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
        throw std::runtime_error("mqtt.password_file " + file + " is readable by others (mode " +
                                 mode + "): the password's file must be its owner's alone (chmod "
                                 "600 " + file + ")");
    }
    std::ifstream in(file);
    std::string password;
    if (!in || !std::getline(in, password))
        throw std::runtime_error("mqtt.password_file " + file + ": cannot be read");
    if (!password.empty() && password.back() == '\r') password.pop_back();
    if (password.empty())
        throw std::runtime_error("mqtt.password_file " + file + ": its first line is empty");
    return password;
}

}  // namespace

MqttClient::MqttClient(const std::string& client_id, const hal::MqttBroker& broker, MqttWill will,
                       Callbacks callbacks)
    : state_(std::make_unique<State>()) {
    library_once();
    if (broker.protocol_version != 4 && broker.protocol_version != 5)
        throw std::invalid_argument("MQTT protocol level " +
                                    std::to_string(broker.protocol_version) + ": 4 or 5");
    const std::string password =
        broker.password_file.empty() ? std::string() : password_from(broker.password_file);
    auto& s = *state_;
    s.callbacks = std::move(callbacks);
    s.will = std::move(will);
    s.protocol_version = broker.protocol_version;
    s.mosq = mosquitto_new(client_id.c_str(), true, &s);
    if (s.mosq == nullptr) throw std::runtime_error("libmosquitto: cannot make a client");
    // Destroyed with the state if what follows throws.
    struct Undo {
        State& s;
        bool armed = true;
        ~Undo() {
            if (armed) mosquitto_destroy(s.mosq);
        }
    } undo{s};
    mosquitto_int_option(s.mosq, MOSQ_OPT_PROTOCOL_VERSION,
                         broker.protocol_version == 5 ? MQTT_PROTOCOL_V5 : MQTT_PROTOCOL_V311);
    if (!broker.user.empty()) {
        s.who = " as " + broker.user;
        if (mosquitto_username_pw_set(s.mosq, broker.user.c_str(),
                                      password.empty() ? nullptr : password.c_str()) !=
            MOSQ_ERR_SUCCESS)
            throw std::runtime_error("libmosquitto: cannot take the user " + broker.user);
    }
    if (broker.tls) {
        // The system's authorities where no CA file is named (a broker with a public
        // certificate); the broker's name is checked against its certificate either way.
        s.tls_check = broker.ca_file.empty() ? "the system's authorities" : broker.ca_file;
        const int rc = mosquitto_tls_set(
            s.mosq, broker.ca_file.empty() ? nullptr : broker.ca_file.c_str(),
            broker.ca_file.empty() ? "/etc/ssl/certs" : nullptr, nullptr, nullptr, nullptr);
        if (rc != MOSQ_ERR_SUCCESS)
            throw std::runtime_error("mqtt: TLS cannot use " + s.tls_check + ": " +
                                     mosquitto_strerror(rc));
        mosquitto_tls_opts_set(s.mosq, 1 /* SSL_VERIFY_PEER */, nullptr, nullptr);
    }
    mosquitto_will_set(s.mosq, s.will.topic.c_str(), static_cast<int>(s.will.payload.size()),
                       s.will.payload.data(), 1, s.will.retain);
    mosquitto_threaded_set(s.mosq, true);
    mosquitto_connect_callback_set(s.mosq, [](mosquitto*, void* user, int rc) {
        auto& st = state_of(user);
        if (rc != 0) {
            st.trouble("the broker refused the box" + st.who + ": " + st.refusal(rc) +
                       " (retried with back-off)");
            return;
        }
        st.connected = true;
        st.told = false;
        if (st.callbacks.connected) st.callbacks.connected();
    });
    mosquitto_disconnect_callback_set(s.mosq, [](mosquitto*, void* user, int rc) {
        auto& st = state_of(user);
        const bool was = st.connected.exchange(false);
        if (rc != 0 && was)
            st.trouble(std::string("the broker went: ") + mosquitto_strerror(rc) +
                       " (retried with back-off)");
    });
    mosquitto_message_callback_set(s.mosq, [](mosquitto*, void* user, const mosquitto_message* m) {
        auto& st = state_of(user);
        if (!st.callbacks.message || m->topic == nullptr) return;
        st.callbacks.message(m->topic, std::string(static_cast<const char*>(m->payload),
                                                   static_cast<std::size_t>(m->payloadlen)));
    });
    // A broker not there yet is tried again by the network thread, at the back-off's pace.
    s.address = broker.address.host + ":" + std::to_string(broker.address.port);
    const int rc = mosquitto_connect_async(s.mosq, broker.address.host.c_str(),
                                           broker.address.port, 30);
    if (rc != MOSQ_ERR_SUCCESS) s.unreachable(rc);
    s.network = std::thread([&s, rc] { s.run(rc == MOSQ_ERR_SUCCESS); });
    undo.armed = false;
}

MqttClient::~MqttClient() {
    auto& s = *state_;
    {
        const std::lock_guard lock(s.stop_mutex);
        s.stopping = true;
    }
    s.stop_asked.notify_all();
    s.network.join();
    mosquitto_destroy(s.mosq);
}

void MqttClient::publish(const std::string& topic, const std::string& payload, bool retain) {
    if (!state_->connected) return;
    mosquitto_publish(state_->mosq, nullptr, topic.c_str(), static_cast<int>(payload.size()),
                      payload.data(), 1, retain);
}

void MqttClient::subscribe(const std::string& topic) {
    mosquitto_subscribe(state_->mosq, nullptr, topic.c_str(), 1);
}

bool MqttClient::connected() const {
    return state_->connected;
}

}  // namespace calbox::drivers
