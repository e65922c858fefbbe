// The pipeline behind the sockets (core/ARCHITECTURE.md §4): an extract becomes grid mapping,
// distance transforms, labels, refinement of the session's cut and Draco encoding. Runs on worker
// threads; per-worker scratch memory lives in the engine, per-session state in ExtractionState.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/result.hpp"
#include "protocol/errors.hpp"
#include "protocol/messages.hpp"
#include "protocol/replies.hpp"
#include "server/model_registry.hpp"

namespace mtlod::server {

// What a connection keeps between its extractions: the last cut, for dynamic refinement.
class ExtractionState {
 public:
  ExtractionState();
  ~ExtractionState();
  ExtractionState(ExtractionState&&) noexcept;
  ExtractionState& operator=(ExtractionState&&) noexcept;
  // Bytes the session holds (its refiner, kept view and delta state).
  std::uint64_t memory_bytes() const;
  struct State;
  std::unique_ptr<State> state;
};

struct ExtractOutcome {
  protocol::MeshReply reply;          // counts, max error and stage timings (queue and total left 0)
  std::vector<std::uint8_t> payload;  // the encoded mesh (the reply's codec)
};
using ExtractResult = Result<ExtractOutcome, protocol::ProtocolError>;

class Engine {
 public:
  explicit Engine(const ModelRegistry& models) : models_(models) {}

  // Thread-safe for distinct sessions; one call at a time per ExtractionState.
  // gaze: the request comes from a gaze update (it picks the gaze defaults, e.g. Draco's method).
  ExtractResult extract(const protocol::Extract& request, bool gaze, ExtractionState& session);

  // The memory `request` may add: scratch for its grid on the worker that runs it, and a
  // session's state for the largest cut it may ask for: its budget, else the whole model. With
  // `session` (the one it will run in) and no budget, a session whose last cut of the model had no
  // budget either is taken to move to at most twice that cut, as views and gazes move cuts: an
  // estimate then, not a bound (the server replaces the reservation by the real figure once the
  // work has run). Zero for an unknown model.
  std::uint64_t estimate_bytes(const protocol::Extract& request,
                               const ExtractionState* session = nullptr) const;

  // On a worker thread after its extraction: by how much this worker's scratch grew (or shrank).
  // Scratch above kRetainedScratchBytes for one model (a huge grid) is freed here, not kept.
  static std::int64_t settle_worker_scratch();
  static constexpr std::uint64_t kRetainedScratchBytes = std::uint64_t{64} << 20;

  const ModelRegistry& models() const { return models_; }

 private:
  ExtractResult run(const ModelPtr& model, const protocol::Extract& request, bool gaze,
                    ExtractionState& session);
  // A scene (request.instances): one extraction of every instance, one mesh each in the payload.
  ExtractResult run_scene(const protocol::Extract& request, bool gaze, ExtractionState& session);
  std::uint64_t estimate_scene_bytes(const protocol::Extract& request) const;
  const ModelRegistry& models_;
};

}  // namespace mtlod::server
