// MTs of the test meshes, built once per test binary and shared by its tests (the builder is the
// slow part). Real scans come from the shared meshes folder; null when a file is absent, so tests
// can GTEST_SKIP.
#pragma once

#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/build/large_build.hpp"
#include "core/build/mt_builder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "tests/core/cut_validator.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::test {

struct MtCase {
  core::model::Mesh mesh;
  core::model::Mt mt;
  CutReference reference;
  // Collapses of the builder's topology phase and their smallest error (core::BuildStats).
  std::size_t topology_collapses = 0;
  float topology_error = std::numeric_limits<float>::infinity();
  std::size_t stacking_collapses = 0;  // of them, those that may stack two faces
  float stacking_error = std::numeric_limits<float>::infinity();
  // From core::BuildStats or core::io::LargeBuildStats.
  template <class Stats>
  void set_topology(const Stats& stats) {
    topology_collapses = stats.topology_collapses;
    topology_error = stats.topology_error;
    stacking_collapses = stats.stacking_collapses;
    stacking_error = stats.stacking_error;
    reference.coarse_topology_changes = stats.topology_collapses > 0;
    reference.stacked_faces = stats.stacking_collapses > 0;
  }
};

// The same mesh with its vertices numbered as the MT numbers them (ids[v]: MT id of input vertex v),
// so cuts can be compared with it id for id.
inline void renumber_like_mt(core::model::Mesh& mesh, const std::vector<std::uint32_t>& ids) {
  const auto renumber = [&](auto& values) {
    if (values.empty()) return;
    auto by_id = values;
    for (std::size_t v = 0; v < ids.size(); ++v)
      for (int k = 0; k < 3; ++k) by_id[3 * std::size_t{ids[v]} + k] = values[3 * v + k];
    values = std::move(by_id);
  };
  renumber(mesh.positions);
  renumber(mesh.normals);
  renumber(mesh.colors);
  for (std::uint32_t& v : mesh.triangles) v = ids[v];
}

// Builds the MT of mesh and renumbers mesh like it.
inline Result<core::model::Mt> build_mt_renumbering(core::model::Mesh& mesh,
                                                    const core::build::BuildOptions& options = {},
                                                    core::build::BuildStats* stats = nullptr) {
  std::vector<std::uint32_t> ids;
  auto mt = core::build::build_mt(mesh, options, stats, &ids);
  if (mt.ok()) renumber_like_mt(mesh, ids);
  return mt;
}

// The input mesh is kept numbered as the MT numbers its vertices.
inline const MtCase* build_case(const std::string& key, core::model::Mesh mesh,
                                const core::build::BuildOptions& options = {}) {
  static std::map<std::string, std::unique_ptr<MtCase>> cache;
  auto& slot = cache[key];
  if (!slot) {
    auto c = std::make_unique<MtCase>();
    c->mesh = std::move(mesh);
    core::build::BuildStats stats;
    auto mt = build_mt_renumbering(c->mesh, options, &stats);
    EXPECT_TRUE(mt.ok()) << key << ": " << (mt.ok() ? "" : mt.error().message);
    if (!mt.ok()) return nullptr;
    c->mt = std::move(mt).value();
    c->reference = make_reference(c->mesh);
    c->set_topology(stats);
    slot = std::move(c);
  }
  return slot.get();
}

// The same mesh built out of core (core/build/large_build.hpp) in leaf blocks of block_triangles, through
// a PLY file and an .mt file; mesh is kept numbered as the MT numbers its vertices.
inline const MtCase* large_case(const std::string& key, core::model::Mesh mesh, std::size_t block_triangles) {
  static std::map<std::string, std::unique_ptr<MtCase>> cache;
  auto& slot = cache[key];
  if (!slot) {
    const auto dir = scratch_dir("large-case");
    const auto ply = dir / "input.ply", mt_path = dir / "output.mt";
    EXPECT_TRUE(core::io::save_mesh(ply, mesh).ok()) << key;
    std::vector<std::uint32_t> ids;
    core::build::LargeBuildOptions options;
    options.block_triangles = block_triangles;
    options.vertex_ids = &ids;
    core::build::LargeBuildStats stats;
    const auto built = core::build::build_mt_file(ply, mt_path, options, &stats);
    EXPECT_TRUE(built.ok()) << key << ": " << (built.ok() ? "" : built.error().message);
    if (!built.ok()) return nullptr;
    auto mt = core::io::read_mt_file(mt_path);
    EXPECT_TRUE(mt.ok()) << key << ": " << (mt.ok() ? "" : mt.error().message);
    if (!mt.ok()) return nullptr;
    auto c = std::make_unique<MtCase>();
    c->mesh = std::move(mesh);
    renumber_like_mt(c->mesh, ids);
    c->mt = std::move(mt).value();
    c->reference = make_reference(c->mesh);
    c->set_topology(stats);
    slot = std::move(c);
  }
  return slot.get();
}

// A shared scan, loaded with the default clean-up (as mtlod-build does); null when absent.
// keep_topology builds it with BuildOptions::coarse_topology off.
inline const MtCase* scan_case(const std::string& file, bool keep_topology = false) {
  const auto path = shared_meshes_dir() / file;
  if (!std::filesystem::exists(path)) return nullptr;
  auto loaded = core::io::load_mesh(path);
  EXPECT_TRUE(loaded.ok()) << file;
  if (!loaded.ok()) return nullptr;
  core::build::BuildOptions options;
  options.coarse_topology = !keep_topology;
  return build_case(keep_topology ? file + "/keep-topology" : file, std::move(loaded->mesh), options);
}

// A shared scan (cleaned as scan_case does) built out of core in blocks; null when absent.
inline const MtCase* large_scan_case(const std::string& file, std::size_t block_triangles) {
  const auto path = shared_meshes_dir() / file;
  if (!std::filesystem::exists(path)) return nullptr;
  auto loaded = core::io::load_mesh(path);
  EXPECT_TRUE(loaded.ok()) << file;
  if (!loaded.ok()) return nullptr;
  return large_case(file + "/" + std::to_string(block_triangles), std::move(loaded->mesh), block_triangles);
}

// A synthetic shape of about the given size.
inline const MtCase* shape_case(core::eval::Shape shape, std::size_t triangles, std::uint32_t seed = 1) {
  core::eval::GenerateOptions options;
  options.shape = shape;
  options.target_triangles = triangles;
  options.seed = seed;
  return build_case(
      "shape" + std::to_string(int(shape)) + "-" + std::to_string(triangles) + "-" + std::to_string(seed),
      core::eval::generate_mesh(options));
}

}  // namespace mtlod::test
