// Connections relayed by a trusted load balancer (README "Deployment", PROTOCOL.md "Behind a load
// balancer"). A peer inside --proxy-protocol-from must open with a PROXY protocol v2 header, whose
// source address then stands for the connection everywhere: the per-address cap, the fair
// scheduler's turns, logs. Every other peer is served on its own address and may not send one, so
// no client can claim another's address. Both listeners (server.cpp, web_session.cpp) run their
// accepted sockets through here before admission; only those two include this header.
#pragma once

#include <boost/asio/ip/tcp.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/result.hpp"

namespace mtlod::server {

class Metrics;

// IPv4 and IPv6 networks in CIDR notation. An IPv4 network also holds the IPv4-mapped IPv6 forms
// of its addresses (::ffff:10.1.2.3), which is how a dual-stack socket reports IPv4 peers.
class TrustedNetworks {
 public:
  // Entries such as "10.0.0.0/8", "::1/128" or a bare address (one host); an entry may hold several
  // separated by commas. Errors name the entry: not an address, a prefix out of range, or host
  // bits set below the prefix (a likely typo, which would otherwise widen the network silently).
  static Result<TrustedNetworks> parse(const std::vector<std::string>& entries);

  bool empty() const { return networks_.empty(); }
  bool contains(const boost::asio::ip::address& address) const;
  // The networks, comma-separated, for the log.
  std::string to_string() const;

 private:
  struct Network {
    std::array<std::uint8_t, 16> bytes{};  // IPv6; an IPv4 network as its IPv4-mapped form
    unsigned prefix_bits = 0;              // of the 128
    std::string text;
  };
  std::vector<Network> networks_;
};

// The client address as text: IPv4 dotted, IPv6 in Asio's form, an IPv4-mapped IPv6 address as
// plain IPv4 (one client has one address, whichever way its balancer reports it).
std::string client_address_text(const boost::asio::ip::address& address);

// Reads PROXY headers from trusted peers and screens the first bytes of untrusted ones, for both
// listeners. Every socket it holds is closed by stop(), so a drain never waits on a header.
class ProxyGate {
 public:
  // Called on the socket's executor with the socket, unread past the header, and the client
  // address it stands for.
  using Handoff = std::function<void(boost::asio::ip::tcp::socket socket, std::string address)>;

  // `timeout_ms`: how long a header (or, from an untrusted peer, the first bytes) may take.
  // `metrics` counts refused headers as refused connections.
  ProxyGate(TrustedNetworks networks, std::uint32_t timeout_ms, Metrics& metrics);
  ~ProxyGate();

  // Whether this peer must open with a header.
  bool trusted(const boost::asio::ip::tcp::socket& socket) const;

  // For a trusted peer: reads exactly the header's bytes, then hands the socket on with the
  // header's source address (PROXY over TCP/IPv4 or IPv6) or the socket's own (LOCAL, UNSPEC,
  // AF_UNIX). A malformed, partial or late header closes the socket with a log line naming
  // `name` (e.g. "conn=12"), the peer and the reason.
  void read_header(boost::asio::ip::tcp::socket socket, std::string name, Handoff handoff);

  // For an untrusted peer: waits for its first bytes without consuming them and closes the socket,
  // with a log line, when they are the PROXY v2 signature; otherwise hands it on with its own
  // address. A peer that sends nothing within the timeout, or hangs up, is closed quietly, as an
  // idle connection would be.
  void screen(boost::asio::ip::tcp::socket socket, std::string name, Handoff handoff);

  // Closes every socket still being read or screened; later ones are closed at once. Any thread.
  void stop();

  struct Operation;  // one socket being read or screened (proxy_accept.cpp)

 private:
  // Registers `operation` for stop(); false once stopped.
  bool track(const std::shared_ptr<Operation>& operation);

  const TrustedNetworks networks_;
  const std::uint32_t timeout_ms_;
  Metrics& metrics_;
  std::mutex mutex_;
  bool stopped_ = false;
  std::list<std::weak_ptr<Operation>> pending_;
};

}  // namespace mtlod::server
