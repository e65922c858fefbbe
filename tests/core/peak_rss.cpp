// Runs a command and checks the peak resident set size the kernel measured for it (wait4's
// ru_maxrss), not what the command says about itself, against a limit in MiB. The command's output
// passes through unchanged; the last line says the peak and whether it stayed under the limit.
//   mtlod_peak_rss LIMIT_MIB -- PROGRAM [ARGUMENT...]
// Exit status: 0 when the command exited with 0 and its peak is at most the limit; 1 when it failed
// (non-zero status, a signal, or it could not be run) or went over the limit; 2 on a bad command line.
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

int main(int argc, char** argv) {
  char* end = nullptr;
  const long limit_mib = argc > 3 ? std::strtol(argv[1], &end, 10) : 0;
  if (argc < 4 || *end != '\0' || limit_mib <= 0 || std::string(argv[2]) != "--") {
    std::fprintf(stderr, "usage: %s LIMIT_MIB -- PROGRAM [ARGUMENT...]\n", argv[0]);
    return 2;
  }
  // Buffered output would otherwise be written twice, once by each process.
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid < 0) {
    std::fprintf(stderr, "peak_rss: fork: %s\n", std::strerror(errno));
    return 1;
  }
  if (pid == 0) {
    execvp(argv[3], argv + 3);
    std::fprintf(stderr, "peak_rss: cannot run %s: %s\n", argv[3], std::strerror(errno));
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  while (wait4(pid, &status, 0, &usage) < 0) {
    if (errno == EINTR) continue;
    std::fprintf(stderr, "peak_rss: wait4: %s\n", std::strerror(errno));
    return 1;
  }
  // Linux reports ru_maxrss in KiB.
  const long peak_kib = usage.ru_maxrss, limit_kib = limit_mib * 1024;
  const double peak_mib = double(peak_kib) / 1024.0;
  if (WIFSIGNALED(status)) {
    std::printf("peak_rss: %s was killed by signal %d (%s) at a peak RSS of %.1f MiB\n", argv[3],
                WTERMSIG(status), strsignal(WTERMSIG(status)), peak_mib);
    return 1;
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::printf("peak_rss: %s failed with exit status %d at a peak RSS of %.1f MiB\n", argv[3],
                WIFEXITED(status) ? WEXITSTATUS(status) : -1, peak_mib);
    return 1;
  }
  if (peak_kib > limit_kib) {
    std::printf("peak_rss: peak RSS %.1f MiB is over the limit of %ld MiB\n", peak_mib, limit_mib);
    return 1;
  }
  std::printf("peak_rss: peak RSS %.1f MiB is within the limit of %ld MiB\n", peak_mib, limit_mib);
  return 0;
}
