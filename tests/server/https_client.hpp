// HTTPS for the TLS tests (Beast over OpenSSL, synchronous): one request per fresh connection to
// 127.0.0.1, trusting one certificate. The WebSocket upgrade is sent as a plain HTTP request, so a
// refusal's status can be read (Beast 1.74's websocket handshake drops a declined response).
#pragma once

#include <openssl/x509v3.h>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "tests/server/http_client.hpp"

namespace mtlod::test {

// GET `target` with `headers` (name, value) over TLS; status 0 when the connection or the TLS
// handshake failed or nothing HTTP came back.
inline HttpReply https_get(std::uint16_t port, const std::filesystem::path& ca, const std::string& target,
                           const std::vector<std::pair<std::string, std::string>>& headers = {}) {
  namespace net = boost::asio;
  namespace beast = boost::beast;
  namespace http = beast::http;
  HttpReply reply;
  net::io_context ioc;
  net::ssl::context context(net::ssl::context::tls_client);
  context.load_verify_file(ca.string());
  context.set_verify_mode(net::ssl::verify_peer);
  beast::ssl_stream<beast::tcp_stream> stream(ioc, context);
  beast::error_code ec;
  beast::get_lowest_layer(stream).expires_after(std::chrono::seconds(10));
  beast::get_lowest_layer(stream).connect(net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), port),
                                          ec);
  if (ec) return reply;
  X509_VERIFY_PARAM_set1_ip_asc(SSL_get0_param(stream.native_handle()), "127.0.0.1");
  stream.handshake(net::ssl::stream_base::client, ec);
  if (ec) return reply;
  http::request<http::empty_body> request{http::verb::get, target, 11};
  request.set(http::field::host, "127.0.0.1");
  for (const auto& [name, value] : headers) request.set(name, value);
  http::write(stream, request, ec);
  if (ec) return reply;
  beast::flat_buffer buffer;
  http::response_parser<http::string_body> parser;
  http::read_header(stream, buffer, parser, ec);
  if (ec) return reply;
  reply.status = parser.get().result_int();
  // A 101 has no body: the stream is a WebSocket from here on.
  if (reply.status != 101) http::read(stream, buffer, parser, ec);
  for (const auto& field : parser.get()) {
    reply.head += std::string(field.name_string()) + ": " + std::string(field.value()) + "\r\n";
  }
  reply.body = parser.get().body();
  return reply;
}

// The HTTP status a WebSocket upgrade of `target` gets (101: upgraded), with `authorization` as
// the Authorization header when not empty.
inline int upgrade_status(std::uint16_t port, const std::filesystem::path& ca, const std::string& target,
                          const std::string& authorization = "") {
  std::vector<std::pair<std::string, std::string>> headers = {
      {"Upgrade", "websocket"},
      {"Connection", "upgrade"},
      {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="},
      {"Sec-WebSocket-Version", "13"}};
  if (!authorization.empty()) headers.emplace_back("Authorization", authorization);
  return https_get(port, ca, target, headers).status;
}

}  // namespace mtlod::test
