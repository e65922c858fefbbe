// .mt file reading and writing: one read, one write; parsing lives in core/mt_format.cpp.
#include "core/io/mt_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "core/mt_format.hpp"

namespace mtlod::core::io {
namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

}  // namespace

Result<Mt> read_mt_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    return make_error(ErrorCode::kNotFound, "MT file " + path.string() + " does not exist");
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return make_error(ErrorCode::kIoError, "cannot stat " + path.string() + ": " + ec.message());
  File file(std::fopen(path.c_str(), "rb"));
  if (!file) return make_error(ErrorCode::kIoError, "cannot open " + path.string() + ": " + std::strerror(errno));
  std::vector<std::uint8_t> bytes(size);
  if (size != 0 && std::fread(bytes.data(), 1, size, file.get()) != size)
    return make_error(ErrorCode::kIoError, "short read of " + path.string());
  auto mt = deserialize_mt(bytes);
  if (!mt.ok()) {
    Error error = mt.take_error();
    error.message = path.string() + ": " + error.message;
    return error;
  }
  return mt;
}

Result<std::uint64_t> write_mt_file(const std::filesystem::path& path, const Mt& mt) {
  std::vector<std::uint8_t> bytes;
  serialize_mt(mt, bytes);
  File file(std::fopen(path.c_str(), "wb"));
  if (!file) return make_error(ErrorCode::kIoError, "cannot create " + path.string() + ": " + std::strerror(errno));
  if (std::fwrite(bytes.data(), 1, bytes.size(), file.get()) != bytes.size() || std::fflush(file.get()) != 0)
    return make_error(ErrorCode::kIoError, "cannot write " + path.string() + ": " + std::strerror(errno));
  return std::uint64_t{bytes.size()};
}

}  // namespace mtlod::core::io
