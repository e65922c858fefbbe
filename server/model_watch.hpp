// Keeps the served models in step with their files, on a thread of its own: hands a file over to a
// writer once the version mapped from it is retired (lease breaks), loads new versions when the
// files change (an inotify watch on their directories, on by default), on request (SIGHUP, the
// admin `reload` message) and, while a writer still holds a file open, every second until it is
// done.
#pragma once

#include <chrono>
#include <memory>

#include "server/model_registry.hpp"

namespace mtlod::server {

struct ModelWatchOptions {
  bool watch_files = true;  // inotify on the models' directories; off: SIGHUP or `reload` only
  // How long a file must be quiet after a change before it is loaded (one `cp` makes several events).
  std::chrono::milliseconds settle{100};
};

class ModelWatch {
 public:
  ModelWatch(ModelRegistry& models, ModelWatchOptions options);
  ~ModelWatch();  // stops the thread
  ModelWatch(const ModelWatch&) = delete;
  ModelWatch& operator=(const ModelWatch&) = delete;

  // Asks for a reload of every model (SIGHUP); returns at once, safe from any thread.
  void request_reload();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mtlod::server
