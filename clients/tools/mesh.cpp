// mtlod-mesh: loads a mesh (PLY, OBJ, OFF, STL), prints its topology and what clean-up changed,
// and optionally writes it as binary PLY or OBJ.
#include <chrono>
#include <string>

#include "CLI/CLI.hpp"
#include "core/io/mesh_io.hpp"
#include "fmt/format.h"

int main(int argc, char** argv) {
  using namespace mtlod::core;
  CLI::App app{"Inspect, clean and convert a triangle mesh."};
  std::string input, output;
  bool raw = false;
  app.add_option("input", input, "mesh file: .ply (ASCII or binary), .obj, .off or .stl")->required();
  app.add_option("-o,--output", output, "write the (cleaned) mesh here: .ply (binary) or .obj");
  app.add_flag("--raw", raw, "keep the mesh as read: no welding, no dropped triangles or vertices");
  CLI11_PARSE(app, argc, argv);

  io::LoadOptions options;
  options.clean = !raw;
  const auto start = std::chrono::steady_clock::now();
  auto loaded = io::load_mesh(input, options);
  if (!loaded) {
    fmt::print(stderr, "mtlod-mesh: {}\n", loaded.error().message);
    return 1;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const model::Mesh& mesh = loaded->mesh;
  fmt::print("{}: read in {:.2f} s\n  as read: {}\n", input, seconds, loaded->input_topology.summary());
  if (loaded->polygons_triangulated != 0)
    fmt::print("  {} polygons triangulated\n", loaded->polygons_triangulated);
  if (!raw) fmt::print("  {}\n", loaded->cleanup.summary());
  fmt::print("  result: {} vertices, {} triangles{}{}\n", mesh.vertex_count(), mesh.triangle_count(),
             mesh.has_normals() ? ", normals" : "", mesh.has_colors() ? ", colours" : "");
  if (!output.empty()) {
    if (auto saved = io::save_mesh(output, mesh); !saved) {
      fmt::print(stderr, "mtlod-mesh: {}\n", saved.error().message);
      return 1;
    }
    fmt::print("  written to {}\n", output);
  }
  return 0;
}
