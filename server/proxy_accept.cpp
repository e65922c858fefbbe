// Trusted networks and the reading of PROXY headers before a connection is admitted (see
// proxy_accept.hpp). Each socket is read on its own strand, as the sessions it becomes are.
#include "server/proxy_accept.hpp"

#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>

#include <algorithm>
#include <charconv>
#include <chrono>

#include "fmt/format.h"
#include "protocol/proxy_header.hpp"
#include "protocol/text.hpp"
#include "server/admission.hpp"
#include "server/metrics.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace {

namespace net = boost::asio;
using tcp = net::ip::tcp;
using boost::system::error_code;

// An untrusted peer whose first bytes so far are a strict prefix of the signature is looked at
// again after this pause: it may yet turn out to be anything.
constexpr auto kScreenRetry = std::chrono::milliseconds(10);

std::array<std::uint8_t, 16> v6_bytes(const net::ip::address& address) {
  if (address.is_v4()) return net::ip::make_address_v6(net::ip::v4_mapped, address.to_v4()).to_bytes();
  return address.to_v6().to_bytes();
}

std::string_view trimmed(std::string_view text) {
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  return text;
}

}  // namespace

Result<TrustedNetworks> TrustedNetworks::parse(const std::vector<std::string>& entries) {
  TrustedNetworks out;
  for (const std::string& entry : entries) {
    for (std::string_view rest = entry; !rest.empty();) {
      const std::size_t comma = std::min(rest.find(','), rest.size());
      const std::string_view text = trimmed(rest.substr(0, comma));
      rest = rest.substr(std::min(comma + 1, rest.size()));
      auto bad = [&](const std::string& why) {
        return make_error(ErrorCode::kInvalidArgument,
                          fmt::format("--proxy-protocol-from '{}': {}", protocol::printable(text), why));
      };
      if (text.empty()) return bad("an empty network");
      const std::size_t slash = text.find('/');
      error_code ec;
      const net::ip::address address = net::ip::make_address(std::string(text.substr(0, slash)), ec);
      if (ec) return bad("not an IPv4 or IPv6 address");
      const unsigned width = address.is_v4() ? 32 : 128;
      unsigned prefix = width;
      if (slash != std::string_view::npos) {
        const std::string_view digits = text.substr(slash + 1);
        const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), prefix);
        if (digits.empty() || error != std::errc() || end != digits.data() + digits.size() || prefix > width)
          return bad(fmt::format("the prefix length must be 0 to {}", width));
      }
      Network network{v6_bytes(address), prefix + (128 - width), std::string(text)};
      for (unsigned bit = network.prefix_bits; bit < 128; ++bit) {
        if (network.bytes[bit / 8] & (0x80u >> (bit % 8)))
          return bad(fmt::format("the address has bits set past the /{} prefix", prefix));
      }
      out.networks_.push_back(std::move(network));
    }
  }
  return out;
}

bool TrustedNetworks::contains(const net::ip::address& address) const {
  const std::array<std::uint8_t, 16> bytes = v6_bytes(address);
  return std::any_of(networks_.begin(), networks_.end(), [&](const Network& network) {
    const unsigned whole = network.prefix_bits / 8, rest = network.prefix_bits % 8;
    if (!std::equal(bytes.begin(), bytes.begin() + whole, network.bytes.begin())) return false;
    const auto mask = static_cast<std::uint8_t>(0xFF00u >> rest);
    return rest == 0 || (bytes[whole] & mask) == network.bytes[whole];
  });
}

std::string TrustedNetworks::to_string() const {
  std::string out;
  for (const Network& network : networks_) out += (out.empty() ? "" : ", ") + network.text;
  return out;
}

std::string client_address_text(const net::ip::address& address) {
  if (address.is_v6() && address.to_v6().is_v4_mapped())
    return net::ip::make_address_v4(net::ip::v4_mapped, address.to_v6()).to_string();
  return address.to_string();
}

// One socket on its way to admission. Runs on the socket's strand; stop() posts cancel() there.
struct ProxyGate::Operation : std::enable_shared_from_this<ProxyGate::Operation> {
  Operation(ProxyGate& gate, tcp::socket s, std::string n, Handoff h)
      : socket(std::move(s)),
        executor(socket.get_executor()),
        deadline(executor),
        name(std::move(n)),
        peer(remote_address(socket)),
        handoff(std::move(h)),
        metrics(gate.metrics_),
        timeout_ms(gate.timeout_ms_) {}
  virtual ~Operation() = default;

  void cancel() {
    cancelled = true;
    close();
  }
  void close() {
    error_code ignored;
    deadline.cancel();
    socket.close(ignored);
  }
  // Arms the deadline: when it passes, the socket is closed and the pending read or wait ends.
  void arm() {
    deadline.expires_after(std::chrono::milliseconds(timeout_ms));
    deadline.async_wait([self = shared_from_this()](error_code ec) {
      if (ec || self->finished) return;
      self->timed_out = true;
      error_code ignored;
      self->socket.close(ignored);
    });
  }
  void finish(std::string address) {
    finished = true;
    deadline.cancel();
    handoff(std::move(socket), std::move(address));
  }

  tcp::socket socket;
  net::any_io_executor executor;  // the socket's strand, kept apart so that stop() may read it
  net::steady_timer deadline;
  std::string name;  // "conn=12" or "http", for the log
  std::string peer;  // the socket's own address
  Handoff handoff;
  Metrics& metrics;
  std::uint32_t timeout_ms;
  bool cancelled = false, timed_out = false, finished = false;
};

namespace {

// A trusted peer's header: read in as many steps as it arrives in, never a byte past its end.
struct HeaderRead final : ProxyGate::Operation {
  using Operation::Operation;

  void start() {
    arm();
    read(protocol::kProxyFixedBytes);
  }

  void read(std::size_t total) {
    bytes.resize(total);
    socket.async_read_some(net::buffer(bytes.data() + have, total - have),
                           [self = std::static_pointer_cast<HeaderRead>(shared_from_this())](
                               error_code ec, std::size_t n) { self->on_read(ec, n); });
  }

  void on_read(error_code ec, std::size_t n) {
    have += n;
    if (cancelled) return;  // the server is stopping
    if (timed_out) {
      return refuse(fmt::format("no complete header within {} ms ({} of {} bytes arrived)", timeout_ms, have,
                                bytes.size()));
    }
    if (ec) {
      return refuse(ec == net::error::eof || ec == net::error::connection_reset
                        ? fmt::format("the peer closed after {} of the header's {} bytes", have, bytes.size())
                        : fmt::format("reading the header failed: {}", ec.message()));
    }
    const auto parsed = protocol::parse_proxy_header(std::span<const std::uint8_t>(bytes.data(), have));
    if (!parsed) return refuse(parsed.error().message);
    if (!parsed->complete()) return read(parsed->bytes_needed);
    const protocol::ProxyHeader& header = parsed->header;
    if (header.command == protocol::ProxyCommand::kLocal) {
      spdlog::debug("{} from {}: PROXY header LOCAL: served as the balancer's own connection", name, peer);
      return finish(peer);
    }
    if (header.family == protocol::ProxyFamily::kNone) {
      spdlog::debug("{} from {}: PROXY header without an IP address: served on the socket's address", name,
                    peer);
      return finish(peer);
    }
    const net::ip::address source =
        header.family == protocol::ProxyFamily::kIpv4
            ? net::ip::address(net::ip::address_v4(
                  net::ip::address_v4::bytes_type{header.source_address[0], header.source_address[1],
                                                  header.source_address[2], header.source_address[3]}))
            : net::ip::address(net::ip::address_v6(header.source_address));
    std::string client = client_address_text(source);
    spdlog::debug("{} from {}: PROXY header: client {} port {}", name, peer, client, header.source_port);
    finish(std::move(client));
  }

  void refuse(const std::string& why) {
    // A trusted peer is the balancer: a bad header there is a misconfiguration worth a warning, and
    // only the few trusted addresses can cause one.
    spdlog::warn("{} from {} refused: PROXY header: {}", name, peer, protocol::printable(why));
    metrics.connection_refused();
    close();
  }

  std::vector<std::uint8_t> bytes;
  std::size_t have = 0;
};

// An untrusted peer's first bytes, looked at with MSG_PEEK so that its session reads them all.
struct Screen final : ProxyGate::Operation {
  using Operation::Operation;

  void start() {
    error_code ignored;
    socket.non_blocking(true, ignored);  // a peek after a spurious wake-up must not block the thread
    arm();
    wait();
  }

  void wait() {
    socket.async_wait(tcp::socket::wait_read, [self = std::static_pointer_cast<Screen>(shared_from_this())](
                                                  error_code ec) { self->on_readable(ec); });
  }

  void on_readable(error_code ec) {
    if (cancelled) return;
    if (ec || timed_out) {
      spdlog::debug("{} from {} closed: {}", name, peer, timed_out ? "nothing sent in time" : ec.message());
      return close();
    }
    std::array<std::uint8_t, protocol::kProxySignature.size()> first{};
    const std::size_t n = socket.receive(net::buffer(first), tcp::socket::message_peek, ec);
    if (ec == net::error::would_block) return wait();
    if (ec || n == 0) return close();  // gone before saying anything: nothing to serve
    const std::span<const std::uint8_t> seen(first.data(), n);
    if (!protocol::matches_proxy_signature(seen)) {
      socket.non_blocking(false, ec);
      return finish(peer);
    }
    if (n == first.size()) {
      // Info, not warning: anyone can send this, and it affects no one else.
      spdlog::info(
          "{} from {} refused: a PROXY protocol header from an address outside --proxy-protocol-from", name,
          peer);
      metrics.connection_refused();
      return close();
    }
    retry.expires_after(kScreenRetry);
    retry.async_wait([self = std::static_pointer_cast<Screen>(shared_from_this())](error_code ec) {
      if (ec || self->cancelled) return;
      self->on_readable({});
    });
  }

  net::steady_timer retry{executor};
};

}  // namespace

ProxyGate::ProxyGate(TrustedNetworks networks, std::uint32_t timeout_ms, Metrics& metrics)
    : networks_(std::move(networks)), timeout_ms_(timeout_ms), metrics_(metrics) {}

ProxyGate::~ProxyGate() = default;

bool ProxyGate::trusted(const tcp::socket& socket) const {
  error_code ec;
  const tcp::endpoint peer = socket.remote_endpoint(ec);
  return !ec && networks_.contains(peer.address());
}

bool ProxyGate::track(const std::shared_ptr<Operation>& operation) {
  std::lock_guard lock(mutex_);
  if (stopped_) return false;
  pending_.remove_if([](const std::weak_ptr<Operation>& o) { return o.expired(); });
  pending_.push_back(operation);
  return true;
}

void ProxyGate::read_header(tcp::socket socket, std::string name, Handoff handoff) {
  auto operation =
      std::make_shared<HeaderRead>(*this, std::move(socket), std::move(name), std::move(handoff));
  if (!track(operation)) return operation->close();
  net::post(operation->executor, [operation] { operation->start(); });
}

void ProxyGate::screen(tcp::socket socket, std::string name, Handoff handoff) {
  auto operation = std::make_shared<Screen>(*this, std::move(socket), std::move(name), std::move(handoff));
  if (!track(operation)) return operation->close();
  net::post(operation->executor, [operation] { operation->start(); });
}

void ProxyGate::stop() {
  std::lock_guard lock(mutex_);
  stopped_ = true;
  for (const auto& weak : pending_) {
    if (auto operation = weak.lock()) net::post(operation->executor, [operation] { operation->cancel(); });
  }
  pending_.clear();
}

}  // namespace mtlod::server
