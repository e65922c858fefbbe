// mtlod-gen: writes a synthetic mesh (noisy sphere, terrain, sea shell) of a target size as
// binary PLY, for scaling tests and benchmarks.
#include <chrono>
#include <cstdio>
#include <string>

#include "CLI/CLI.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "core/mesh_cleanup.hpp"
#include "fmt/format.h"

int main(int argc, char** argv) {
  using namespace mtlod::core;
  CLI::App app{"Generate a synthetic triangle mesh as binary PLY."};
  std::string shape_name = "sphere", output;
  GenerateOptions options;
  app.add_option("--shape", shape_name,
                 "sphere (closed, noisy), terrain (open height field) or shell "
                 "(closed logarithmic-spiral sea shell)")
      ->check(CLI::IsMember({"sphere", "terrain", "shell"}))
      ->capture_default_str();
  app.add_option("--triangles,-n", options.target_triangles,
                 "target triangle count (met within a few percent)")
      ->check(CLI::Range(std::size_t{16}, std::size_t{200'000'000}))
      ->capture_default_str();
  app.add_option("--seed", options.seed, "noise seed: the same seed gives the same mesh")
      ->capture_default_str();
  app.add_option("--noise", options.noise, "relative noise amplitude, 0 for a smooth surface")
      ->check(CLI::Range(0.0f, 0.5f))
      ->capture_default_str();
  app.add_option("-o,--output", output, "output file (.ply or .obj)")->required();
  CLI11_PARSE(app, argc, argv);
  parse_shape(shape_name, options.shape);

  const auto start = std::chrono::steady_clock::now();
  const Mesh mesh = generate_mesh(options);
  const auto status = io::save_mesh(output, mesh);
  if (!status) {
    fmt::print(stderr, "mtlod-gen: {}\n", status.error().message);
    return 1;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const TopologyReport topology = analyze_topology(mesh.positions, mesh.triangles);
  fmt::print("{} ({}): {}\ngenerated and written in {:.2f} s\n", output, shape_name, topology.summary(),
             seconds);
  return 0;
}
