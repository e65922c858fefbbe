// PROXY protocol v2 headers written out byte by byte from HAProxy's doc/proxy-protocol.txt (section
// 2.2): what each kind says, that every prefix of a valid header asks for exactly the bytes still
// missing and never for one past its end, and that each malformed field is refused as soon as its
// byte has arrived.
#include "protocol/proxy_header.hpp"

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

namespace mtlod::protocol {
namespace {

using Bytes = std::vector<std::uint8_t>;

// The 12-byte signature, spelled out as the specification prints it.
const Bytes kSignature{0x0D, 0x0A, 0x0D, 0x0A, 0x00, 0x0D, 0x0A, 0x51, 0x55, 0x49, 0x54, 0x0A};

// Signature, version-and-command, family-and-transport, the 16-bit big-endian length of `block`,
// then `block`.
Bytes header(std::uint8_t version_command, std::uint8_t family_transport, const Bytes& block) {
  Bytes out = kSignature;
  out.push_back(version_command);
  out.push_back(family_transport);
  out.push_back(static_cast<std::uint8_t>(block.size() >> 8));
  out.push_back(static_cast<std::uint8_t>(block.size() & 0xFF));
  out.insert(out.end(), block.begin(), block.end());
  return out;
}

// PROXY, TCP over IPv4: 192.0.2.10:51234 to 198.51.100.1:7878, with every byte written out.
const Bytes kIpv4{0x0D, 0x0A, 0x0D, 0x0A, 0x00, 0x0D, 0x0A, 0x51, 0x55, 0x49, 0x54, 0x0A,  // signature
                  0x21,                                                                    // v2, PROXY
                  0x11,                                                                    // TCP over IPv4
                  0x00, 0x0C,                                                              // 12 bytes follow
                  192,  0,    2,    10,                                                    // source
                  198,  51,   100,  1,                                                     // destination
                  0xC8, 0x22,                                                              // 51234
                  0x1E, 0xC6};                                                             // 7878

// PROXY, TCP over IPv6: [2001:db8::7]:443 to [2001:db8::1]:7878.
Bytes ipv6_header() {
  Bytes block{0x20, 0x01, 0x0D, 0xB8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,    0x07, 0x20,
              0x01, 0x0D, 0xB8, 0,    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x01, 0x01, 0xBB,  // 443
              0x1E, 0xC6};                                                             // 7878
  return header(0x21, 0x21, block);
}

ProxyHeader parse_whole(const Bytes& bytes) {
  const auto read = parse_proxy_header(bytes);
  EXPECT_TRUE(read.ok()) << read.error().message;
  if (!read.ok()) return {};
  EXPECT_TRUE(read->complete()) << "asks for " << read->bytes_needed;
  return read->header;
}

// The error for `bytes`, failing the test when they parse.
Error parse_error(const Bytes& bytes) {
  const auto read = parse_proxy_header(bytes);
  EXPECT_FALSE(read.ok()) << "parsed; asks for " << (read.ok() ? read->bytes_needed : 0);
  return read.ok() ? Error{} : read.error();
}

bool mentions(const Error& error, const std::string& text) {
  return error.message.find(text) != std::string::npos;
}

TEST(ProxyHeader, ReadsTcpOverIpv4) {
  const ProxyHeader h = parse_whole(kIpv4);
  EXPECT_EQ(h.command, ProxyCommand::kProxy);
  EXPECT_EQ(h.family, ProxyFamily::kIpv4);
  EXPECT_EQ(Bytes(h.source_address.begin(), h.source_address.begin() + 4), (Bytes{192, 0, 2, 10}));
  EXPECT_EQ(Bytes(h.destination_address.begin(), h.destination_address.begin() + 4),
            (Bytes{198, 51, 100, 1}));
  EXPECT_EQ(h.source_port, 51234);
  EXPECT_EQ(h.destination_port, 7878);
  EXPECT_EQ(h.header_bytes, 28u);  // 16 + 2×4 + 2×2
}

TEST(ProxyHeader, ReadsTcpOverIpv6) {
  const ProxyHeader h = parse_whole(ipv6_header());
  EXPECT_EQ(h.command, ProxyCommand::kProxy);
  EXPECT_EQ(h.family, ProxyFamily::kIpv6);
  const std::array<std::uint8_t, 16> source{0x20, 0x01, 0x0D, 0xB8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x07};
  const std::array<std::uint8_t, 16> destination{0x20, 0x01, 0x0D, 0xB8, 0, 0, 0, 0,
                                                 0,    0,    0,    0,    0, 0, 0, 0x01};
  EXPECT_EQ(h.source_address, source);
  EXPECT_EQ(h.destination_address, destination);
  EXPECT_EQ(h.source_port, 443);
  EXPECT_EQ(h.destination_port, 7878);
  EXPECT_EQ(h.header_bytes, 52u);  // 16 + 2×16 + 2×2
}

TEST(ProxyHeader, LocalIgnoresFamilyAndAddresses) {
  // What HAProxy's check-send-proxy sends: LOCAL, UNSPEC, no address.
  const ProxyHeader bare = parse_whole(header(0x20, 0x00, {}));
  EXPECT_EQ(bare.command, ProxyCommand::kLocal);
  EXPECT_EQ(bare.family, ProxyFamily::kNone);
  EXPECT_EQ(bare.header_bytes, 16u);
  // The specification: the receiver must skip the length it is given even for LOCAL, and ignore
  // the family, whatever it is (here an IPv4 block, then a family byte it does not define).
  Bytes with_block = kIpv4;
  with_block[12] = 0x20;
  const ProxyHeader skipped = parse_whole(with_block);
  EXPECT_EQ(skipped.command, ProxyCommand::kLocal);
  EXPECT_EQ(skipped.family, ProxyFamily::kNone);
  EXPECT_EQ(skipped.header_bytes, 28u);
  EXPECT_EQ(skipped.source_port, 0);
  EXPECT_EQ(parse_whole(header(0x20, 0x41, {1, 2, 3})).header_bytes, 19u);
}

TEST(ProxyHeader, UnspecAndUnixCarryNoClientAddress) {
  const ProxyHeader unspec = parse_whole(header(0x21, 0x00, {}));
  EXPECT_EQ(unspec.command, ProxyCommand::kProxy);
  EXPECT_EQ(unspec.family, ProxyFamily::kNone);
  EXPECT_EQ(unspec.header_bytes, 16u);
  // UNSPEC with address bytes anyway: they are skipped ("the receiver should ignore address
  // information").
  EXPECT_EQ(parse_whole(header(0x21, 0x00, Bytes(12, 0xAB))).header_bytes, 28u);
  // AF_UNIX stream: two 108-byte paths.
  Bytes paths(216, 0);
  const std::string path = "/run/haproxy.sock";
  std::copy(path.begin(), path.end(), paths.begin());
  const ProxyHeader unix_stream = parse_whole(header(0x21, 0x31, paths));
  EXPECT_EQ(unix_stream.command, ProxyCommand::kProxy);
  EXPECT_EQ(unix_stream.family, ProxyFamily::kNone);
  EXPECT_EQ(unix_stream.header_bytes, 232u);
}

TEST(ProxyHeader, SkipsTlvsAfterTheAddresses) {
  Bytes block(kIpv4.begin() + 16, kIpv4.end());
  // PP2_TYPE_ALPN "h2", PP2_TYPE_NOOP of 3 bytes, a custom type 0xE0 of 0 bytes.
  const Bytes tlvs{0x01, 0x00, 0x02, 'h', '2', 0x04, 0x00, 0x03, 0, 0, 0, 0xE0, 0x00, 0x00};
  block.insert(block.end(), tlvs.begin(), tlvs.end());
  const ProxyHeader h = parse_whole(header(0x21, 0x11, block));
  EXPECT_EQ(h.header_bytes, 16u + 12 + tlvs.size());
  EXPECT_EQ(h.family, ProxyFamily::kIpv4);
  EXPECT_EQ(Bytes(h.source_address.begin(), h.source_address.begin() + 4), (Bytes{192, 0, 2, 10}));
  EXPECT_EQ(h.source_port, 51234);
  // TLVs are not read: one whose length runs past the header is skipped all the same.
  block.insert(block.end(), {0x02, 0xFF, 0xFF});
  EXPECT_EQ(parse_whole(header(0x21, 0x11, block)).header_bytes, 16u + 12 + tlvs.size() + 3);
}

TEST(ProxyHeader, StopsAtTheHeadersEndWhateverFollows) {
  // A protocol frame (or a TLS ClientHello, or HTTP) comes right after on the same stream.
  Bytes stream = kIpv4;
  const Bytes frame{22, 0, 0, 0, 0, 0, 0, 0, '{', '"', 't', 'y', 'p', 'e', '"'};
  stream.insert(stream.end(), frame.begin(), frame.end());
  EXPECT_EQ(parse_whole(stream).header_bytes, kIpv4.size());
}

TEST(ProxyHeader, EveryPrefixAsksForTheMissingBytesOnly) {
  Bytes with_tlv = kIpv4;
  with_tlv[15] = 12 + 5;
  with_tlv.insert(with_tlv.end(), {0x01, 0x00, 0x02, 'h', '2'});
  for (const Bytes& whole : {kIpv4, ipv6_header(), header(0x20, 0x00, {}), header(0x21, 0x00, {}),
                             header(0x20, 0x11, Bytes(12, 7)), with_tlv}) {
    for (std::size_t n = 0; n < whole.size(); ++n) {
      const auto read = parse_proxy_header(std::span(whole.data(), n));
      ASSERT_TRUE(read.ok()) << n << " bytes: " << read.error().message;
      ASSERT_FALSE(read->complete()) << n << " of " << whole.size() << " bytes";
      // 16 until the length field is in, then the whole header: never a byte of what follows it.
      EXPECT_EQ(read->bytes_needed, n < 16 ? 16 : whole.size()) << n << " bytes";
      EXPECT_GT(read->bytes_needed, n);
    }
    EXPECT_EQ(parse_whole(whole).header_bytes, whole.size());
  }
}

TEST(ProxyHeader, RefusesAWrongSignatureAtItsFirstWrongByte) {
  for (std::size_t i = 0; i < kSignature.size(); ++i) {
    Bytes bytes = kIpv4;
    bytes[i] ^= 0x40;
    // Refused with only the bytes up to the wrong one: a peer that is no balancer is not waited on.
    const Error early = parse_error(Bytes(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(i) + 1));
    EXPECT_EQ(early.code, ErrorCode::kCorrupt) << i;
    EXPECT_TRUE(mentions(early, "signature")) << early.message;
    EXPECT_TRUE(mentions(early, "byte " + std::to_string(i))) << early.message;
    EXPECT_EQ(parse_error(bytes).code, ErrorCode::kCorrupt);
  }
  // What reaches a port when the balancer sends no header, or the text of version 1.
  for (const std::string text :
       {"GET /health HTTP/1.1\r\n\r\n", "PROXY TCP4 192.0.2.10 198.51.100.1 51234 7878\r\n"}) {
    const Error error = parse_error(Bytes(text.begin(), text.end()));
    EXPECT_TRUE(mentions(error, "no PROXY protocol v2 signature")) << error.message;
  }
  const Bytes hello_frame{30, 0, 0, 0, 0, 0, 0, 0, '{'};
  EXPECT_TRUE(mentions(parse_error(hello_frame), "signature"));
  const Bytes tls_client_hello{0x16, 0x03, 0x01, 0x02, 0x00};
  EXPECT_TRUE(mentions(parse_error(tls_client_hello), "signature"));
}

TEST(ProxyHeader, RefusesOtherVersionsAndCommandsAtTheThirteenthByte) {
  for (const std::uint8_t version_command : {0x11, 0x31, 0x01, 0xF1}) {
    Bytes bytes = kIpv4;
    bytes[12] = version_command;
    const Error error = parse_error(Bytes(bytes.begin(), bytes.begin() + 13));
    EXPECT_EQ(error.code, ErrorCode::kCorrupt);
    EXPECT_TRUE(mentions(error, "version " + std::to_string(version_command >> 4))) << error.message;
  }
  for (const std::uint8_t version_command : {0x22, 0x2F}) {
    Bytes bytes = kIpv4;
    bytes[12] = version_command;
    const Error error = parse_error(Bytes(bytes.begin(), bytes.begin() + 13));
    EXPECT_EQ(error.code, ErrorCode::kCorrupt);
    EXPECT_TRUE(mentions(error, "command")) << error.message;
    EXPECT_EQ(parse_error(bytes).code, ErrorCode::kCorrupt);
  }
}

TEST(ProxyHeader, RefusesDatagramsAndUnknownFamiliesAtTheFourteenthByte) {
  for (const std::uint8_t datagram : {0x12, 0x22, 0x32}) {
    const Bytes bytes = header(0x21, datagram, Bytes(216, 0));
    const Error error = parse_error(Bytes(bytes.begin(), bytes.begin() + 14));
    EXPECT_EQ(error.code, ErrorCode::kUnsupported);
    EXPECT_TRUE(mentions(error, datagram == 0x32 ? "UNIX datagram" : "UDP")) << error.message;
  }
  // Values outside the specification's table, whichever half is wrong.
  for (const std::uint8_t unknown : {0x10, 0x01, 0x13, 0x41, 0x20, 0xFF}) {
    const Bytes bytes = header(0x21, unknown, Bytes(216, 0));
    const Error error = parse_error(Bytes(bytes.begin(), bytes.begin() + 14));
    EXPECT_EQ(error.code, ErrorCode::kCorrupt);
    EXPECT_TRUE(mentions(error, "unknown")) << error.message;
  }
}

TEST(ProxyHeader, RefusesAnAddressBlockShorterThanItsFamilyNeeds) {
  struct Case {
    std::uint8_t family_transport;
    std::size_t needed;
  };
  for (const Case c : {Case{0x11, 12}, Case{0x21, 36}, Case{0x31, 216}}) {
    for (const std::size_t length : {std::size_t{0}, c.needed - 1}) {
      const Bytes bytes = header(0x21, c.family_transport, Bytes(length, 1));
      // Refused as soon as the length field is in, before any address byte is waited for.
      const Error error = parse_error(Bytes(bytes.begin(), bytes.begin() + 16));
      EXPECT_EQ(error.code, ErrorCode::kCorrupt);
      EXPECT_TRUE(mentions(
          error, std::to_string(length) + " address bytes, fewer than the " + std::to_string(c.needed)))
          << error.message;
    }
    EXPECT_EQ(parse_whole(header(0x21, c.family_transport, Bytes(c.needed, 1))).header_bytes, 16 + c.needed);
  }
}

TEST(ProxyHeader, RefusesALengthOverTheCap) {
  EXPECT_EQ(kProxyMaxLength, 2048u);
  const Bytes at_cap = header(0x21, 0x11, Bytes(kProxyMaxLength, 0));
  EXPECT_EQ(parse_whole(at_cap).header_bytes, 16 + kProxyMaxLength);
  for (const std::size_t length : {kProxyMaxLength + 1, std::size_t{0xFFFF}}) {
    Bytes fixed = kIpv4;
    fixed.resize(16);
    fixed[14] = static_cast<std::uint8_t>(length >> 8);
    fixed[15] = static_cast<std::uint8_t>(length & 0xFF);
    const Error error = parse_error(fixed);
    EXPECT_EQ(error.code, ErrorCode::kLimitExceeded);
    EXPECT_TRUE(mentions(error, "length " + std::to_string(length) + " exceeds the limit of 2048"))
        << error.message;
    // LOCAL too: its bytes would be waited on all the same.
    fixed[12] = 0x20;
    EXPECT_EQ(parse_error(fixed).code, ErrorCode::kLimitExceeded);
  }
}

TEST(ProxyHeader, MatchesTheSignatureAsFarAsTheBytesGo) {
  EXPECT_TRUE(matches_proxy_signature({}));
  for (std::size_t n = 1; n <= kIpv4.size(); ++n)
    EXPECT_TRUE(matches_proxy_signature(std::span(kIpv4.data(), n)));
  const std::string http = "GET / HTTP/1.1\r\n";
  EXPECT_FALSE(
      matches_proxy_signature(std::span(reinterpret_cast<const std::uint8_t*>(http.data()), http.size())));
  EXPECT_FALSE(matches_proxy_signature(Bytes{0x16, 0x03, 0x01}));
  EXPECT_FALSE(matches_proxy_signature(Bytes{0x0D, 0x0A, 0x0D, 0x0A, 0x01}));
}

TEST(ProxyHeader, AnyBytesGiveAnAnswerWithinTheirLength) {
  // Fixed-seed mutations of valid headers and random strings: never a crash (the sanitizers watch),
  // and a complete header never claims more bytes than it was given.
  std::mt19937 random(20240601);
  const std::vector<Bytes> seeds{kIpv4, ipv6_header(), header(0x20, 0x00, {}),
                                 header(0x21, 0x31, Bytes(216, 9))};
  for (int round = 0; round < 20000; ++round) {
    Bytes bytes = seeds[round % seeds.size()];
    if (round % 5 == 4) bytes.assign(random() % 64, 0);
    const int mutations = 1 + static_cast<int>(random() % 4);
    for (int m = 0; m < mutations && !bytes.empty(); ++m) {
      const std::size_t at = random() % bytes.size();
      switch (random() % 3) {
        case 0:
          bytes[at] = static_cast<std::uint8_t>(random());
          break;
        case 1:
          bytes.resize(at);
          break;
        default:
          bytes.insert(bytes.begin() + static_cast<std::ptrdiff_t>(at), static_cast<std::uint8_t>(random()));
      }
    }
    const auto read = parse_proxy_header(bytes);
    if (!read.ok()) {
      EXPECT_FALSE(read.error().message.empty());
    } else if (read->complete()) {
      EXPECT_LE(read->header.header_bytes, bytes.size());
      EXPECT_GE(read->header.header_bytes, kProxyFixedBytes);
    } else {
      EXPECT_GT(read->bytes_needed, bytes.size());
      EXPECT_LE(read->bytes_needed, kProxyFixedBytes + kProxyMaxLength);
    }
  }
}

}  // namespace
}  // namespace mtlod::protocol
