// Server-side TLS context (see tls.hpp).
#include "server/tls.hpp"

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "fmt/format.h"

namespace mtlod::server {

namespace ssl = boost::asio::ssl;

Result<std::unique_ptr<ssl::context>> make_tls_context(const std::string& cert_file,
                                                       const std::string& key_file) {
  // OpenSSL's own message for a missing file is "system library"; say which file and why.
  for (const std::string& file : {cert_file, key_file}) {
    if (!std::ifstream(file)) {
      return make_error(ErrorCode::kNotFound, fmt::format("{}: cannot read: {}", file, std::strerror(errno)));
    }
  }
  auto context = std::make_unique<ssl::context>(ssl::context::tls_server);
  context->set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 | ssl::context::no_sslv3 |
                       ssl::context::single_dh_use);
  ::SSL_CTX_set_min_proto_version(context->native_handle(), TLS1_2_VERSION);
  // A TLS 1.2 client may ask for handshake after handshake on one connection, each costing the
  // server far more than the client: nothing here needs renegotiation.
  ::SSL_CTX_set_options(context->native_handle(), SSL_OP_NO_RENEGOTIATION);
  boost::system::error_code ec;
  context->use_certificate_chain_file(cert_file, ec);
  if (ec) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("{}: not a PEM certificate chain ({})", cert_file, ec.message()));
  }
  context->use_private_key_file(key_file, ssl::context::pem, ec);
  // OpenSSL compares the key with the certificate as it loads it: a valid key of another
  // certificate fails here, and deserves its own message.
  const bool mismatch = ec && ec.category() == boost::asio::error::get_ssl_category() &&
                        ERR_GET_REASON(static_cast<unsigned long>(ec.value())) == X509_R_KEY_VALUES_MISMATCH;
  if (ec && !mismatch) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("{}: not an unencrypted PEM private key ({})", key_file, ec.message()));
  }
  if (mismatch || ::SSL_CTX_check_private_key(context->native_handle()) != 1) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("{} is not the private key of the certificate in {}", key_file, cert_file));
  }
  return context;
}

}  // namespace mtlod::server
