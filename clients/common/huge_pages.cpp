#include "clients/common/huge_pages.hpp"

#include <unistd.h>

#include <cstdlib>
#include <string>

namespace mtlod::clients {

void rerun_with_huge_pages(char** argv) {
  const char* choice = std::getenv("MTLOD_HUGE_PAGES");
  if (choice != nullptr && std::string(choice) == "0") return;
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  std::string value = tunables ? tunables : "";
  if (value.find("glibc.malloc.hugetlb") != std::string::npos) return;
  value += value.empty() ? "glibc.malloc.hugetlb=1" : ":glibc.malloc.hugetlb=1";
  if (::setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0) return;
  ::execv("/proc/self/exe", argv);
  // Not run again: go on with ordinary pages (the variable set above is harmless).
}

}  // namespace mtlod::clients
