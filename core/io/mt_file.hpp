// Reads and writes .mt files (core/ARCHITECTURE.md §2.8; layout: core/model/FORMAT.md). Version-2 files
// are memory-mapped and checked block by block as they are used; version-1 files, or any file with
// MtLoad::kRead, are read whole with one read and validated at once (core/model/mt_format).
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "core/io/file_lease.hpp"
#include "core/model/mt.hpp"
#include "core/result.hpp"

namespace mtlod::core::io {

enum class MtLoad {
  kMap,   // version 2 mapped: start-up reads the header, the block table and the root's block
  kRead,  // read into memory and validated whole
};

// Opens an .mt file. Errors name the file: kNotFound, kIoError, and the parser's kCorrupt /
// kUnsupported. A mapped file must not be truncated or rewritten in place while it is in use
// (replace it by renaming a new file over it, as mtlod-build does).
Result<model::Mt> read_mt_file(const std::filesystem::path& path, MtLoad load = MtLoad::kMap);

// An .mt file opened to be served while other processes may change it: mapped under a read lease
// (core/io/file_lease.hpp), so that the server hears of a writer before the mapping can change,
// or read whole into memory where no lease can be had (then nothing outside can change it).
struct ServedMt {
  model::Mt mt;
  FileIdentity identity;             // of the bytes the MT comes from
  std::unique_ptr<FileLease> lease;  // guards the mapping; null when the MT is in memory
  std::string read_whole_because;    // empty when mapped under a lease
};
// Errors name the file: kNotFound, kInvalidArgument (not a regular file), kBusy (open for writing
// by another process: try again once it is closed), kIoError, and the parser's kCorrupt and
// kUnsupported.
Result<ServedMt> open_served_mt(const std::filesystem::path& path);

// Writes mt as an .mt file (replacing it). Returns the file size in bytes.
Result<std::uint64_t> write_mt_file(const std::filesystem::path& path, const model::Mt& mt);

}  // namespace mtlod::core::io
