// Anonymous mappings for ZeroedArray (see zeroed_array.hpp).
#include "core/util/zeroed_array.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <new>
#include <vector>

namespace mtlod::core::util::zeroed_detail {
namespace {

std::size_t page_size() {
  static const std::size_t size = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  return size;
}

}  // namespace

void* map(std::size_t bytes) {
  // MAP_NORESERVE: the length is the model's, the pages written are the cut's.
  void* data =
      ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (data == MAP_FAILED) throw std::bad_alloc();
  return data;
}

void unmap(void* data, std::size_t bytes) {
  ::munmap(data, bytes);
}

std::size_t resident(const void* data, std::size_t bytes) {
  const std::size_t page = page_size();
  const std::size_t pages = (bytes + page - 1) / page;
  // One byte per page; a thread's own scratch, as sessions ask from any worker.
  thread_local std::vector<unsigned char> in_memory;
  in_memory.resize(pages);
  if (::mincore(const_cast<void*>(data), bytes, in_memory.data()) != 0) return pages * page;
  std::size_t count = 0;
  for (const unsigned char p : in_memory) count += p & 1;
  return count * page;
}

}  // namespace mtlod::core::util::zeroed_detail
