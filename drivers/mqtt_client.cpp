#include "drivers/mqtt_client.hpp"

#include <mosquitto.h>

#include <atomic>
#include <mutex>
#include <stdexcept>

namespace calbox::drivers {

struct MqttClient::State {
    mosquitto* mosq = nullptr;
    Callbacks callbacks;
    MqttWill will;
    std::atomic<bool> connected{false};
    std::mutex told_mutex;
    std::string last_trouble;  // told once until it changes or the link is back

    void trouble(const std::string& why) {
        {
            const std::lock_guard lock(told_mutex);
            if (why == last_trouble) return;
            last_trouble = why;
        }
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
    mosquitto_reconnect_delay_set(s.mosq, 1, 60, true);
    mosquitto_connect_callback_set(s.mosq, [](mosquitto*, void* user, int rc) {
        auto& st = state_of(user);
        if (rc != 0) {
            st.trouble(std::string("the broker refused the box: ") + mosquitto_connack_string(rc) +
                       " (retried with back-off)");
            return;
        }
        st.connected = true;
        {
            const std::lock_guard lock(st.told_mutex);
            st.last_trouble.clear();
        }
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
    const int rc = mosquitto_connect_async(s.mosq, host.c_str(), port, 30);
    if (rc != MOSQ_ERR_SUCCESS)
        s.trouble(
            "cannot reach the broker at " + host + ":" + std::to_string(port) + ": " +
            (rc == MOSQ_ERR_ERRNO ? "connection refused or no route" : mosquitto_strerror(rc)) +
            " (retried with back-off)");
    if (mosquitto_loop_start(s.mosq) != MOSQ_ERR_SUCCESS) {
        mosquitto_destroy(s.mosq);
        throw std::runtime_error("libmosquitto: cannot start its network thread");
    }
}

MqttClient::~MqttClient() {
    auto& s = *state_;
    const bool connected = s.connected;
    if (connected && !closing_.empty())
        mosquitto_publish(s.mosq, nullptr, s.will.topic.c_str(), static_cast<int>(closing_.size()),
                          closing_.data(), 1, true);
    mosquitto_disconnect(s.mosq);
    // Connected: the network thread sends what is queued, then the disconnect, and ends. Not
    // connected: it may sit in the back-off's wait, so it is stopped where it is.
    mosquitto_loop_stop(s.mosq, !connected);
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
