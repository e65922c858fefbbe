// The request pipeline (see engine.hpp): protocol request → core::ViewRequest → the five timed
// stages of core::ViewExtractor → Draco. Per-worker extractors and encoder are thread_local so no
// lock is taken per request and buffers are reused.
#include "server/engine.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <unordered_map>

#include "core/codec/cut_encoder.hpp"
#include "core/cut/cut_delta.hpp"
#include "core/view/scene_extract.hpp"
#include "core/view/view_extract.hpp"
#include "fmt/format.h"
#include "protocol/view_request.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::server {

struct ExtractionState::State {
  ModelPtr model;  // the version the session's cut comes from
  std::unique_ptr<core::cut::Refiner> refiner;
  core::view::ViewCache view;         // lets a gaze (same view, new foci) reuse the view's stages
  core::cut::CutDelta sent;           // the client's mesh, when it asked for delta replies
  std::uint64_t error_bound_cut = 0;  // triangles of the last cut, when it had no budget
  // A scene's: the models of its instances (their versions) and each instance's mesh on the client,
  // for delta replies.
  std::vector<ModelPtr> scene_models;
  std::vector<core::cut::CutDelta> scene_sent;
  core::view::SceneCache scene_view;  // lets a scene's gaze reuse its view's occupancy and transforms
};

ExtractionState::ExtractionState() = default;
ExtractionState::~ExtractionState() = default;
ExtractionState::ExtractionState(ExtractionState&&) noexcept = default;
ExtractionState& ExtractionState::operator=(ExtractionState&&) noexcept = default;

namespace {

using Clock = std::chrono::steady_clock;

std::uint64_t elapsed_us(Clock::time_point& since) {
  const auto now = Clock::now();
  const auto us = std::chrono::duration_cast<std::chrono::microseconds>(now - since).count();
  since = now;
  return static_cast<std::uint64_t>(us);
}

// The stages' times, each from the end of the one before.
struct StageClock final : core::view::StageObserver {
  explicit StageClock(protocol::StageTimings& timings) : timings(timings) {}
  void finished(core::view::Stage stage) override {
    static constexpr std::array<std::uint64_t protocol::StageTimings::*, core::view::kStageCount> kField{
        &protocol::StageTimings::map_us, &protocol::StageTimings::occupancy_us,
        &protocol::StageTimings::dt_us, &protocol::StageTimings::labels_us,
        &protocol::StageTimings::refine_us};
    timings.*kField[static_cast<std::size_t>(stage)] = elapsed_us(clock);
  }
  protocol::StageTimings& timings;
  Clock::time_point clock = Clock::now();
};

// A worker's extractor for one version of a model (which it reads): dropped once that version is
// no longer served.
struct CachedExtractor {
  std::weak_ptr<const Model> model;
  std::unique_ptr<core::view::ViewExtractor> extractor;
};

// The models a worker's scene extractor keeps state for, by Model::serial.
struct SceneModel {
  std::weak_ptr<const Model> model;
  const core::model::Mt* mt = nullptr;
};

// Per worker: one extractor per model version and one encoder, created on first use, reused after;
// one scene extractor for every scene.
struct Worker {
  std::unordered_map<std::uint64_t, CachedExtractor> extractors;  // by Model::serial
  core::codec::CutEncoder encoder;
  core::cut::CutMesh cut;
  std::vector<std::uint32_t> added, removed, added_ids, added_triangles;  // delta replies
  std::unique_ptr<core::view::SceneExtractor> scene;
  std::unordered_map<std::uint64_t, SceneModel> scene_models;
  std::vector<core::cut::CutMesh> scene_cuts;
  std::vector<std::uint8_t> part;  // one instance's payload
  std::uint64_t accounted = 0;     // scratch bytes last reported to the memory ceiling

  std::uint64_t scratch_bytes() const {
    std::uint64_t bytes = cut.triangles.capacity() * sizeof(std::uint32_t) + part.capacity();
    for (const auto& [serial, cached] : extractors) bytes += cached.extractor->memory_bytes();
    if (scene) bytes += scene->memory_bytes();
    for (const core::cut::CutMesh& c : scene_cuts)
      bytes += (c.triangles.capacity() + c.ids.capacity()) * sizeof(std::uint32_t);
    return bytes;
  }
  // Drops the scene extractor's state for models no longer served (before a new MT may come at a
  // freed one's address).
  void forget_scene_models() {
    std::erase_if(scene_models, [this](const auto& entry) {
      const ModelPtr model = entry.second.model.lock();
      if (model && !model->gate.retired()) return false;
      if (scene) scene->forget(*entry.second.mt);
      return true;
    });
  }
};

Worker& this_worker() {
  thread_local Worker worker;
  return worker;
}

// Bytes per grid cell of a worker's extractor and of a session; per cut triangle of a session's
// kept mesh and delta state. Arrays indexed by vertex, node or MT triangle (the allowed error, the
// cut's membership, the delta's sent set, the labels) are mapped zeroed and cost only the pages a
// request writes: bounded by the whole arrays (kPerVertex, kPerMtTriangle) and, as each vertex,
// node or triangle read touches at most a page of each, in practice far below that by
// kPagedPerCutTriangle per triangle of the cut (its neighbours' ids lie close together). Upper
// bounds with headroom, checked against the real figures by tests/server/memory_test.cpp.
constexpr std::uint64_t kScratchPerCell = 16, kSessionPerCell = 16, kSessionPerCutTriangle = 128;
// Hidden-surface coarsening: the depth image and its 3×3 bound per worker, the bound per session.
constexpr std::uint64_t kHiddenPerCell = 12;
constexpr std::uint64_t kPerVertex = 24, kPerMtTriangle = 1, kPagedPerCutTriangle = 2048;

// Encodes a cut for the client into `out`: whole, or for delta requests what changed since `sent`
// (the new triangles in cut order, their ids and the ids dropped; `delta` gets the counts). Returns
// the vertices encoded. On failure `sent` starts afresh: that change never reaches the client.
Result<std::uint64_t> encode_cut(const Model& model, const protocol::Extract& request, bool gaze,
                                 const core::cut::CutSpan& cut, std::span<const std::uint32_t> labels,
                                 core::cut::CutDelta& sent, Worker& worker, std::vector<std::uint8_t>& out,
                                 std::optional<protocol::MeshDelta>& delta) {
  const core::codec::EncodeOptions encoding =
      protocol::to_encode_options(request, {gaze, model.mt.has_colors(), model.bounds_min, model.bounds_max});
  std::span<const std::uint32_t> triangles = cut.triangles;
  if (request.delta) {
    const bool reset = sent.update(cut.ids, model.mt.triangle_count(), worker.added, worker.removed);
    core::cut::gather_triangles(cut.triangles, cut.ids, worker.added, worker.added_triangles,
                                worker.added_ids);
    triangles = worker.added_triangles;
    delta = protocol::MeshDelta{reset, 0, worker.added_ids.size(), worker.removed.size()};
  } else {
    sent.reset();  // the client replaces its mesh with this one
  }
  std::uint64_t vertices = 0;
  out.clear();
  if (!triangles.empty() || !request.delta) {  // a full reply always goes through the encoder's checks
    const core::codec::DracoInput input{model.mt.positions, model.mt.normals, labels, triangles,
                                        model.mt.colors};
    auto encoded = worker.encoder.encode(input, encoding, out);
    if (!encoded) {
      sent.reset();
      return encoded.take_error();
    }
    vertices = encoded->vertices;
  }
  if (delta) {
    delta->payload_bytes = out.size();
    protocol::append_delta_ids(worker.added_ids, worker.removed, out);
  }
  return vertices;
}

}  // namespace

std::uint64_t ExtractionState::memory_bytes() const {
  if (!state) return 0;
  std::uint64_t bytes = state->view.memory_bytes() + state->sent.memory_bytes();
  if (state->refiner) bytes += state->refiner->memory_bytes();
  for (const core::cut::CutDelta& sent : state->scene_sent) bytes += sent.memory_bytes();
  bytes += state->scene_view.memory_bytes();
  return bytes;
}

std::uint64_t Engine::estimate_bytes(const protocol::Extract& request, const ExtractionState* session) const {
  if (!request.instances.empty()) return estimate_scene_bytes(request);
  const ModelPtr model = models_.find(request.model);
  if (!model) return 0;
  const std::uint64_t cells = std::uint64_t{request.grid[0]} * request.grid[1];
  // A budget bounds the cut; without one it may be the whole input, or for a session whose last
  // cut of the model had no budget either, twice that cut.
  std::uint64_t cut = std::min<std::uint64_t>(model->input_triangles, request.budget.value_or(UINT64_MAX));
  if (!request.budget && session && session->state && session->state->model == model &&
      session->state->error_bound_cut > 0)
    cut = std::min(cut, 2 * session->state->error_bound_cut);
  cut = std::max<std::uint64_t>(cut, model->mt.root_triangle_count());  // never below the root
  const std::uint64_t paged =
      std::min(kPerVertex * model->mt.vertex_count() + kPerMtTriangle * model->mt.triangle_count(),
               kPagedPerCutTriangle * cut);
  const std::uint64_t per_cell =
      kScratchPerCell + kSessionPerCell + (request.criteria.hidden_factor != 1 ? kHiddenPerCell : 0);
  return per_cell * cells + kSessionPerCutTriangle * cut + paged;
}

std::uint64_t Engine::estimate_scene_bytes(const protocol::Extract& request) const {
  // The worker's grids (the shared ones and one instance's), and per instance its cut: its share of
  // the budget at most, else its model whole; per distinct model a refiner and field, paged as a
  // single model's are.
  const std::uint64_t cells = std::uint64_t{request.grid[0]} * request.grid[1];
  std::uint64_t cuts = 0, paged = 0;
  std::unordered_map<std::string_view, std::uint64_t> models;
  for (const protocol::Instance& instance : request.instances) {
    const ModelPtr model = models_.find(instance.model);
    if (!model) continue;
    cuts += model->input_triangles;
    const std::uint64_t whole =
        kPerVertex * model->mt.vertex_count() + kPerMtTriangle * model->mt.triangle_count();
    models.emplace(instance.model, whole);
  }
  if (request.budget) cuts = std::min<std::uint64_t>(cuts, *request.budget + request.instances.size() * 4096);
  for (const auto& [name, whole] : models) paged += std::min(whole, kPagedPerCutTriangle * cuts);
  return (2 * kScratchPerCell + kHiddenPerCell) * cells + kSessionPerCutTriangle * cuts + paged;
}

std::int64_t Engine::settle_worker_scratch() {
  Worker& worker = this_worker();
  worker.forget_scene_models();
  if (worker.scene && worker.scene->memory_bytes() > kRetainedScratchBytes) {
    worker.scene.reset();
    worker.scene_models.clear();
    worker.scene_cuts = {};
  }
  std::erase_if(worker.extractors, [](const auto& entry) {
    const CachedExtractor& cached = entry.second;
    if (cached.extractor->memory_bytes() > kRetainedScratchBytes) return true;
    // A version no session or registry holds any more, or one retired: its extractor is not reused.
    const ModelPtr model = cached.model.lock();
    return !model || model->gate.retired();
  });
  const std::uint64_t now = worker.scratch_bytes();
  const auto change = static_cast<std::int64_t>(now) - static_cast<std::int64_t>(worker.accounted);
  worker.accounted = now;
  return change;
}

ExtractResult Engine::extract(const protocol::Extract& request, bool gaze, ExtractionState& session) {
  if (!request.instances.empty()) return run_scene(request, gaze, session);
  const ModelPtr model = models_.find(request.model);
  if (!model)
    return protocol::ProtocolError{protocol::ErrorKind::kUnknownModel,
                                   fmt::format("no model named '{}'", request.model)};
  // Held until the cut is encoded: the version's file is not handed to a writer before then.
  const ModelGate::Pass pass = model->gate.enter();
  if (!pass) {
    return protocol::ProtocolError{
        protocol::ErrorKind::kUnavailable,
        fmt::format("model '{}' is being rewritten on disk; it is served again once the new file is loaded",
                    request.model)};
  }
  // Normals are always there: stored, or computed when the model was loaded.
  if (request.colors.value_or(false) && !model->mt.has_colors()) {
    return protocol::ProtocolError{protocol::ErrorKind::kBadRequest,
                                   fmt::format("model '{}' has no colours to send", request.model)};
  }
  return run(model, request, gaze, session);
}

ExtractResult Engine::run_scene(const protocol::Extract& request, bool gaze, ExtractionState& session) {
  // Every instance's model, each version entered once and held until the scene is encoded: the
  // whole scene is served or none of it.
  const std::size_t n = request.instances.size();
  std::vector<ModelPtr> models;
  std::vector<ModelGate::Pass> passes;
  passes.reserve(n);
  std::unordered_map<std::string_view, ModelPtr> by_name;
  for (std::size_t i = 0; i < n; ++i) {
    const std::string& name = request.instances[i].model;
    ModelPtr& model = by_name[name];
    if (!model) {
      model = models_.find(name);
      if (!model) {
        return protocol::ProtocolError{protocol::ErrorKind::kUnknownModel,
                                       fmt::format("scene.instances[{}]: no model named '{}'", i, name)};
      }
      passes.push_back(model->gate.enter());
      if (!passes.back()) {
        return protocol::ProtocolError{
            protocol::ErrorKind::kUnavailable,
            fmt::format("scene.instances[{}]: model '{}' is being rewritten on disk; it is served again once "
                        "the new file is loaded",
                        i, name)};
      }
      if (request.colors.value_or(false) && !model->mt.has_colors()) {
        return protocol::ProtocolError{
            protocol::ErrorKind::kBadRequest,
            fmt::format("scene.instances[{}]: model '{}' has no colours to send", i, name)};
      }
    }
    models.push_back(model);
  }

  Worker& worker = this_worker();
  worker.forget_scene_models();
  if (!worker.scene) worker.scene = std::make_unique<core::view::SceneExtractor>();
  std::vector<core::view::SceneInstance> instances(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Model& model = *models[i];
    worker.scene_models.try_emplace(model.serial, SceneModel{models[i], &model.mt});
    instances[i] = {&model.mt, model.occupancy.get(), protocol::to_glm(request.instances[i].matrix)};
  }
  core::view::SceneRequest scene{protocol::to_view_request(request, true), instances};
  scene.view.labels = false;

  if (!session.state) session.state = std::make_unique<ExtractionState::State>();
  ExtractionState::State& state = *session.state;
  // Another scene (other models or versions, in another order): every instance's mesh starts afresh.
  if (state.scene_models != models) {
    state.scene_models = models;
    state.scene_sent.clear();
    state.scene_sent.resize(n);
  }
  state.model.reset();  // a single model's session starts afresh after a scene
  state.refiner.reset();
  state.view.reset();
  state.sent.reset();

  ExtractOutcome outcome;
  StageClock stages(outcome.reply.timings);
  const Result<core::view::SceneStats> extracted =
      worker.scene->extract(scene, worker.scene_cuts, &stages, &state.scene_view);
  if (!extracted) {
    spdlog::error("scene: {}", extracted.error().message);
    state.scene_models.clear();
    state.scene_view.reset();
    return protocol::ProtocolError{
        protocol::ErrorKind::kInternal,
        fmt::format("a model of the scene is damaged: {}", extracted.error().message)};
  }
  protocol::MeshReply& reply = outcome.reply;
  reply.instances.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const core::cut::CutSpan cut = core::cut::CutSpan::of(worker.scene_cuts[i]);
    protocol::InstanceMesh& mesh = reply.instances[i];
    auto encoded =
        encode_cut(*models[i], request, gaze, cut, {}, state.scene_sent[i], worker, worker.part, mesh.delta);
    if (!encoded) {
      state.scene_models.clear();  // the client's meshes are no longer known
      return protocol::ProtocolError{protocol::ErrorKind::kInternal, encoded.error().message};
    }
    outcome.payload.insert(outcome.payload.end(), worker.part.begin(), worker.part.end());
    mesh.model = models[i]->name;
    mesh.triangles = cut.triangle_count();
    mesh.vertices = *encoded;
    mesh.max_error = cut.max_error;
    mesh.bytes = worker.part.size();
    reply.triangles += mesh.triangles;
    reply.vertices += mesh.vertices;
    reply.max_error = std::max(reply.max_error, mesh.max_error);
  }
  reply.timings.encode_us = elapsed_us(stages.clock);
  reply.within_budget = extracted->within_budget;
  reply.bytes = outcome.payload.size();
  reply.codec = request.codec.value_or(core::codec::Codec::kDraco);
  reply.session_bytes = session.memory_bytes();
  reply.scratch_bytes = worker.scratch_bytes();
  return outcome;
}

ExtractResult Engine::run(const ModelPtr& model, const protocol::Extract& request, bool gaze,
                          ExtractionState& session) {
  Worker& worker = this_worker();
  CachedExtractor& cached = worker.extractors[model->serial];
  if (!cached.extractor) {
    cached.model = model;
    cached.extractor = std::make_unique<core::view::ViewExtractor>(model->mt, *model->occupancy);
  }
  core::view::ViewExtractor* const extractor = cached.extractor.get();

  if (!session.state) session.state = std::make_unique<ExtractionState::State>();
  ExtractionState::State& state = *session.state;
  bool model_changed = false;
  if (state.model != model) {
    // Another model, or a new version of this one: the cut starts afresh from its root.
    model_changed = state.model && state.model->name == model->name;
    state.refiner = std::make_unique<core::cut::Refiner>(model->mt);
    state.model = model;
    state.view.reset();
    state.sent.reset();
  }

  const core::view::ViewRequest view = protocol::to_view_request(request, model->mt.has_normals());
  ExtractOutcome outcome;
  StageClock stages(outcome.reply.timings);
  // A gaze's cut is read in place from the session's refiner (no copy of the whole mesh).
  const Result<core::cut::CutSpan> extracted =
      extractor->extract(view, *state.refiner, worker.cut, &state.view, &stages);
  if (!extracted) {
    // A block of the model's mapped file failed its check on first use. Every request that reaches
    // it fails the same way; the others are served. The session starts again from nothing.
    spdlog::error("model {}: {}", model->name, extracted.error().message);
    session.state.reset();
    return protocol::ProtocolError{
        protocol::ErrorKind::kInternal,
        fmt::format("model '{}' is damaged: {}", model->name, extracted.error().message)};
  }
  const core::cut::CutSpan cut = *extracted;
  state.error_bound_cut = request.budget ? 0 : cut.triangle_count();

  auto encoded = encode_cut(*model, request, gaze, cut,
                            request.labels ? extractor->vertex_labels() : std::span<const std::uint32_t>(),
                            state.sent, worker, outcome.payload, outcome.reply.delta);
  if (!encoded) return protocol::ProtocolError{protocol::ErrorKind::kInternal, encoded.error().message};
  const std::uint64_t vertices = *encoded;
  outcome.reply.timings.encode_us = elapsed_us(stages.clock);

  outcome.reply.model = model->name;
  outcome.reply.model_version = model->version;
  outcome.reply.model_changed = model_changed;
  outcome.reply.triangles = cut.triangle_count();
  outcome.reply.vertices = vertices;
  outcome.reply.bytes = outcome.payload.size();
  outcome.reply.codec = request.codec.value_or(core::codec::Codec::kDraco);
  outcome.reply.max_error = cut.max_error;
  outcome.reply.session_bytes = session.memory_bytes();
  outcome.reply.scratch_bytes =
      extractor->memory_bytes() + worker.cut.triangles.capacity() * sizeof(std::uint32_t);
  return outcome;
}

}  // namespace mtlod::server
