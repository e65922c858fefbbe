// The request pipeline behind the sockets (DESIGN.md §4): an extract request becomes grid mapping,
// distance transforms, labels, refinement of the session's cut and Draco encoding. Runs on worker
// threads; per-worker scratch memory lives in the engine, per-session state in SessionCut.
#pragma once

#include <cstdint>
#include <memory>
#include <variant>
#include <vector>

#include "protocol/errors.hpp"
#include "protocol/messages.hpp"
#include "protocol/replies.hpp"
#include "server/model_registry.hpp"

namespace mtlod::server {

// What a connection keeps between its extractions: the last cut, for dynamic refinement.
class SessionCut {
 public:
  SessionCut();
  ~SessionCut();
  SessionCut(SessionCut&&) noexcept;
  SessionCut& operator=(SessionCut&&) noexcept;
  struct State;
  std::unique_ptr<State> state;
};

struct ExtractOutcome {
  protocol::MeshReply reply;          // counts, max error and stage timings (queue and total left 0)
  std::vector<std::uint8_t> payload;  // Draco bytes
};

class Engine {
 public:
  explicit Engine(const ModelRegistry& models) : models_(models) {}

  // Thread-safe for distinct sessions; one call at a time per SessionCut.
  std::variant<ExtractOutcome, protocol::ProtocolError> extract(const protocol::Extract& request, SessionCut& session);

  const ModelRegistry& models() const { return models_; }

 private:
  const ModelRegistry& models_;
};

}  // namespace mtlod::server
