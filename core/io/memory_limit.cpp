#include "core/io/memory_limit.hpp"

#include <unistd.h>

#include <fstream>

namespace mtlod::core::io {

std::uint64_t default_memory_limit() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  std::uint64_t usable =
      pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page) : std::uint64_t{4} << 30;
  // cgroup v2, then v1: "max" or a huge number mean no limit.
  for (const char* file : {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {
    std::ifstream in(file);
    std::uint64_t limit = 0;
    if (in >> limit && limit > 0 && limit < usable) usable = limit;
  }
  return usable / 2;
}

}  // namespace mtlod::core::io
