// Reads the table of malformed requests from protocol/PROTOCOL.md, so the document and the tests
// (parser unit tests and the server integration test) can never disagree.
#pragma once

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

namespace mtlod::test {

struct MalformedCase {
  std::string json;
  std::string code;
  std::string message_contains;
};

inline std::filesystem::path protocol_document() {
  return std::filesystem::path(MTLOD_SOURCE_DIR) / "protocol/PROTOCOL.md";
}

// Rows of the form | `{...}` | `code` | `text in the message` |
inline std::vector<MalformedCase> malformed_cases() {
  std::ifstream in(protocol_document());
  std::vector<MalformedCase> cases;
  const std::regex row(R"(^\|\s*`(\{.*\})`\s*\|\s*`([a-z_]+)`\s*\|\s*`([^`]*)`\s*\|)");
  std::string line;
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_search(line, m, row)) cases.push_back({m[1], m[2], m[3]});
  }
  return cases;
}

}  // namespace mtlod::test
