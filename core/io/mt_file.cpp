// .mt file reading and writing: a memory map or one read, one write; parsing lives in
// core/model/mt_format.cpp.
#include "core/io/mt_file.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <system_error>
#include <vector>

#include "core/model/mt_format.hpp"

namespace mtlod::core::io {
namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

// A read-only shared mapping of a whole file: the pages come from the page cache as they are read,
// and the kernel can drop them again under memory pressure.
class Mapping {
 public:
  Mapping(const void* data, std::size_t size) : data_(data), size_(size) {}
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  ~Mapping() { ::munmap(const_cast<void*>(data_), size_); }
  std::span<const std::uint8_t> bytes() const { return {static_cast<const std::uint8_t*>(data_), size_}; }
  void advise_random() const { ::madvise(const_cast<void*>(data_), size_, MADV_RANDOM); }

 private:
  const void* data_;
  std::size_t size_;
};

Error named(const std::filesystem::path& path, Error error) {
  error.message = path.string() + ": " + error.message;
  return error;
}

// Opens path read-only: a missing file is kNotFound, any other failure kIoError.
Result<int> open_readonly(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd >= 0) return fd;
  if (errno == ENOENT)
    return make_error(ErrorCode::kNotFound, "MT file " + path.string() + " does not exist");
  return make_error(ErrorCode::kIoError, "cannot open " + path.string() + ": " + std::strerror(errno));
}

// Reads the whole file behind fd (from its start) with pread, which a truncation can only shorten.
Result<std::vector<std::uint8_t>> read_whole(int fd, std::uint64_t size, const std::filesystem::path& path) {
  std::vector<std::uint8_t> bytes(size);
  for (std::uint64_t done = 0; done < size;) {
    const ssize_t n = ::pread(fd, bytes.data() + done, size - done, static_cast<off_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      return make_error(ErrorCode::kBusy, path.string() + ": changed while it was read (short read)");
    done += static_cast<std::uint64_t>(n);
  }
  return bytes;
}

// Maps a whole file of at least a header's size, or says why not.
Result<std::shared_ptr<const Mapping>> map_whole(int fd, std::size_t size,
                                                 const std::filesystem::path& path) {
  void* data = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, fd, 0);
  if (data == MAP_FAILED)
    return make_error(ErrorCode::kIoError, "cannot map " + path.string() + ": " + std::strerror(errno));
  return std::make_shared<const Mapping>(data, size);
}

// The current format is read in place from the mapping; refinements jump between blocks, so no
// read-ahead beyond the pages they touch. Version 1 is copied out of the mapping whole.
Result<model::Mt> parse_mapped(std::shared_ptr<const Mapping> mapping, const std::filesystem::path& path) {
  const bool in_place = model::mt_file_version(mapping->bytes()) == model::kMtFormatVersion;
  if (in_place) mapping->advise_random();
  auto mt = in_place ? model::view_mt(mapping->bytes(), mapping) : model::deserialize_mt(mapping->bytes());
  if (!mt) return named(path, mt.take_error());
  return mt;
}

Result<model::Mt> parse_read(std::span<const std::uint8_t> bytes, const std::filesystem::path& path) {
  auto mt = model::deserialize_mt(bytes);  // reports what is wrong with a short file too
  if (!mt) return named(path, mt.take_error());
  return mt;
}

}  // namespace

Result<model::Mt> read_mt_file(const std::filesystem::path& path, MtLoad load) {
  MTLOD_TRY(const int fd, open_readonly(path));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return make_error(ErrorCode::kInvalidArgument, path.string() + ": not a regular file");
  }
  const std::size_t size = std::size_t(st.st_size);
  if (load == MtLoad::kMap && size >= model::kMtHeaderBytes) {
    auto mapping = map_whole(fd, size, path);
    ::close(fd);  // the mapping keeps the file
    if (!mapping) return mapping.take_error();
    return parse_mapped(std::move(*mapping), path);
  }
  auto bytes = read_whole(fd, size, path);
  ::close(fd);
  if (!bytes) return bytes.take_error();
  return parse_read(*bytes, path);
}

Result<ServedMt> open_served_mt(const std::filesystem::path& path) {
  MTLOD_TRY(const int fd, open_readonly(path));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return make_error(ErrorCode::kInvalidArgument, path.string() + ": not a regular file");
  }
  ServedMt served;
  auto lease = FileLease::acquire(fd);  // owns fd from here on, whatever it answers
  if (!lease && lease.error().code == ErrorCode::kBusy) return named(path, lease.take_error());
  if (!lease) {
    // No lease here: a private copy, which no other process can change or truncate.
    served.read_whole_because = lease.error().message;
    MTLOD_TRY(const int copy_fd, open_readonly(path));
    auto before = identify(copy_fd);
    if (!before) {
      ::close(copy_fd);
      return named(path, before.take_error());
    }
    auto bytes = read_whole(copy_fd, before->size, path);
    auto after = identify(copy_fd);
    ::close(copy_fd);
    if (!bytes) return bytes.take_error();
    if (!after || *after != *before)
      return make_error(ErrorCode::kBusy, path.string() + ": changed while it was read");
    served.identity = *before;
    MTLOD_TRY(served.mt, parse_read(*bytes, path));
    return served;
  }
  served.lease = std::move(*lease);
  const int leased = served.lease->fd();
  MTLOD_TRY(served.identity, identify(leased));
  const std::size_t size = served.identity.size;
  if (size < model::kMtHeaderBytes) {
    MTLOD_TRY(std::vector<std::uint8_t> bytes, read_whole(leased, size, path));
    served.lease.reset();
    MTLOD_TRY(served.mt, parse_read(bytes, path));
    return served;
  }
  MTLOD_TRY(std::shared_ptr<const Mapping> mapping, map_whole(leased, size, path));
  const bool copied = model::mt_file_version(mapping->bytes()) != model::kMtFormatVersion;
  MTLOD_TRY(served.mt, parse_mapped(std::move(mapping), path));
  // Version 1 was copied out of the mapping whole: nothing is left to guard.
  if (copied) served.lease.reset();
  return served;
}

Result<std::uint64_t> write_mt_file(const std::filesystem::path& path, const model::Mt& mt) {
  std::vector<std::uint8_t> bytes;
  model::serialize_mt(mt, bytes);
  // Written beside and renamed over: a server may have the old file mapped, and rewriting a mapped
  // file in place would pull pages out from under it.
  std::filesystem::path partial = path;
  partial += ".partial";
  {
    File file(std::fopen(partial.c_str(), "wb"));
    if (!file)
      return make_error(ErrorCode::kIoError,
                        "cannot create " + partial.string() + ": " + std::strerror(errno));
    if (std::fwrite(bytes.data(), 1, bytes.size(), file.get()) != bytes.size() ||
        std::fflush(file.get()) != 0)
      return make_error(ErrorCode::kIoError,
                        "cannot write " + partial.string() + ": " + std::strerror(errno));
  }
  std::error_code ec;
  std::filesystem::rename(partial, path, ec);
  if (ec) return make_error(ErrorCode::kIoError, "cannot rename " + partial.string() + ": " + ec.message());
  return std::uint64_t{bytes.size()};
}

}  // namespace mtlod::core::io
