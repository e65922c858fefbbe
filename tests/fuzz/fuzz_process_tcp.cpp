// libFuzzer target: the bytes a TCP client sends, to a real server in this process over a loopback
// socket (process_harness.hpp): the acceptor, TcpSession's reads and writes, the connection, the
// engine and the replies as a client reads them. The input's end is the client closing its side.
// Its seeds are server_stream's: the same framed byte streams.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>

#include "tests/fuzz/process_harness.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mtlod::fuzz;
  const std::uint16_t port = ProcessServer::get().port();
  run_stream_client(std::span<const std::uint8_t>(data, size),
                    [port] { return std::make_unique<ClientSocket>(port); });
  return 0;
}
