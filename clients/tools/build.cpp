// mtlod-build: reads a mesh, builds its MT (core/ARCHITECTURE.md §2) and writes an .mt file,
// with a progress bar on a terminal and a summary of counts, error, time and size.
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>

#include "CLI/CLI.hpp"
#include "clients/common/huge_pages.hpp"
#include "core/build/large_build.hpp"
#include "core/build/mt_builder.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/threads/thread_pool.hpp"
#include "fmt/format.h"

namespace {

struct BarState {
  int last_percent = -1;
  const char* phase = nullptr;
};

void draw_bar(void* user, double fraction) {
  auto* state = static_cast<BarState*>(user);
  const int percent = static_cast<int>(fraction * 100.0);
  if (percent == state->last_percent) return;
  state->last_percent = percent;
  constexpr int kWidth = 40;
  const int filled = percent * kWidth / 100;
  fmt::print(stderr, "\r  simplifying [{}{}] {:3d}%", std::string(filled, '#'),
             std::string(kWidth - filled, ' '), percent);
  std::fflush(stderr);
}

void draw_phase(void* user, const char* phase, double fraction) {
  auto* state = static_cast<BarState*>(user);
  const int percent = static_cast<int>(fraction * 100.0);
  if (percent == state->last_percent && phase == state->phase) return;
  if (phase != state->phase && state->phase != nullptr) fmt::print(stderr, "\n");
  state->phase = phase;
  state->last_percent = percent;
  constexpr int kWidth = 40;
  const int filled = percent * kWidth / 100;
  fmt::print(stderr, "\r  {:<17} [{}{}] {:3d}%", phase, std::string(filled, '#'),
             std::string(kWidth - filled, ' '), percent);
  std::fflush(stderr);
}

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// Says where the normals came from: a mesh without them is common (scans rarely carry them), broken
// ones are worth a warning.
void report_normals(bool given, std::uint64_t computed, std::uint64_t vertices) {
  if (!given)
    fmt::print(stderr, "mtlod-build: the mesh has no normals: computed from its surface (angle-weighted)\n");
  else if (computed > 0)
    fmt::print(
        stderr,
        "mtlod-build: warning: {} of {} vertex normals are NaN or zero-length: computed from the surface\n",
        computed, vertices);
}

// Where the topology may differ from the input's: only in cuts coarser than the error printed; and
// where a cut may hold two faces on the same three vertices.
std::string topology_line(std::size_t collapses, float error, std::size_t stacking, float stacking_error) {
  if (collapses == 0) return "  every cut has the input's topology\n";
  std::string line = fmt::format(
      "  {} collapses change the topology, all with error >= {:.6g}: finer cuts keep it\n", collapses, error);
  if (stacking > 0)
    line +=
        fmt::format("  {} of them may stack two faces, all with error >= {:.6g}\n", stacking, stacking_error);
  return line;
}

// PLY in bounded memory, streamed (core/build/large_build.hpp).
int build_large(const std::string& input, const std::string& output,
                const mtlod::core::build::LargeBuildOptions& options, bool tty) {
  using namespace mtlod::core;
  BarState bar;
  build::LargeBuildOptions large = options;
  if (tty) {
    large.progress = draw_phase;
    large.progress_user = &bar;
  }
  build::LargeBuildStats stats;
  const auto start = std::chrono::steady_clock::now();
  const auto built = build::build_mt_file(input, output, large, &stats);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (tty) fmt::print(stderr, "\n");
  if (!built) {
    fmt::print(stderr, "mtlod-build: {}\n", built.error().message);
    return 1;
  }
  report_normals(stats.normals_given, stats.normals_computed, stats.vertices);
  fmt::print(
      "{}: {} vertices, {} triangles\n"
      "  clean-up: dropped {} degenerate and {} duplicate triangles, {} polygons triangulated\n"
      "  memory limit {} MiB: {} blocks of at most {} triangles, {} stages in {} levels\n"
      "  input triangles {}, root triangles {}, nodes {}, MT triangles {}\n"
      "  max error {:.6g} (model units), {} complex vertices kept\n"
      "{}"
      "  built in {:.3f} s ({:.0f} input triangles/s), temporary files up to {} MiB\n"
      "  wrote {} ({} bytes)\n",
      input, stats.vertices, stats.input_triangles, stats.dropped_degenerate, stats.dropped_duplicate,
      stats.polygons_triangulated,
      (large.memory_limit ? large.memory_limit : io::default_memory_limit()) >> 20, stats.blocks,
      stats.block_triangles, stats.stages, stats.levels,
      stats.input_triangles - stats.dropped_degenerate - stats.dropped_duplicate, stats.root_triangles,
      stats.nodes, stats.mt_triangles, stats.max_error, stats.complex_vertices,
      topology_line(stats.topology_collapses, stats.topology_error, stats.stacking_collapses,
                    stats.stacking_error),
      seconds, double(stats.input_triangles) / seconds, stats.temp_bytes >> 20, output, stats.file_bytes);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace mtlod::core;
  mtlod::clients::rerun_with_huge_pages(argv);
  CLI::App app{"Build a Multi-Tessellation (.mt) from a triangle mesh."};
  std::string input, output;
  build::BuildOptions options;
  build::LargeBuildOptions large;
  bool raw = false;
  app.add_option("input", input, "mesh file: .ply (streamed in bounded memory), .obj, .off or .stl")
      ->required();
  app.add_option("-o,--output", output, "MT file to write")->required();
  app.add_option("--pass-fraction", options.pass_fraction,
                 "share of the cheapest collapses tried per pass (smaller: closer to greedy order, slower)")
      ->check(CLI::Range(0.01f, 1.0f));
  bool keep_topology = false;
  app.add_flag("--keep-topology", keep_topology,
               "every cut keeps the input's topology, the coarsest too (larger roots on scans with many "
               "components, holes or non-manifold edges)");
  bool serial = false;
  app.add_flag("--serial", serial, "build on one thread (the MT is the same)");
  app.add_flag("--raw", raw,
               "no clean-up of the input (keep unused vertices, degenerate and duplicate triangles); "
               "reads the whole mesh into memory");
  app.add_option("--memory-limit", large.memory_limit,
                 "peak memory of a PLY build, e.g. 4G or 512M (default: half the RAM or cgroup limit)")
      ->transform(CLI::AsSizeValue(false));
  app.add_option("--block-triangles", large.block_triangles,
                 "triangles per block of a PLY build (default: the most the memory limit allows)")
      ->check(CLI::Range(std::size_t{16}, std::size_t{1} << 30));
  app.add_option("--temp-dir", large.temp_dir,
                 "where a PLY build keeps its temporary files (default: beside -o)");
  CLI11_PARSE(app, argc, argv);
  options.coarse_topology = !keep_topology;

  const bool tty = isatty(fileno(stderr)) != 0;
  mtlod::core::threads::ThreadPool pool(serial ? 1u
                                               : std::thread::hardware_concurrency());  // 1: no other thread
  if (!serial) pool.attach(options);
  if (!raw && lower_extension(input) == ".ply") {
    large.build = options;
    large.threads = serial ? 1 : std::max(1u, std::thread::hardware_concurrency());
    return build_large(input, output, large, tty);
  }

  io::LoadOptions load_options;
  load_options.clean = !raw;
  auto loaded = io::load_mesh(input, load_options);
  if (!loaded) {
    fmt::print(stderr, "mtlod-build: {}\n", loaded.error().message);
    return 1;
  }
  const model::Mesh& mesh = loaded->mesh;
  fmt::print("{}: {} vertices, {} triangles\n  {}\n", input, mesh.vertex_count(), mesh.triangle_count(),
             loaded->cleanup.summary());

  BarState bar;
  if (tty) {
    options.progress = draw_bar;
    options.progress_user = &bar;
  }
  build::BuildStats stats;
  const auto start = std::chrono::steady_clock::now();
  auto mt = build::build_mt(mesh, options, &stats);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (tty) fmt::print(stderr, "\n");
  if (!mt) {
    fmt::print(stderr, "mtlod-build: {}\n", mt.error().message);
    return 1;
  }
  report_normals(stats.normals_given, stats.normals_computed, mesh.vertex_count());
  auto size = io::write_mt_file(output, *mt);
  if (!size) {
    fmt::print(stderr, "mtlod-build: {}\n", size.error().message);
    return 1;
  }
  const double per_triangle =
      double(mt->memory_bytes()) / double(std::max<std::size_t>(stats.input_triangles, 1));
  fmt::print(
      "  input triangles {}, root triangles {}, nodes {}, MT triangles {}\n"
      "  max error {:.6g} (model units), {} passes, {} complex vertices kept\n"
      "{}"
      "  built in {:.3f} s ({:.0f} input triangles/s)\n"
      "  wrote {} ({} bytes), {:.1f} bytes per input triangle in memory\n",
      stats.input_triangles, stats.root_triangles, stats.nodes, stats.mt_triangles, stats.max_error,
      stats.passes, stats.complex_vertices,
      topology_line(stats.topology_collapses, stats.topology_error, stats.stacking_collapses,
                    stats.stacking_error),
      seconds, double(stats.input_triangles) / seconds, output, *size, per_triangle);
  return 0;
}
