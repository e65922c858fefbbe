// mtlod-extract: loads an .mt file and writes one selective refinement of it as a mesh
// (DESIGN.md §2): a uniform error bound (--error, model units) and/or a triangle budget (--budget).
// Option parsing fills ExtractOptions in one function so further flags (view-dependent refinement)
// slot in beside the existing ones.
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/refine.hpp"
#include "fmt/format.h"

namespace {

struct ExtractOptions {
  std::string model;                  // .mt file to read
  std::string output;                 // mesh to write (.ply or .obj)
  std::optional<float> error;         // uniform allowed error, model units
  std::optional<std::size_t> budget;  // at most this many triangles
};

void add_extract_options(CLI::App& app, ExtractOptions& o) {
  app.add_option("model", o.model, "MT file written by mtlod-build")->required();
  app.add_option("-o,--output", o.output, "mesh to write: .ply (binary) or .obj")->required();
  app.add_option("--error", o.error, "allowed error everywhere, in model units");
  app.add_option("--budget", o.budget, "at most this many triangles, worst error first");
}

// The cut with its used vertices only, renumbered in first-use order; normals and colours follow.
mtlod::core::Mesh compact(const mtlod::core::Mt& mt, const std::vector<std::uint32_t>& triangles) {
  mtlod::core::Mesh mesh;
  std::vector<std::uint32_t> remap(mt.vertex_count(), UINT32_MAX);
  mesh.triangles.reserve(triangles.size());
  for (const std::uint32_t v : triangles) {
    if (remap[v] == UINT32_MAX) {
      remap[v] = std::uint32_t(mesh.positions.size() / 3);
      mesh.positions.insert(mesh.positions.end(), &mt.positions[3 * std::size_t{v}],
                            &mt.positions[3 * std::size_t{v} + 3]);
      if (mt.has_normals())
        mesh.normals.insert(mesh.normals.end(), &mt.normals[3 * std::size_t{v}],
                            &mt.normals[3 * std::size_t{v} + 3]);
      if (mt.has_colors())
        mesh.colors.insert(mesh.colors.end(), &mt.colors[3 * std::size_t{v}],
                           &mt.colors[3 * std::size_t{v} + 3]);
    }
    mesh.triangles.push_back(remap[v]);
  }
  return mesh;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace mtlod::core;
  CLI::App app{"Extract a level of detail from a Multi-Tessellation."};
  ExtractOptions options;
  add_extract_options(app, options);
  CLI11_PARSE(app, argc, argv);
  if (!options.error && !options.budget) {
    fmt::print(stderr, "mtlod-extract: give --error E, --budget N or both\n");
    return 2;
  }

  auto start = std::chrono::steady_clock::now();
  auto mt = io::read_mt_file(options.model);
  if (!mt) {
    fmt::print(stderr, "mtlod-extract: {}\n", mt.error().message);
    return 1;
  }
  const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  Refiner refiner(*mt);
  CutMesh cut;
  start = std::chrono::steady_clock::now();
  if (options.budget) {
    // Without --error every triangle that has a finer version competes, ranked by its error.
    refiner.refine_budget(AllowedError::everywhere(options.error.value_or(0.0f)), *options.budget, cut);
  } else {
    refiner.refine(AllowedError::everywhere(*options.error), cut);
  }
  const double refine_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!cut.within_budget)
    fmt::print(stderr, "mtlod-extract: warning: the coarsest mesh has {} triangles, over the budget of {}\n",
               cut.triangle_count(), *options.budget);

  const Mesh mesh = compact(*mt, cut.triangles);
  if (auto saved = io::save_mesh(options.output, mesh); !saved) {
    fmt::print(stderr, "mtlod-extract: {}\n", saved.error().message);
    return 1;
  }
  fmt::print(
      "{}: {} triangles, {} vertices, {} of {} nodes, max error {:.6g}\n  loaded in {:.3f} s, refined in "
      "{:.3f} ms; wrote {}\n",
      options.model, cut.triangle_count(), mesh.vertex_count(), cut.node_count, mt->node_count(),
      cut.max_error, load_s, refine_s * 1e3, options.output);
  return 0;
}
