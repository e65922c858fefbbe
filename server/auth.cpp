// Access tokens (see auth.hpp). OpenSSL supplies SHA-256 and the constant-time comparison.
#include "server/auth.hpp"

#include <openssl/crypto.h>
#include <openssl/evp.h>

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>

#include "fmt/format.h"

namespace mtlod::server {
namespace {

using Digest = std::array<unsigned char, 32>;

Digest sha256(std::string_view text) {
  Digest digest{};
  unsigned int size = 0;
  // EVP_Digest fails only when OpenSSL cannot allocate; a zero digest then matches no entry.
  if (::EVP_Digest(text.data(), text.size(), digest.data(), &size, ::EVP_sha256(), nullptr) != 1) digest = {};
  return digest;
}

bool token_character(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' || c == '.' ||
         c == '_' || c == '~';
}

}  // namespace

bool Grant::sees(std::string_view model) const {
  return models.empty() || std::find(models.begin(), models.end(), model) != models.end();
}

Result<TokenTable> TokenTable::parse(std::string_view text, const std::string& source) {
  TokenTable table;
  std::set<Digest> seen;
  std::istringstream lines{std::string(text)};
  std::string line;
  for (std::size_t number = 1; std::getline(lines, line); ++number) {
    std::istringstream words(line);
    std::string token;
    if (!(words >> token) || token.front() == '#') continue;
    if (token.size() < kMinTokenLength || token.size() > kMaxTokenLength ||
        !std::all_of(token.begin(), token.end(), token_character)) {
      // The message does not quote the token: it is a secret, and the error may be logged.
      return make_error(
          ErrorCode::kInvalidArgument,
          fmt::format("{}:{}: a token is {} to {} characters from A-Z a-z 0-9 - . _ ~ (this one has "
                      "{}); make one with `openssl rand -hex 32`",
                      source, number, kMinTokenLength, kMaxTokenLength, token.size()));
    }
    Entry entry{sha256(token), Grant{number, {}}};
    if (!seen.insert(entry.digest).second) {
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("{}:{}: this token is already on an earlier line", source, number));
    }
    for (std::string model; words >> model && model.front() != '#';) entry.grant.models.push_back(model);
    table.entries_.push_back(std::move(entry));
  }
  return table;
}

Result<TokenTable> TokenTable::load(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in)
    return make_error(ErrorCode::kNotFound, fmt::format("{}: cannot read the tokens file", file.string()));
  std::stringstream text;
  text << in.rdbuf();
  MTLOD_TRY(TokenTable table, parse(text.str(), file.string()));
  if (table.size() == 0) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("{}: no tokens (one per line: TOKEN [model ...])", file.string()));
  }
  return table;
}

const Grant* TokenTable::find(std::string_view token) const {
  const Digest digest = sha256(token);
  const Grant* found = nullptr;
  // Every entry is compared, matched or not: the loop's length does not depend on the guess.
  for (const Entry& entry : entries_) {
    const bool match = ::CRYPTO_memcmp(entry.digest.data(), digest.data(), digest.size()) == 0;
    if (match) found = &entry.grant;
  }
  return found;
}

std::vector<std::string> TokenTable::listed_models() const {
  std::set<std::string> names;
  for (const Entry& entry : entries_) names.insert(entry.grant.models.begin(), entry.grant.models.end());
  return {names.begin(), names.end()};
}

}  // namespace mtlod::server
