// Reading and writing .mt files (DESIGN.md §2 "Storage", layout in core/FORMAT.md). The file is read
// with one read into memory and parsed by core/mt_format, which validates everything.
#pragma once

#include <filesystem>

#include "core/mt.hpp"
#include "core/result.hpp"

namespace mtlod::core::io {

// Reads and validates an .mt file. Errors name the file: kNotFound, kIoError, and the parser's
// kCorrupt / kUnsupported.
Result<Mt> read_mt_file(const std::filesystem::path& path);

// Writes mt as an .mt file (replacing it). Returns the file size in bytes.
Result<std::uint64_t> write_mt_file(const std::filesystem::path& path, const Mt& mt);

}  // namespace mtlod::core::io
