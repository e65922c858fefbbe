// The TCP transport of a connection: length-prefixed frames (PROTOCOL.md "Framing") over a socket,
// plain or TLS, with idle and read timeouts.
#pragma once

#include <boost/asio/ip/tcp.hpp>

#include <cstdint>
#include <memory>

#include "server/connection.hpp"

namespace boost::asio::ssl {
class context;
}

namespace mtlod::server {

// Starts serving an accepted socket; the socket's executor must be a strand. With `tls` the
// connection speaks TLS only: its handshake must complete within the first-frame deadline.
std::shared_ptr<Connection> start_tcp_session(ServerContext& server, boost::asio::ip::tcp::socket socket,
                                              std::uint64_t number, AddressTable::Slot slot,
                                              boost::asio::ssl::context* tls);

}  // namespace mtlod::server
