// The trusted networks of --proxy-protocol-from, without a socket: which entries parse (and why the
// others do not), and which peers they hold, checked by hand on edge cases and against a plain
// 32-bit mask on fixed-seed random IPv4 networks and addresses.
#include "server/proxy_accept.hpp"

#include <gtest/gtest.h>

#include <random>

namespace mtlod::server {
namespace {

namespace ip = boost::asio::ip;

TrustedNetworks parse_ok(const std::vector<std::string>& entries) {
  auto networks = TrustedNetworks::parse(entries);
  EXPECT_TRUE(networks.ok()) << networks.error().message;
  return networks.ok() ? std::move(*networks) : TrustedNetworks{};
}

bool holds(const TrustedNetworks& networks, const std::string& address) {
  return networks.contains(ip::make_address(address));
}

TEST(TrustedNetworks, HoldIpv4PeersAndTheirMappedForms) {
  const TrustedNetworks n = parse_ok({"10.0.0.0/8"});
  EXPECT_TRUE(holds(n, "10.0.0.0"));
  EXPECT_TRUE(holds(n, "10.255.255.255"));
  EXPECT_FALSE(holds(n, "11.0.0.0"));
  EXPECT_FALSE(holds(n, "9.255.255.255"));
  // A dual-stack listener reports an IPv4 peer as ::ffff:a.b.c.d.
  EXPECT_TRUE(holds(n, "::ffff:10.1.2.3"));
  EXPECT_FALSE(holds(n, "::ffff:11.1.2.3"));
  // The same 32 bits in an ordinary IPv6 address are not an IPv4 peer.
  EXPECT_FALSE(holds(n, "::a01:203"));
  EXPECT_FALSE(holds(n, "10::1"));
}

TEST(TrustedNetworks, HoldIpv6PeersByPrefix) {
  const TrustedNetworks n = parse_ok({"::1/128", "2001:db8::/32", "fc00::/7"});
  EXPECT_TRUE(holds(n, "::1"));
  EXPECT_FALSE(holds(n, "::2"));
  EXPECT_FALSE(holds(n, "127.0.0.1"));  // loopback by another family is another peer
  EXPECT_TRUE(holds(n, "2001:db8:ffff:ffff::1"));
  EXPECT_FALSE(holds(n, "2001:db9::"));
  // A prefix that ends inside a byte: fc00::/7 is fc00:: to fdff:ff...
  EXPECT_TRUE(holds(n, "fc00::1"));
  EXPECT_TRUE(holds(n, "fdff::1"));
  EXPECT_FALSE(holds(n, "fe00::1"));
  EXPECT_FALSE(holds(n, "fb00::1"));
}

TEST(TrustedNetworks, TakeBareAddressesCommaListsAndTheWholeSpace) {
  const TrustedNetworks hosts = parse_ok({"127.0.0.1, ::1", "192.168.0.0/23"});
  EXPECT_EQ(hosts.to_string(), "127.0.0.1, ::1, 192.168.0.0/23");
  EXPECT_TRUE(holds(hosts, "127.0.0.1"));
  EXPECT_FALSE(holds(hosts, "127.0.0.2"));
  EXPECT_TRUE(holds(hosts, "192.168.1.255"));
  EXPECT_FALSE(holds(hosts, "192.168.2.0"));
  const TrustedNetworks every_v4 = parse_ok({"0.0.0.0/0"});
  EXPECT_TRUE(holds(every_v4, "203.0.113.7"));
  EXPECT_TRUE(holds(every_v4, "::ffff:203.0.113.7"));
  EXPECT_FALSE(holds(every_v4, "2001:db8::1"));
  EXPECT_TRUE(parse_ok({}).empty());
  EXPECT_FALSE(parse_ok({}).contains(ip::make_address("127.0.0.1")));
}

TEST(TrustedNetworks, NameWhatIsWrongWithAnEntry) {
  struct Case {
    std::string entry, message;
  };
  for (const Case& c : {Case{"10.0.0.1/8", "'10.0.0.1/8': the address has bits set past the /8 prefix"},
                        Case{"2001:db8::1/32", "has bits set past the /32 prefix"},
                        Case{"banana", "'banana': not an IPv4 or IPv6 address"},
                        Case{"10.0.0.0/33", "the prefix length must be 0 to 32"},
                        Case{"::/129", "the prefix length must be 0 to 128"},
                        Case{"10.0.0.0/", "the prefix length must be 0 to 32"},
                        Case{"10.0.0.0/8x", "the prefix length must be 0 to 32"},
                        Case{"10.0.0.0/-8", "the prefix length must be 0 to 32"},
                        Case{"10.0.0.0/8,,::1", "'': an empty network"}}) {
    const auto parsed = TrustedNetworks::parse({c.entry});
    ASSERT_FALSE(parsed.ok()) << c.entry;
    EXPECT_EQ(parsed.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(parsed.error().message.find("--proxy-protocol-from"), std::string::npos)
        << parsed.error().message;
    EXPECT_NE(parsed.error().message.find(c.message), std::string::npos) << parsed.error().message;
  }
}

TEST(TrustedNetworks, AgreeWithAPlainMaskOnRandomIpv4Networks) {
  std::mt19937 random(7878);
  for (int round = 0; round < 2000; ++round) {
    const unsigned prefix = random() % 33;
    const std::uint32_t mask = prefix == 0 ? 0 : ~std::uint32_t{0} << (32 - prefix);
    const std::uint32_t network = static_cast<std::uint32_t>(random()) & mask;
    const TrustedNetworks n = parse_ok({ip::address_v4(network).to_string() + "/" + std::to_string(prefix)});
    for (int probe = 0; probe < 20; ++probe) {
      // Half the probes inside the network with random host bits, half anywhere.
      const std::uint32_t address = probe % 2 ? (network | (static_cast<std::uint32_t>(random()) & ~mask))
                                              : static_cast<std::uint32_t>(random());
      const bool expected = (address & mask) == network;
      EXPECT_EQ(n.contains(ip::address_v4(address)), expected)
          << ip::address_v4(address).to_string() << " in " << n.to_string();
    }
  }
}

TEST(ClientAddressText, WritesMappedIpv4AsIpv4) {
  EXPECT_EQ(client_address_text(ip::make_address("::ffff:203.0.113.8")), "203.0.113.8");
  EXPECT_EQ(client_address_text(ip::make_address("203.0.113.8")), "203.0.113.8");
  EXPECT_EQ(client_address_text(ip::make_address("2001:db8::7")), "2001:db8::7");
}

}  // namespace
}  // namespace mtlod::server
