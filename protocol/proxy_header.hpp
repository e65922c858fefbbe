// The PROXY protocol version 2 header (HAProxy's doc/proxy-protocol.txt, section 2.2) that a load
// balancer sends before the first byte of the connection it relays, naming the client's address
// (PROTOCOL.md "Behind a load balancer"). Pure code over spans, no sockets: the server reads the
// bytes and this decides how many more it needs and what they say.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "core/result.hpp"

namespace mtlod::protocol {

// The 12 bytes every version 2 header starts with.
inline constexpr std::array<std::uint8_t, 12> kProxySignature{0x0D, 0x0A, 0x0D, 0x0A, 0x00, 0x0D,
                                                              0x0A, 0x51, 0x55, 0x49, 0x54, 0x0A};
// Signature, version and command, family and transport, and the 16-bit length of what follows.
inline constexpr std::size_t kProxyFixedBytes = 16;
// The largest length field accepted: the biggest address block (AF_UNIX, 216 bytes) plus room for
// TLVs. The field allows 65535; a balancer sends tens of bytes, and a connection should not be
// able to make the server wait on, or buffer, 64 KiB before it has said who it is.
inline constexpr std::size_t kProxyMaxLength = 2048;

enum class ProxyCommand : std::uint8_t {
  kLocal,  // the balancer's own connection (a health check): use the socket's address
  kProxy,  // relayed on behalf of a client: the header's source address is the client's
};

enum class ProxyFamily : std::uint8_t {
  kNone,  // LOCAL, UNSPEC or AF_UNIX: no IP address; the socket's own address applies
  kIpv4,  // TCP over IPv4
  kIpv6,  // TCP over IPv6
};

struct ProxyHeader {
  ProxyCommand command = ProxyCommand::kLocal;
  ProxyFamily family = ProxyFamily::kNone;
  // Network byte order: the first 4 bytes for IPv4, all 16 for IPv6; zero for kNone.
  std::array<std::uint8_t, 16> source_address{}, destination_address{};
  std::uint16_t source_port = 0, destination_port = 0;
  // Every byte of the header on the stream, TLVs included (16 + its length field). The stream's
  // own bytes (a TLS handshake, frames, HTTP) start right after.
  std::size_t header_bytes = 0;
};

// What the bytes read so far say.
struct ProxyHeaderRead {
  // Nonzero while the header is incomplete: the total number of bytes to have read (16 for the
  // fixed part, then 16 + its length) before asking again. Never more than the header holds.
  std::size_t bytes_needed = 0;
  ProxyHeader header;  // when bytes_needed is 0
  bool complete() const { return bytes_needed == 0; }
};

// Reads a header from `bytes`, the first bytes of a stream (any number of them; those after the
// header are ignored). Errors as early as the bytes allow: kCorrupt for a signature that does not
// match, a version other than 2, an unknown command, an unknown family or transport, or an address
// block shorter than its family needs; kUnsupported for a datagram (UDP) transport;
// kLimitExceeded for a length field over kProxyMaxLength. TLVs are skipped, not read. A LOCAL
// header's family and addresses are ignored, as the specification requires.
Result<ProxyHeaderRead> parse_proxy_header(std::span<const std::uint8_t> bytes);

// Whether `bytes` (a stream's first bytes, possibly fewer than 12) agree with the signature as far
// as they go. True for an empty span.
bool matches_proxy_signature(std::span<const std::uint8_t> bytes);

}  // namespace mtlod::protocol
