// The TCP transport of a connection: length-prefixed frames (PROTOCOL.md "Framing") over a socket,
// with idle and read timeouts.
#pragma once

#include <boost/asio/ip/tcp.hpp>

#include <cstdint>
#include <memory>

#include "server/connection.hpp"

namespace mtlod::server {

// Starts serving an accepted socket; the socket's executor must be a strand.
std::shared_ptr<Connection> start_tcp_session(ServerContext& server, boost::asio::ip::tcp::socket socket,
                                              std::uint64_t number, AddressTable::Slot slot);

}  // namespace mtlod::server
