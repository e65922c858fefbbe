// The models' watcher (see model_watch.hpp): one thread polling the lease-break pipe, an inotify
// descriptor and its own wake-up pipe.
#include "server/model_watch.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/inotify.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "core/io/file_lease.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kRetryEvery = std::chrono::seconds(1);
constexpr char kReloadAll = 'R', kQuit = 'Q';

}  // namespace

struct ModelWatch::Impl {
  ModelRegistry& models;
  ModelWatchOptions options;
  int wake[2] = {-1, -1};
  int inotify = -1;
  std::map<int, std::filesystem::path> watched;  // inotify watch descriptor → directory
  std::set<std::string> dirty;                   // names changed on disk, loaded once quiet
  Clock::time_point dirty_until{};
  std::thread thread;

  Impl(ModelRegistry& m, ModelWatchOptions o) : models(m), options(o) {}

  void start_watching() {
    if (!options.watch_files) return;
    inotify = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (inotify < 0) {
      spdlog::warn("no file-system watch on the models ({}): reload with SIGHUP", std::strerror(errno));
      return;
    }
    for (const std::filesystem::path& dir : models.watched_directories()) {
      const int wd = ::inotify_add_watch(
          inotify, dir.c_str(),
          IN_CLOSE_WRITE | IN_MOVED_TO | IN_MOVED_FROM | IN_CREATE | IN_DELETE | IN_ATTRIB);
      if (wd < 0) {
        spdlog::warn("cannot watch {} ({}): reload its models with SIGHUP", dir.string(),
                     std::strerror(errno));
        continue;
      }
      watched[wd] = dir;
      spdlog::debug("watching {} for model changes", dir.string());
    }
  }

  void read_events() {
    alignas(inotify_event) char buffer[16384];
    for (;;) {
      const ssize_t n = ::read(inotify, buffer, sizeof buffer);
      if (n <= 0) return;
      for (ssize_t at = 0; at < n;) {
        const auto* event = reinterpret_cast<const inotify_event*>(buffer + at);
        at += static_cast<ssize_t>(sizeof(inotify_event) + event->len);
        if (event->mask & IN_Q_OVERFLOW) {
          dirty.insert("");  // events were lost: reload everything
        } else if (event->len > 0) {
          const auto dir = watched.find(event->wd);
          if (dir == watched.end()) continue;
          if (auto name = models.model_for(dir->second, event->name)) dirty.insert(*name);
        }
        dirty_until = Clock::now() + options.settle;
      }
    }
  }

  // Lease breaks: each retired version's file goes to its writer; its new content is loaded later.
  void read_lease_breaks(int pipe) {
    std::array<int, 64> fds{};
    for (;;) {
      const ssize_t n = ::read(pipe, fds.data(), sizeof fds);
      if (n <= 0) return;
      for (ssize_t i = 0; i < n / static_cast<ssize_t>(sizeof(int)); ++i) models.hand_over_leases(fds[i]);
    }
  }

  // The registry logs each outcome that matters at info level or above; here only what set it off.
  void reload(std::vector<std::string> names, const char* why) {
    if (std::find(names.begin(), names.end(), "") != names.end()) names.clear();
    const auto outcomes = models.reload(names);
    for (const auto& o : outcomes) {
      if (o.change != "unchanged" && o.change != "pending")
        spdlog::debug("reload ({}): {} {}", why, o.name, o.change);
    }
  }

  void run() {
    auto next_retry = Clock::now() + kRetryEvery;
    for (;;) {
      const int lease_pipe = core::io::lease_break_pipe();
      std::array<pollfd, 3> fds{{{wake[0], POLLIN, 0}, {lease_pipe, POLLIN, 0}, {inotify, POLLIN, 0}}};
      auto until = next_retry;
      if (!dirty.empty()) until = std::min(until, dirty_until);
      const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now()).count();
      ::poll(fds.data(), fds.size(), static_cast<int>(std::max<std::int64_t>(0, wait)));
      bool reload_all = false;
      if (fds[0].revents & POLLIN) {
        char commands[64];
        const ssize_t n = ::read(wake[0], commands, sizeof commands);
        for (ssize_t i = 0; i < n; ++i) {
          if (commands[i] == kQuit) return;
          if (commands[i] == kReloadAll) reload_all = true;
        }
      }
      if (lease_pipe >= 0 && (fds[1].revents & POLLIN)) read_lease_breaks(lease_pipe);
      if (inotify >= 0 && (fds[2].revents & POLLIN)) read_events();
      const auto now = Clock::now();
      if (reload_all) {
        reload({""}, "requested");
        dirty.clear();
      } else if (!dirty.empty() && now >= dirty_until) {
        reload({dirty.begin(), dirty.end()}, "file change");
        dirty.clear();
      }
      if (now >= next_retry) {
        next_retry = now + kRetryEvery;
        // A notice lost to a full pipe still hands its file over; a file a writer held open, or one
        // handed over, is tried again until it loads.
        models.hand_over_leases(-1);
        if (auto names = models.due_pending(); !names.empty()) reload(std::move(names), "retry");
      }
    }
  }
};

ModelWatch::ModelWatch(ModelRegistry& models, ModelWatchOptions options)
    : impl_(std::make_unique<Impl>(models, options)) {
  if (::pipe2(impl_->wake, O_CLOEXEC | O_NONBLOCK) != 0) {
    spdlog::error("model watch: cannot make its pipe: {}", std::strerror(errno));
    return;
  }
  impl_->start_watching();
  impl_->thread = std::thread([this] { impl_->run(); });
}

ModelWatch::~ModelWatch() {
  if (impl_->thread.joinable()) {
    const char quit = kQuit;
    [[maybe_unused]] const ssize_t n = ::write(impl_->wake[1], &quit, 1);
    impl_->thread.join();
  }
  for (int fd : {impl_->wake[0], impl_->wake[1], impl_->inotify}) {
    if (fd >= 0) ::close(fd);
  }
}

void ModelWatch::request_reload() {
  const char command = kReloadAll;
  [[maybe_unused]] const ssize_t n = ::write(impl_->wake[1], &command, 1);
}

}  // namespace mtlod::server
