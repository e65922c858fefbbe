// The models a server holds (see model_registry.hpp).
#include "server/model_registry.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/bounds.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/mt_builder.hpp"
#include "core/threads/thread_pool.hpp"
#include "fmt/format.h"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace fs = std::filesystem;

protocol::ModelSummary Model::summary() const {
  return {name,         mt.vertex_count(), input_triangles, mt.root_triangle_count(), mt.node_count(),
          memory_bytes, max_error};
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

std::unique_ptr<Model> describe(std::string name, fs::path path, core::Mt mt) {
  auto model = std::make_unique<Model>();
  model->name = std::move(name);
  model->path = std::move(path);
  model->mt = std::move(mt);
  const core::Mt& m = model->mt;
  model->occupancy = std::make_unique<core::OccupancyLevels>(m);
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

}  // namespace

Status ModelRegistry::add_file(const fs::path& path) {
  MTLOD_TRY(core::Mt mt, core::io::read_mt_file(path));
  if (!mt.vertices_in_node_order()) {
    spdlog::warn(
        "{}: written by an older mtlod-build (vertices not in node order); it is served as it is, "
        "and rebuilt with mtlod-build it refines about 10 % faster",
        path.string());
  }
  return add(path, std::move(mt));
}

Status ModelRegistry::add(const fs::path& path, core::Mt mt) {
  const std::string name = path.stem().string();
  if (find(name))
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("{}: a model named '{}' is already loaded", path.string(), name));
  try {
    models_.push_back(describe(name, path, std::move(mt)));
  } catch (const core::CorruptMt& e) {
    // A mapped file's block failed its check while the coarse cuts were read.
    return make_error(ErrorCode::kCorrupt, fmt::format("{}: {}", path.string(), e.what()));
  }
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
  for (const fs::path& f : files) MTLOD_RETURN_IF_ERROR(add_file(f));
  if (files.empty()) return make_error(ErrorCode::kNotFound, fmt::format("{}: no .mt files", dir.string()));
  return Ok{};
}

Status ModelRegistry::add_mesh(const fs::path& mesh, const fs::path& mt_path) {
  std::error_code ec;
  const bool fresh = fs::exists(mt_path, ec) && fs::exists(mesh, ec) &&
                     fs::last_write_time(mt_path, ec) >= fs::last_write_time(mesh, ec);
  if (fresh) {
    // A cached file an older build wrote is built again: that takes seconds, and it is built once.
    auto cached = core::io::read_mt_file(mt_path);
    if (cached && cached->vertices_in_node_order()) return add(mt_path, std::move(*cached));
    spdlog::info(
        "{}: {}; building it again from {}", mt_path.string(),
        cached ? "written by an older mtlod-build (vertices not in node order)" : cached.error().message,
        mesh.string());
  }
  core::Mt built;
  {  // the input mesh and the build's threads are released before the model is described
    const auto start = std::chrono::steady_clock::now();
    MTLOD_TRY(core::io::LoadedMesh loaded, core::io::load_mesh(mesh));
    core::BuildStats stats;
    // Built before the server serves anyone: every core helps (the MT is the same as serial).
    core::ThreadPool pool;
    core::BuildOptions options;
    pool.attach(options);
    MTLOD_TRY(core::Mt mt, core::build_mt(loaded.mesh, options, &stats));
    fs::create_directories(mt_path.parent_path(), ec);
    MTLOD_TRY(std::uint64_t bytes, core::io::write_mt_file(mt_path, mt));
    spdlog::info("built {} from {}: {} triangles → {} root triangles, {} nodes, {:.1f} MiB, {:.2f} s",
                 mt_path.string(), mesh.string(), stats.input_triangles, stats.root_triangles, stats.nodes,
                 bytes / 1048576.0,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    built = std::move(mt);
  }
  return add(mt_path, std::move(built));  // the MT just written, not read back
}

const Model* ModelRegistry::find(std::string_view name) const {
  for (const auto& m : models_) {
    if (m->name == name) return m.get();
  }
  return nullptr;
}

}  // namespace mtlod::server
