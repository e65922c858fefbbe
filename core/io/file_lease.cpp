// Read leases and their break notifications (see file_lease.hpp).
#include "core/io/file_lease.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <mutex>
#include <string>

namespace mtlod::core::io {
namespace {

// A real-time signal: queued (one per break, not merged) and carrying si_fd. Real-time signals
// end the process by default, so the handler is installed before the first lease is taken.
int lease_signal() {
  return SIGRTMIN + 3;
}

int break_pipe[2] = {-1, -1};

void on_lease_break(int, siginfo_t* info, void*) {
  const int saved = errno;
  const int fd = info->si_fd;
  // A full pipe drops the notice; the watcher also polls every lease (FileLease::breaking).
  [[maybe_unused]] const ssize_t n = ::write(break_pipe[1], &fd, sizeof fd);
  errno = saved;
}

Status install_handler() {
  static std::once_flag once;
  static Status installed = Ok{};
  std::call_once(once, [] {
    if (::pipe2(break_pipe, O_CLOEXEC | O_NONBLOCK) != 0) {
      installed =
          make_error(ErrorCode::kIoError, std::string("cannot make the lease pipe: ") + std::strerror(errno));
      return;
    }
    struct sigaction action {};
    action.sa_sigaction = on_lease_break;
    action.sa_flags = SA_SIGINFO | SA_RESTART;
    sigemptyset(&action.sa_mask);
    if (::sigaction(lease_signal(), &action, nullptr) != 0)
      installed =
          make_error(ErrorCode::kIoError, std::string("cannot handle lease breaks: ") + std::strerror(errno));
  });
  return installed;
}

std::int64_t nanoseconds(const timespec& t) {
  return std::int64_t{t.tv_sec} * 1'000'000'000 + t.tv_nsec;
}

FileIdentity from_stat(const struct stat& st) {
  return {st.st_dev, st.st_ino, static_cast<std::uint64_t>(st.st_size), nanoseconds(st.st_mtim),
          nanoseconds(st.st_ctim)};
}

}  // namespace

Result<FileIdentity> identify(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) != 0)
    return make_error(ErrorCode::kIoError, std::string("cannot stat: ") + std::strerror(errno));
  return from_stat(st);
}

Result<FileIdentity> identify(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    return make_error(errno == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIoError,
                      path.string() + ": " + std::strerror(errno));
  return from_stat(st);
}

Result<std::unique_ptr<FileLease>> FileLease::acquire(int fd) {
  if (Status s = install_handler(); !s) {
    ::close(fd);
    return s.take_error();
  }
  if (::fcntl(fd, F_SETSIG, lease_signal()) != 0 || ::fcntl(fd, F_SETLEASE, F_RDLCK) != 0) {
    const int e = errno;
    ::close(fd);
    // EAGAIN: the file is open for writing somewhere (a lease would conflict at once).
    if (e == EAGAIN || e == EWOULDBLOCK || e == EBUSY)
      return make_error(ErrorCode::kBusy, "the file is open for writing by another process");
    return make_error(ErrorCode::kUnsupported, std::string("no read lease: ") + std::strerror(e));
  }
  return std::unique_ptr<FileLease>(new FileLease(fd));
}

FileLease::~FileLease() {
  ::close(fd_);  // closing drops the lease too
}

bool FileLease::breaking() const {
  // While a break is pending, F_GETLEASE answers the type the lease must be lowered to.
  return held_ && ::fcntl(fd_, F_GETLEASE) == F_UNLCK;
}

void FileLease::release() {
  if (!held_) return;
  held_ = false;
  ::fcntl(fd_, F_SETLEASE, F_UNLCK);
}

int lease_break_pipe() {
  return break_pipe[0];
}

}  // namespace mtlod::core::io
