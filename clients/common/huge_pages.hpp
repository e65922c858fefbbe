// Transparent huge pages for a tool's large arrays. A large build allocates and first touches
// gigabytes in blocks of a few hundred megabytes; on virtual machines the page faults of 4 KiB pages
// took about half of its time. glibc's malloc backs large blocks with huge pages when its
// glibc.malloc.hugetlb tunable is 1, which must be set before the process starts.
#pragma once

namespace mtlod::clients {

// Runs this program again with glibc.malloc.hugetlb=1 added to GLIBC_TUNABLES, unless it is set
// already or MTLOD_HUGE_PAGES=0; returns (doing nothing) when the program cannot be run again.
void rerun_with_huge_pages(char** argv);

}  // namespace mtlod::clients
