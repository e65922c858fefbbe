// Read leases on served files (fcntl F_SETLEASE, Linux): the kernel tells this process before any
// other process opens a leased file for writing or truncates it, and holds that writer back until
// the lease is released (or /proc/sys/fs/lease-break-time, 45 s by default, has passed). A server
// that maps a file can so stop reading the mapping before its pages change or vanish, instead of
// dying of SIGBUS on a truncated page or reading half-rewritten arrays.
//
// Notification is a signal the kernel queues with the leased descriptor in si_fd; a handler
// installed on first use forwards the descriptor's number through a pipe, so whoever polls
// lease_break_pipe() learns of breaks without running code in signal context.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <ctime>
#include <filesystem>
#include <memory>

#include "core/result.hpp"

namespace mtlod::core::io {

// What identifies a file's content without reading it: a rename over it changes the inode, an
// in-place rewrite its size, modification or change time.
struct FileIdentity {
  dev_t device = 0;
  ino_t inode = 0;
  std::uint64_t size = 0;
  std::int64_t mtime_ns = 0;
  std::int64_t ctime_ns = 0;

  bool operator==(const FileIdentity&) const = default;
};

// The identity of the file an open descriptor refers to; of a path (following links).
Result<FileIdentity> identify(int fd);
Result<FileIdentity> identify(const std::filesystem::path& path);

class FileLease {
 public:
  // Takes a read lease on `fd` (opened read-only), which the lease keeps and closes. Errors:
  // kUnavailable when another process has the file open for writing (try again once it closes),
  // kUnsupported when the file system or this process's rights give no leases (NFS, a file owned
  // by another user without CAP_LEASE).
  static Result<std::unique_ptr<FileLease>> acquire(int fd);
  ~FileLease();
  FileLease(const FileLease&) = delete;
  FileLease& operator=(const FileLease&) = delete;

  int fd() const { return fd_; }
  // Whether a writer is waiting for this lease (the kernel has started to break it).
  bool breaking() const;
  // Hands the file over: the waiting writer proceeds. The descriptor stays open.
  void release();

 private:
  explicit FileLease(int fd) : fd_(fd) {}
  int fd_;
  bool held_ = true;
};

// The read end of the pipe on which the descriptors of broken leases arrive, an int each
// (non-blocking; -1 before the first lease was taken).
int lease_break_pipe();

}  // namespace mtlod::core::io
