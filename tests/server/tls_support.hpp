// Certificates and access tokens for the TLS tests, made at test time: a self-signed certificate for
// 127.0.0.1 by the `openssl` program (scripts/bootstrap.sh installs it), and a tokens file in
// mtlod-server --auth-tokens format.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace mtlod::test {

// Tokens the tests' files hold: one for every model, one for the model "hare" only.
inline constexpr char kEveryModelToken[] = "test-token-every-model-0123456789abcdef";
inline constexpr char kHareOnlyToken[] = "test-token-hare-only-fedcba9876543210";

struct Certificate {
  std::filesystem::path cert;  // PEM certificate, also the CA a client trusts
  std::filesystem::path key;   // its PEM private key
};

// A self-signed certificate valid for IP address 127.0.0.1 (as the subject alternative name, which
// clients check), written into `dir`. Fails the test when openssl cannot make it.
inline Certificate make_certificate(const std::filesystem::path& dir, const std::string& name = "server") {
  Certificate out{dir / (name + "-cert.pem"), dir / (name + "-key.pem")};
  const std::string command =
      "openssl req -x509 -newkey rsa:2048 -nodes -days 2 -subj /CN=127.0.0.1 "
      "-addext subjectAltName=IP:127.0.0.1 -keyout " +
      out.key.string() + " -out " + out.cert.string() + " > " + (dir / (name + "-openssl.log")).string() +
      " 2>&1";
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
  EXPECT_TRUE(std::filesystem::exists(out.cert) && std::filesystem::exists(out.key)) << command;
  return out;
}

// A tokens file granting kEveryModelToken every model and kHareOnlyToken the model "hare".
inline std::filesystem::path write_tokens(const std::filesystem::path& dir) {
  const auto path = dir / "tokens.txt";
  std::ofstream(path) << "# made by the TLS tests\n"
                      << kEveryModelToken << "\n"
                      << kHareOnlyToken << " hare   # only the hare\n";
  return path;
}

}  // namespace mtlod::test
