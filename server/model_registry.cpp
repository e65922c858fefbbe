// The models a server holds (see model_registry.hpp).
#include "server/model_registry.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>

#include "core/build/mt_builder.hpp"
#include "core/build/vertex_normals.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/model/bounds.hpp"
#include "core/threads/thread_pool.hpp"
#include "fmt/format.h"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace fs = std::filesystem;

ModelGate::Pass::~Pass() {
  if (!gate_) return;
  std::lock_guard lock(gate_->mutex_);
  if (--gate_->passes_ == 0) gate_->idle_.notify_all();
}

ModelGate::Pass ModelGate::enter() const {
  std::lock_guard lock(mutex_);
  if (retired_) return Pass();
  ++passes_;
  return Pass(this);
}

void ModelGate::retire() const {
  std::unique_lock lock(mutex_);
  retired_ = true;
  idle_.wait(lock, [this] { return passes_ == 0; });
}

bool ModelGate::retired() const {
  std::lock_guard lock(mutex_);
  return retired_;
}

protocol::ModelSummary Model::summary() const {
  return {name,         mt.vertex_count(), input_triangles, mt.root_triangle_count(), mt.node_count(),
          memory_bytes, max_error,         version};
}

protocol::ModelInfoReply Model::info() const {
  protocol::ModelInfoReply r;
  r.model = summary();
  for (int c = 0; c < 3; ++c) r.bounds_min[c] = bounds_min[c], r.bounds_max[c] = bounds_max[c];
  r.min_error = min_error;
  r.normals = mt.has_normals();
  r.colors = mt.has_colors();
  return r;
}

namespace {

std::atomic<std::uint64_t> next_serial{1};

// A version of `name` from an MT, with its derived data. kCorrupt when a mapped block the coarse
// cuts read fails its check.
Result<std::shared_ptr<Model>> describe(std::string name, fs::path path, core::model::Mt mt) {
  auto model = std::make_shared<Model>();
  model->name = std::move(name);
  model->path = std::move(path);
  model->mt = std::move(mt);
  model->serial = next_serial++;
  const core::model::Mt& m = model->mt;
  const auto damaged = [&](const Error& e) {
    return make_error(ErrorCode::kCorrupt, fmt::format("{}: {}", model->path.string(), e.message));
  };
  // Every reply carries normals: an MT stored without them gets them now (12 bytes per vertex).
  Result<bool> computed = core::build::ensure_normals(model->mt);
  if (!computed) return damaged(computed.error());
  model->normals_computed = *computed;
  Result<std::unique_ptr<core::view::OccupancyLevels>> occupancy = core::view::OccupancyLevels::make(m);
  if (!occupancy) return damaged(occupancy.error());
  model->occupancy = std::move(*occupancy);
  model->memory_bytes = m.memory_bytes() + model->occupancy->memory_bytes();
  model->bounds_min = m.bounds.lo;
  model->bounds_max = m.bounds.hi;
  model->input_triangles = m.input_triangles;
  // Nodes are sorted by decreasing error: node 1 has the largest, the last positive the smallest.
  const auto errors = m.node_error.subspan(std::min<std::size_t>(1, m.node_count()));
  model->min_error = INFINITY;
  if (!errors.empty()) {
    model->max_error = errors.front();
    const auto positive = std::partition_point(errors.begin(), errors.end(), [](float e) { return e > 0; });
    if (positive != errors.begin()) model->min_error = *(positive - 1);
  }
  if (!std::isfinite(model->min_error)) model->min_error = 0;
  return model;
}

// Loads `path` as version `version` of `name`: mapped under a lease where it can be.
Result<std::shared_ptr<Model>> load(const std::string& name, const fs::path& path, std::uint64_t version) {
  MTLOD_TRY(core::io::ServedMt served, core::io::open_served_mt(path));
  MTLOD_TRY(std::shared_ptr<Model> model, describe(name, path, std::move(served.mt)));
  model->version = version;
  model->file = served.identity;
  model->lease = std::move(served.lease);
  model->read_whole_because = std::move(served.read_whole_because);
  if (model->normals_computed) {
    spdlog::warn(
        "{}: stored without normals: computed from its surface ({:.1f} MiB in memory); "
        "mtlod-build stores them in the file",
        path.string(), 12.0 * static_cast<double>(model->mt.vertex_count()) / 1048576.0);
  }
  if (!model->read_whole_because.empty()) {
    spdlog::warn("{}: read into memory ({}): changes to the file reach the server only by a reload",
                 path.string(), model->read_whole_because);
  }
  if (!model->mt.vertices_in_node_order()) {
    spdlog::warn(
        "{}: written by an older mtlod-build (vertices not in node order); it is served as it is, "
        "and rebuilt with mtlod-build it refines about 10 % faster",
        path.string());
  }
  return model;
}

struct Source {
  std::string name;
  fs::path path;
};

// How long a file handed over to a writer is left alone unless it reports a change: a writer that
// opens without waiting (coreutils truncate uses O_NONBLOCK) fails once while the lease breaks, and
// its second try must not meet a new lease.
constexpr auto kHandOverGrace = std::chrono::seconds(5);

}  // namespace

struct ModelRegistry::Impl {
  mutable std::mutex mutex;      // everything below but reload_mutex
  std::vector<ModelPtr> models;  // sorted by name
  std::vector<fs::path> directories;
  std::vector<Source> files;  // named files and the MTs built from meshes
  // Names to load again without a file event: a writer held the file open (at once), or its
  // version was handed over to one (after kHandOverGrace, as the writer's close usually comes first).
  std::map<std::string, std::chrono::steady_clock::time_point> pending;
  std::map<std::string, std::uint64_t> last_version;  // versions keep counting across a removal
  std::vector<std::weak_ptr<const Model>> leased;     // every live version holding a lease
  std::uint64_t reloads = 0;
  std::mutex reload_mutex;  // one reload at a time

  ModelPtr find_locked(std::string_view name) const {
    const auto it = std::lower_bound(models.begin(), models.end(), name,
                                     [](const ModelPtr& m, std::string_view n) { return m->name < n; });
    return it != models.end() && (*it)->name == name ? *it : nullptr;
  }
  // Serves `model` in place of any version of its name.
  void publish(ModelPtr model) {
    std::lock_guard lock(mutex);
    if (model->lease) leased.push_back(model);
    std::erase_if(leased, [](const std::weak_ptr<const Model>& m) { return m.expired(); });
    const auto it = std::lower_bound(models.begin(), models.end(), model->name,
                                     [](const ModelPtr& m, const std::string& n) { return m->name < n; });
    if (it != models.end() && (*it)->name == model->name) {
      *it = std::move(model);
    } else {
      models.insert(it, std::move(model));
    }
  }
  void remove(const std::string& name) {
    std::lock_guard lock(mutex);
    std::erase_if(models, [&](const ModelPtr& m) { return m->name == name; });
  }
  // Every (name, path) the sources name now: listed files, then each directory's .mt files.
  std::map<std::string, fs::path> candidates() const {
    std::map<std::string, fs::path> out;
    std::vector<fs::path> dirs;
    {
      std::lock_guard lock(mutex);
      for (const Source& s : files) out.emplace(s.name, s.path);
      dirs = directories;
    }
    for (const fs::path& dir : dirs) {
      std::error_code ec;
      for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        if (it->path().extension() == ".mt") out.emplace(it->path().stem().string(), it->path());
      }
    }
    return out;
  }
  Status add(std::shared_ptr<Model> model, const fs::path& path) {
    if (find_locked_guarded(model->name))
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("{}: a model named '{}' is already loaded", path.string(), model->name));
    {
      std::lock_guard lock(mutex);
      last_version[model->name] = model->version;
    }
    publish(std::move(model));
    return Ok{};
  }
  ModelPtr find_locked_guarded(std::string_view name) const {
    std::lock_guard lock(mutex);
    return find_locked(name);
  }

  // The file is gone or not a regular file: stops serving the name.
  void drop(const std::string& name, const fs::path& path, protocol::ModelReload& outcome) {
    std::error_code ec;
    outcome.change = "removed";
    outcome.version = 0;
    outcome.message =
        fs::exists(path, ec) ? path.string() + " is not a regular file" : path.string() + " is gone";
    remove(name);
    {
      std::lock_guard lock(mutex);
      pending.erase(name);
    }
    spdlog::warn("model {}: no longer served: {}", name, outcome.message);
  }
  // The new file did not load: retried later when a writer holds it, else reported.
  void reject(const std::string& name, const ModelPtr& current, const Error& error,
              protocol::ModelReload& outcome) {
    outcome.message = error.message;
    if (error.code == ErrorCode::kBusy) {
      // A writer still has it open: the next reload (its close, or the retry timer) tries again.
      outcome.change = "pending";
      std::lock_guard lock(mutex);
      pending[name] = std::chrono::steady_clock::now();
      return;
    }
    outcome.change = "failed";
    {
      std::lock_guard lock(mutex);
      pending.erase(name);
    }
    if (current && current->gate.retired()) {
      // Its bytes were overwritten in place: nothing is left to serve until a valid file comes.
      remove(name);
      outcome.version = 0;
      spdlog::error("model {}: not served: version {} was rewritten in place and {}", name, current->version,
                    outcome.message);
    } else if (current) {
      spdlog::error("model {}: version {} keeps serving: the new file is rejected: {}", name,
                    current->version, outcome.message);
    } else {
      spdlog::error("model {}: not loaded: {}", name, outcome.message);
    }
  }
  // The new version loaded: serves it in place of the current one, if any.
  void serve(const std::string& name, const fs::path& path, const std::shared_ptr<Model>& model,
             double load_ms, bool replaced, protocol::ModelReload& outcome) {
    outcome.change = replaced ? "replaced" : "loaded";
    outcome.version = model->version;
    spdlog::info(
        "model {}: version {} serving from {} ({}, {} input triangles, {} root triangles; loaded in {:.1f} "
        "ms)",
        name, model->version, path.string(), model->lease ? "mapped under a read lease" : "in memory",
        model->input_triangles, model->mt.root_triangle_count(), load_ms);
    publish(model);
    {
      std::lock_guard lock(mutex);
      pending.erase(name);
      last_version[name] = model->version;
      ++reloads;
    }
  }
};

ModelRegistry::ModelRegistry() : impl_(std::make_unique<Impl>()) {}
ModelRegistry::~ModelRegistry() = default;

Status ModelRegistry::add_file(const fs::path& path) {
  const std::string name = path.stem().string();
  MTLOD_TRY(std::shared_ptr<Model> model, load(name, path, 1));
  MTLOD_RETURN_IF_ERROR(impl_->add(std::move(model), path));
  std::lock_guard lock(impl_->mutex);
  impl_->files.push_back({name, path});
  return Ok{};
}

Status ModelRegistry::add_directory(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    return make_error(ErrorCode::kNotFound, fmt::format("{}: not a directory", dir.string()));
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (entry.path().extension() == ".mt") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) return make_error(ErrorCode::kNotFound, fmt::format("{}: no .mt files", dir.string()));
  // A file that does not load now (being written, damaged, a directory) does not keep the others
  // from being served: it is loaded like any other once it changes, as a replica restarted while
  // an operator replaces a model must still serve the rest.
  for (const fs::path& f : files) {
    const std::string name = f.stem().string();
    auto model = load(name, f, 1);
    if (!model) {
      spdlog::error("model {}: not loaded: {}", name, model.error().message);
      std::lock_guard lock(impl_->mutex);
      if (model.error().code == ErrorCode::kBusy) impl_->pending[name] = std::chrono::steady_clock::now();
      continue;
    }
    MTLOD_RETURN_IF_ERROR(impl_->add(std::move(*model), f));
  }
  std::lock_guard lock(impl_->mutex);
  impl_->directories.push_back(dir);
  return Ok{};
}

Status ModelRegistry::add_mesh(const fs::path& mesh, const fs::path& mt_path) {
  const std::string name = mt_path.stem().string();
  std::error_code ec;
  const bool fresh = fs::exists(mt_path, ec) && fs::exists(mesh, ec) &&
                     fs::last_write_time(mt_path, ec) >= fs::last_write_time(mesh, ec);
  std::shared_ptr<Model> model;
  if (fresh) {
    // A cached file an older build wrote is built again: that takes seconds, and it is built once.
    auto cached = load(name, mt_path, 1);
    if (cached && (*cached)->mt.vertices_in_node_order() && !(*cached)->normals_computed)
      model = std::move(*cached);
    if (!model) {
      spdlog::info("{}: {}; building it again from {}", mt_path.string(),
                   !cached ? cached.error().message
                   : !(*cached)->mt.vertices_in_node_order()
                       ? "written by an older mtlod-build (vertices not in node order)"
                       : "written by an older mtlod-build (no normals)",
                   mesh.string());
    }
  }
  if (!model) {
    core::model::Mt built;
    {  // the input mesh and the build's threads are released before the model is described
      const auto start = std::chrono::steady_clock::now();
      MTLOD_TRY(core::io::LoadedMesh loaded, core::io::load_mesh(mesh));
      core::build::BuildStats stats;
      // Built before the server serves anyone: every core helps (the MT is the same as serial).
      core::threads::ThreadPool pool;
      core::build::BuildOptions options;
      pool.attach(options);
      MTLOD_TRY(core::model::Mt mt, core::build::build_mt(loaded.mesh, options, &stats));
      if (!stats.normals_given) {
        spdlog::info("{}: no normals: computed from its surface (angle-weighted)", mesh.string());
      } else if (stats.normals_computed > 0) {
        spdlog::warn("{}: {} of {} vertex normals are NaN or zero-length: computed from the surface",
                     mesh.string(), stats.normals_computed, loaded.mesh.vertex_count());
      }
      fs::create_directories(mt_path.parent_path(), ec);
      MTLOD_TRY(std::uint64_t bytes, core::io::write_mt_file(mt_path, mt));
      spdlog::info("built {} from {}: {} triangles → {} root triangles, {} nodes, {:.1f} MiB, {:.2f} s",
                   mt_path.string(), mesh.string(), stats.input_triangles, stats.root_triangles, stats.nodes,
                   bytes / 1048576.0,
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      built = std::move(mt);
    }
    // The MT just written is served from memory, not read back; a later change to its file is
    // loaded like any other.
    MTLOD_TRY(model, describe(name, mt_path, std::move(built)));
    if (auto id = core::io::identify(mt_path)) model->file = *id;
  }
  MTLOD_RETURN_IF_ERROR(impl_->add(std::move(model), mt_path));
  std::lock_guard lock(impl_->mutex);
  impl_->files.push_back({name, mt_path});
  return Ok{};
}

ModelPtr ModelRegistry::find(std::string_view name) const {
  return impl_->find_locked_guarded(name);
}

std::vector<ModelPtr> ModelRegistry::models() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->models;
}

std::vector<protocol::ModelReload> ModelRegistry::reload(const std::vector<std::string>& only) {
  std::lock_guard reloading(impl_->reload_mutex);
  std::map<std::string, fs::path> candidates = impl_->candidates();
  for (const ModelPtr& m : models()) candidates.emplace(m->name, m->path);  // gone ones are dropped
  std::vector<protocol::ModelReload> outcomes;
  for (const auto& [name, path] : candidates) {
    if (!only.empty() && std::find(only.begin(), only.end(), name) == only.end()) continue;
    const ModelPtr current = find(name);
    protocol::ModelReload outcome{name, "unchanged", current ? current->version : 0, ""};
    std::error_code ec;
    const bool regular = fs::is_regular_file(path, ec);
    auto identity = regular ? core::io::identify(path) : Result<core::io::FileIdentity>(Error{});
    if (!identity) {
      if (!current) continue;
      impl_->drop(name, path, outcome);
      outcomes.push_back(std::move(outcome));
      continue;
    }
    if (current && !current->gate.retired() && current->file == *identity) {
      std::lock_guard lock(impl_->mutex);
      impl_->pending.erase(name);
      outcomes.push_back(std::move(outcome));
      continue;
    }
    std::uint64_t version = 1;
    {
      std::lock_guard lock(impl_->mutex);
      version = impl_->last_version[name] + 1;
    }
    const auto load_start = std::chrono::steady_clock::now();
    auto loaded = load(name, path, version);
    const double load_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - load_start).count();
    if (!loaded) {
      impl_->reject(name, current, loaded.error(), outcome);
      outcomes.push_back(std::move(outcome));
      continue;
    }
    impl_->serve(name, path, *loaded, load_ms, current != nullptr, outcome);
    outcomes.push_back(std::move(outcome));
  }
  return outcomes;
}

std::vector<std::string> ModelRegistry::hand_over_leases(int fd) {
  std::vector<ModelPtr> breaking;
  {
    std::lock_guard lock(impl_->mutex);
    std::erase_if(impl_->leased, [](const std::weak_ptr<const Model>& m) { return m.expired(); });
    for (const auto& weak : impl_->leased) {
      ModelPtr m = weak.lock();
      if (m && m->lease && (fd < 0 || m->lease->fd() == fd) && m->lease->breaking()) breaking.push_back(m);
    }
  }
  std::vector<std::string> names;
  for (const ModelPtr& m : breaking) {
    const auto start = std::chrono::steady_clock::now();
    m->gate.retire();  // extractions reading the mapping finish first
    m->lease->release();
    spdlog::warn(
        "model {}: version {} stops serving: another process opens {} for writing; the file was handed "
        "over after {:.1f} ms, and a new version is loaded once it is written",
        m->name, m->version, m->path.string(),
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    names.push_back(m->name);
    std::lock_guard lock(impl_->mutex);
    impl_->pending[m->name] = std::chrono::steady_clock::now() + kHandOverGrace;
  }
  return names;
}

std::vector<std::string> ModelRegistry::due_pending() const {
  const auto now = std::chrono::steady_clock::now();
  std::lock_guard lock(impl_->mutex);
  std::vector<std::string> names;
  for (const auto& [name, due] : impl_->pending) {
    if (due <= now) names.push_back(name);
  }
  return names;
}

std::vector<fs::path> ModelRegistry::watched_directories() const {
  std::lock_guard lock(impl_->mutex);
  std::vector<fs::path> dirs = impl_->directories;
  for (const Source& s : impl_->files) {
    fs::path parent = s.path.parent_path();
    if (parent.empty()) parent = ".";
    dirs.push_back(parent);
  }
  std::sort(dirs.begin(), dirs.end());
  dirs.erase(std::unique(dirs.begin(), dirs.end()), dirs.end());
  return dirs;
}

std::optional<std::string> ModelRegistry::model_for(const fs::path& dir, const std::string& file_name) const {
  std::lock_guard lock(impl_->mutex);
  const fs::path path = dir / file_name;
  for (const Source& s : impl_->files) {
    fs::path parent = s.path.parent_path();
    if (parent.empty()) parent = ".";
    if (parent == dir && s.path.filename() == file_name) return s.name;
  }
  if (path.extension() == ".mt" &&
      std::find(impl_->directories.begin(), impl_->directories.end(), dir) != impl_->directories.end())
    return path.stem().string();
  return std::nullopt;
}

std::uint64_t ModelRegistry::reloads() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->reloads;
}

}  // namespace mtlod::server
