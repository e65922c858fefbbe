// Access tokens (README, "TLS and access tokens"; PROTOCOL.md, "Access tokens"): the table that
// mtlod-server --auth-tokens FILE loads, and which models each token may see. A connection shows
// its token in `hello` (a WebSocket in its upgrade request) and is served only after that.
//
// The file: one token per line, optionally followed by the names of the models it may see (none:
// every model); `#` starts a comment where a word would start. Tokens are 16 to 256 characters
// from A-Z a-z 0-9 - . _ ~ (safe in a URL as they are: the viewer passes them in its query).
//
//   # the lab's viewers see every model; the demo token only the bunny
//   3f6a1c0e9b8d7f2a5c4e6b1d0a9f8e7c   # lab
//   demo-token-2024-bunny-only bunny
#pragma once

#include <array>
#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "core/result.hpp"

namespace mtlod::server {

// What one token grants.
struct Grant {
  std::size_t line = 0;             // the token's line in the file: names it in logs without showing it
  std::vector<std::string> models;  // empty: every model

  bool sees(std::string_view model) const;
};

class TokenTable {
 public:
  static constexpr std::size_t kMinTokenLength = 16;
  static constexpr std::size_t kMaxTokenLength = 256;

  // Reads the file's text; errors name `source` and the line.
  static Result<TokenTable> parse(std::string_view text, const std::string& source);
  static Result<TokenTable> load(const std::filesystem::path& file);

  // The grant of `token`, or nullptr when it is not in the table. Compares SHA-256 digests with
  // CRYPTO_memcmp against every entry, so the time taken tells neither how much of a guess was
  // right nor which entry it was closest to; a digest also has one length whatever the token's.
  const Grant* find(std::string_view token) const;

  std::size_t size() const { return entries_.size(); }
  // Every model name some token lists (to warn about names that no loaded model has).
  std::vector<std::string> listed_models() const;

 private:
  struct Entry {
    std::array<unsigned char, 32> digest{};  // SHA-256 of the token: the token itself is not kept
    Grant grant;
  };
  std::vector<Entry> entries_;
};

}  // namespace mtlod::server
