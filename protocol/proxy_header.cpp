// PROXY protocol version 2 headers (see proxy_header.hpp; HAProxy's doc/proxy-protocol.txt, 2.2).
// Each field is checked as soon as its bytes are there, so a peer that is not a balancer is turned
// away on its first bytes rather than after the server has waited for sixteen.
#include "protocol/proxy_header.hpp"

#include <algorithm>
#include <cstring>

#include "fmt/format.h"

namespace mtlod::protocol {
namespace {

constexpr std::uint8_t kVersion2 = 0x2;
constexpr std::uint8_t kCommandLocal = 0x0, kCommandProxy = 0x1;

// The family-and-transport bytes the specification lists (its "in practice" table), with the
// address block each needs.
struct FamilyTransport {
  std::uint8_t byte;
  const char* name;
  std::size_t address_bytes;
  ProxyFamily family;
  bool datagram;
};
constexpr std::array<FamilyTransport, 7> kFamilyTransports{{
    {0x00, "UNSPEC", 0, ProxyFamily::kNone, false},
    {0x11, "TCP over IPv4", 2 * 4 + 2 * 2, ProxyFamily::kIpv4, false},
    {0x12, "UDP over IPv4", 2 * 4 + 2 * 2, ProxyFamily::kIpv4, true},
    {0x21, "TCP over IPv6", 2 * 16 + 2 * 2, ProxyFamily::kIpv6, false},
    {0x22, "UDP over IPv6", 2 * 16 + 2 * 2, ProxyFamily::kIpv6, true},
    // AF_UNIX addresses are paths, not client addresses: the socket's own address stands in.
    {0x31, "UNIX stream", 2 * 108, ProxyFamily::kNone, false},
    {0x32, "UNIX datagram", 2 * 108, ProxyFamily::kNone, true},
}};

std::uint16_t read_u16_be(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] << 8 | p[1]);
}

// The family-and-transport entry a PROXY command may carry, or the error that refuses it.
Result<const FamilyTransport*> family_transport(std::uint8_t byte) {
  const auto* it = std::find_if(kFamilyTransports.begin(), kFamilyTransports.end(),
                                [byte](const FamilyTransport& f) { return f.byte == byte; });
  if (it == kFamilyTransports.end()) {
    return make_error(ErrorCode::kCorrupt,
                      fmt::format("PROXY header family and transport 0x{:02x} are unknown (expected 0x00, "
                                  "0x11, 0x21 or 0x31)",
                                  byte));
  }
  // The specification lets a receiver treat these as UNSPEC; a datagram header on a stream
  // connection can only come from a misconfigured balancer, which should hear about it.
  if (it->datagram) {
    return make_error(ErrorCode::kUnsupported,
                      fmt::format("PROXY header transport is {} (0x{:02x}): only stream (TCP) connections "
                                  "are relayed to this server",
                                  it->name, byte));
  }
  return it;
}

}  // namespace

bool matches_proxy_signature(std::span<const std::uint8_t> bytes) {
  const std::size_t n = std::min(bytes.size(), kProxySignature.size());
  return std::equal(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n), kProxySignature.begin());
}

Result<ProxyHeaderRead> parse_proxy_header(std::span<const std::uint8_t> bytes) {
  const std::size_t signature_bytes = std::min(bytes.size(), kProxySignature.size());
  for (std::size_t i = 0; i < signature_bytes; ++i) {
    if (bytes[i] != kProxySignature[i]) {
      return make_error(ErrorCode::kCorrupt,
                        fmt::format("no PROXY protocol v2 signature: byte {} is 0x{:02x} where the signature "
                                    "has 0x{:02x}",
                                    i, bytes[i], kProxySignature[i]));
    }
  }
  const FamilyTransport* family = nullptr;
  bool local = false;
  if (bytes.size() > 12) {
    const std::uint8_t version = bytes[12] >> 4, command = bytes[12] & 0x0F;
    if (version != kVersion2) {
      return make_error(ErrorCode::kCorrupt,
                        fmt::format("PROXY header version {}: only version 2 is accepted", version));
    }
    if (command != kCommandLocal && command != kCommandProxy) {
      return make_error(ErrorCode::kCorrupt, fmt::format("PROXY header command 0x{:x} is unknown (0x0 is "
                                                         "LOCAL, 0x1 PROXY)",
                                                         command));
    }
    local = command == kCommandLocal;
  }
  // LOCAL's family is ignored, whatever it says (the specification: "discard the protocol block
  // including the family").
  if (bytes.size() > 13 && !local) {
    MTLOD_TRY(family, family_transport(bytes[13]));
  }
  if (bytes.size() < kProxyFixedBytes) return ProxyHeaderRead{kProxyFixedBytes, {}};

  const std::size_t length = read_u16_be(bytes.data() + 14);
  if (length > kProxyMaxLength) {
    return make_error(
        ErrorCode::kLimitExceeded,
        fmt::format("PROXY header length {} exceeds the limit of {} bytes", length, kProxyMaxLength));
  }
  if (family && length < family->address_bytes) {
    return make_error(ErrorCode::kCorrupt,
                      fmt::format("PROXY header holds {} address bytes, fewer than the {} that {} needs",
                                  length, family->address_bytes, family->name));
  }
  const std::size_t total = kProxyFixedBytes + length;
  if (bytes.size() < total) return ProxyHeaderRead{total, {}};

  ProxyHeaderRead read;
  ProxyHeader& header = read.header;
  header.header_bytes = total;
  header.command = local ? ProxyCommand::kLocal : ProxyCommand::kProxy;
  if (local || family->family == ProxyFamily::kNone) return read;
  // Addresses, then ports: source before destination, all in network byte order.
  const std::uint8_t* block = bytes.data() + kProxyFixedBytes;
  const std::size_t address_bytes = family->family == ProxyFamily::kIpv4 ? 4 : 16;
  header.family = family->family;
  std::memcpy(header.source_address.data(), block, address_bytes);
  std::memcpy(header.destination_address.data(), block + address_bytes, address_bytes);
  header.source_port = read_u16_be(block + 2 * address_bytes);
  header.destination_port = read_u16_be(block + 2 * address_bytes + 2);
  return read;
}

}  // namespace mtlod::protocol
