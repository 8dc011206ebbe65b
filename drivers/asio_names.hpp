#pragma once
// The names the network drivers use for Boost.Asio and Beast, and the clock their deadlines run
// on. Include only from the drivers' .cpp files (Beast's headers are heavy).
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>

namespace calbox::drivers {
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
namespace ssl = net::ssl;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;
}  // namespace calbox::drivers
