// libFuzzer target: TLS to a real server in this process (process_harness.hpp), on its protocol
// port with a certificate. The first input byte chooses what the rest is:
//   even: raw bytes in place of a TLS handshake (OpenSSL's record and handshake parsing in the
//         server's session): the server must close the connection, and then still serve a real
//         TLS client (a ping answered with a pong);
//   odd:  a client's byte stream after a real handshake: TcpSession's reads and writes over TLS,
//         checked as the plain TCP target checks them (the same seeds, behind one byte).
// The client ends its side by shutting down the TCP socket without close_notify, as many do.
#include <sys/socket.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/write.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "protocol/frame.hpp"
#include "tests/fuzz/process_harness.hpp"

namespace mtlod::fuzz {
namespace {

namespace net = boost::asio;
namespace ssl = net::ssl;

// A TLS client trusting the server's own certificate; every wait has a deadline (complete()).
class TlsChannel final : public Channel {
 public:
  TlsChannel(std::uint16_t port, const std::filesystem::path& certificate)
      : context_(ssl::context::tls_client), stream_(io_, context_) {
    context_.load_verify_file(certificate.string());
    stream_.set_verify_mode(ssl::verify_peer);
    const net::ip::tcp::endpoint server(net::ip::address_v4::loopback(), port);
    auto ec = complete(io_, "a TLS connect",
                       [&](auto done) { stream_.lowest_layer().async_connect(server, done); });
    if (ec) fail("connecting to the TLS port: " + ec.message());
    ec = complete(io_, "a TLS handshake",
                  [&](auto done) { stream_.async_handshake(ssl::stream_base::client, done); });
    if (ec) fail("a real client's TLS handshake failed: " + ec.message());
  }

  bool send(std::span<const std::uint8_t> bytes) override {
    return !complete(io_, "a TLS write", [&](auto done) {
      net::async_write(stream_, net::buffer(bytes.data(), bytes.size()), done);
    });
  }

  void finish_sending() override { ::shutdown(stream_.lowest_layer().native_handle(), SHUT_WR); }

  bool receive(std::vector<std::uint8_t>& into) override {
    std::array<std::uint8_t, 65536> buffer;
    std::size_t n = 0;
    const auto ec = complete(io_, "a TLS read", [&](auto done) {
      stream_.async_read_some(net::buffer(buffer),
                              [&n, done](boost::system::error_code e, std::size_t got) mutable {
                                n = got;
                                done(e);
                              });
    });
    into.insert(into.end(), buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(n));
    return !ec;
  }

 private:
  net::io_context io_;
  ssl::context context_;
  ssl::stream<net::ip::tcp::socket> stream_;
};

std::vector<std::uint8_t> ping_frame() {
  constexpr std::string_view kPing = R"({"type":"ping","id":1})";
  std::vector<std::uint8_t> frame;
  protocol::append_frame(kPing, {}, frame);
  return frame;
}

}  // namespace
}  // namespace mtlod::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mtlod::fuzz;
  if (size == 0) return 0;
  const ProcessServer& server = ProcessServer::get();
  const std::span<const std::uint8_t> rest(data + 1, size - 1);
  auto tls = [&server] { return std::make_unique<TlsChannel>(server.tls_port(), server.certificate()); };
  if (data[0] % 2 == 1) {
    run_stream_client(rest, tls);
    return 0;
  }
  {
    ClientSocket raw(server.tls_port());
    raw.send(rest);
    raw.finish_sending();
    (void)raw.receive_all();  // alerts, or a ServerHello for a ClientHello: not frames
  }
  run_stream_client(ping_frame(), tls);
  return 0;
}
