// Server-side TLS (README, "TLS and access tokens"): the OpenSSL context that both listeners share
// when mtlod-server is given --tls-cert and --tls-key. Asio's SSL headers bring OpenSSL's with
// them, so only server/*.cpp files include this one.
#pragma once

#include <boost/asio/ssl/context.hpp>

#include <memory>
#include <string>

#include "core/result.hpp"

namespace mtlod::server {

// A TLS server context (TLS 1.2 or newer) from PEM files: the certificate chain, leaf first, and
// its private key (unencrypted). Errors name the file and what is wrong with it.
Result<std::unique_ptr<boost::asio::ssl::context>> make_tls_context(const std::string& cert_file,
                                                                    const std::string& key_file);

}  // namespace mtlod::server
