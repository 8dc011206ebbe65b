#include "drivers/mqtt_client.hpp"

#include <mosquitto.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
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
        trouble(
            "cannot reach the broker at " + address + ": " +
            (rc == MOSQ_ERR_ERRNO ? std::string(std::strerror(errno)) : mosquitto_strerror(rc)) +
            " (retried with back-off)");
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

}  // namespace

MqttClient::MqttClient(const std::string& client_id, const std::string& host, int port,
                       MqttWill will, Callbacks callbacks)
    : state_(std::make_unique<State>()) {
    library_once();
    auto& s = *state_;
    s.callbacks = std::move(callbacks);
    s.will = std::move(will);
    s.mosq = mosquitto_new(client_id.c_str(), true, &s);
    if (s.mosq == nullptr) throw std::runtime_error("libmosquitto: cannot make a client");
    mosquitto_int_option(s.mosq, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
    mosquitto_will_set(s.mosq, s.will.topic.c_str(), static_cast<int>(s.will.payload.size()),
                       s.will.payload.data(), 1, s.will.retain);
    mosquitto_threaded_set(s.mosq, true);
    mosquitto_connect_callback_set(s.mosq, [](mosquitto*, void* user, int rc) {
        auto& st = state_of(user);
        if (rc != 0) {
            st.trouble(std::string("the broker refused the box: ") + mosquitto_connack_string(rc) +
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
    s.address = host + ":" + std::to_string(port);
    const int rc = mosquitto_connect_async(s.mosq, host.c_str(), port, 30);
    if (rc != MOSQ_ERR_SUCCESS) s.unreachable(rc);
    s.network = std::thread([&s, rc] { s.run(rc == MOSQ_ERR_SUCCESS); });
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
