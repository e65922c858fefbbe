// mtlod-gen: writes a synthetic mesh (noisy sphere, terrain, sea shell) of a target size as
// binary PLY, for scaling tests and benchmarks; or, with --from, a scan-like mesh of any size made
// from a real scan by splitting every triangle into N² and adding smooth noise (core/eval/subdivide),
// streamed to disk in chunks so that 100M+ triangles need little more memory than the scan.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>

#include "CLI/CLI.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/eval/subdivide.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/ply_stream.hpp"
#include "core/model/mesh_cleanup.hpp"
#include "fmt/format.h"

namespace {

using namespace mtlod;
using namespace mtlod::core;

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Hands the subdivider's chunks to the PLY writer.
class PlySink final : public eval::SubdivisionSink {
 public:
  explicit PlySink(io::PlyWriter& writer) : writer_(writer) {}
  Status vertices(std::span<const float> positions, std::span<const std::uint8_t> colors) override {
    return writer_.write_vertices(positions, {}, colors);
  }
  Status triangles(std::span<const std::uint32_t> triangles) override {
    return writer_.write_triangles(triangles);
  }

 private:
  io::PlyWriter& writer_;
};

int split_mesh(const std::string& from, const std::string& output, const eval::SubdivideOptions& options) {
  if (std::filesystem::path(output).extension() != ".ply") {
    fmt::print(stderr, "mtlod-gen: --from writes binary PLY only, not {}\n", output);
    return 1;
  }
  auto start = std::chrono::steady_clock::now();
  // As read: the scan's defects are what the output is meant to keep.
  auto loaded = io::load_mesh(from, {.clean = false});
  if (!loaded) {
    fmt::print(stderr, "mtlod-gen: {}\n", loaded.error().message);
    return 1;
  }
  const model::Mesh& base = loaded->mesh;
  const eval::Subdivider subdivider(base, options);
  const eval::SubdivisionCounts& counts = subdivider.counts();
  fmt::print("{}: {} vertices, {} edges, {} triangles{}, read in {:.2f} s\n", from, counts.base_vertices,
             counts.base_edges, counts.base_triangles, base.has_colors() ? ", colours" : "",
             seconds_since(start));
  if (!subdivider.fits()) {
    fmt::print(stderr, "mtlod-gen: --split {} gives {} vertices, more than 32-bit ids allow ({})\n",
               options.split, counts.vertices, eval::Subdivider::kMaxVertices);
    return 1;
  }
  fmt::print("split {}: {} vertices, {} triangles; noise amplitude {:.3g} ({} x mean edge {:.3g})\n",
             options.split, counts.vertices, counts.triangles, subdivider.amplitude(), options.noise,
             subdivider.mean_edge_length());

  start = std::chrono::steady_clock::now();
  auto writer = io::PlyWriter::create(output, counts.vertices, counts.triangles, false, base.has_colors());
  if (!writer) {
    fmt::print(stderr, "mtlod-gen: {}\n", writer.error().message);
    return 1;
  }
  PlySink sink(*writer);
  Status status = subdivider.run(sink);
  if (status) status = writer->close();
  if (!status) {
    fmt::print(stderr, "mtlod-gen: {}\n", status.error().message);
    return 1;
  }
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(output, ec);
  fmt::print("{}: {} bytes, generated and written in {:.2f} s\n", output, ec ? 0 : bytes,
             seconds_since(start));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Generate a synthetic triangle mesh, or a scan-like one from a real scan, as binary PLY."};
  std::string shape_name = "sphere", output, from;
  eval::GenerateOptions options;
  eval::SubdivideOptions split_options;
  auto* shape = app.add_option("--shape", shape_name,
                               "sphere (closed, noisy), terrain (open height field) or shell "
                               "(closed logarithmic-spiral sea shell)")
                    ->check(CLI::IsMember({"sphere", "terrain", "shell"}))
                    ->capture_default_str();
  auto* triangles = app.add_option("--triangles,-n", options.target_triangles,
                                   "target triangle count (met within a few percent)")
                        ->check(CLI::Range(std::size_t{16}, std::size_t{200'000'000}))
                        ->capture_default_str();
  auto* from_option = app.add_option("--from", from,
                                     "instead of a shape, split this mesh (PLY, OBJ, OFF, STL; read without "
                                     "clean-up, its defects kept) and displace it by noise")
                          ->excludes(shape, triangles);
  app.add_option("--split", split_options.split,
                 "with --from: cut every edge into N segments, N² triangles per triangle")
      ->check(CLI::Range(1u, 65535u))
      ->needs(from_option)
      ->capture_default_str();
  app.add_option("--seed", options.seed, "noise seed: the same seed gives the same mesh")
      ->capture_default_str();
  app.add_option("--noise", options.noise,
                 "relative noise amplitude, 0 for a smooth surface; with --from, in mean edge lengths of "
                 "the input")
      ->check(CLI::Range(0.0f, 0.5f))
      ->capture_default_str();
  app.add_flag("--colors", options.colors, "give the shape vertex colours (red, green, blue along x, y, z)")
      ->excludes(from_option);
  app.add_option("-o,--output", output, "output file (.ply or .obj; .ply with --from)")->required();
  CLI11_PARSE(app, argc, argv);

  if (!from.empty()) {
    split_options.noise = options.noise;
    split_options.seed = options.seed;
    return split_mesh(from, output, split_options);
  }
  eval::parse_shape(shape_name, options.shape);
  const auto start = std::chrono::steady_clock::now();
  const model::Mesh mesh = eval::generate_mesh(options);
  const auto status = io::save_mesh(output, mesh);
  if (!status) {
    fmt::print(stderr, "mtlod-gen: {}\n", status.error().message);
    return 1;
  }
  const double seconds = seconds_since(start);
  const model::TopologyReport topology = model::analyze_topology(mesh.positions, mesh.triangles);
  fmt::print("{} ({}): {}\ngenerated and written in {:.2f} s\n", output, shape_name, topology.summary(),
             seconds);
  return 0;
}
