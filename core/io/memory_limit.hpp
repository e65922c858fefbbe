// The memory a process should plan to use when nobody says: the default of mtlod-server's
// --max-memory and of mtlod-build's --memory-limit.
#pragma once

#include <cstdint>

namespace mtlod::core::io {

// Half the memory this process may use: the machine's RAM or the cgroup's limit (a container's),
// whichever is smaller. The rest is left to the models, the allocator and the system.
std::uint64_t default_memory_limit();

}  // namespace mtlod::core::io
