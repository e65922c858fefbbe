// libFuzzer target: any text given to the request parser yields a request or an error with a
// message; a parsed request serialises and parses back to the same type.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "protocol/parse.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mtlod::protocol;
  const auto parsed = parse_request(std::string_view(reinterpret_cast<const char*>(data), size), Limits{});
  if (!parsed) {
    if (parsed.error().message.empty()) __builtin_trap();
    return 0;
  }
  const auto again = parse_request(to_json(parsed->request, parsed->id), Limits{});
  if (!again || again->request.index() != parsed->request.index() || again->id != parsed->id)
    __builtin_trap();
  return 0;
}
