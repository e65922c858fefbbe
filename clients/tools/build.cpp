// mtlod-build: reads a mesh, builds its Multi-Tessellation (DESIGN.md §2) and writes an .mt file,
// with a progress bar on a terminal and a summary of counts, error, time and size.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "CLI/CLI.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/mt_builder.hpp"
#include "core/threads/thread_pool.hpp"
#include "fmt/format.h"

namespace {

struct BarState {
  int last_percent = -1;
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

}  // namespace

int main(int argc, char** argv) {
  using namespace mtlod::core;
  CLI::App app{"Build a Multi-Tessellation (.mt) from a triangle mesh."};
  std::string input, output;
  BuildOptions options;
  bool raw = false;
  app.add_option("input", input, "mesh file: .ply, .obj, .off or .stl")->required();
  app.add_option("-o,--output", output, "MT file to write")->required();
  app.add_option("--pass-fraction", options.pass_fraction,
                 "share of the cheapest collapses tried per pass (smaller: closer to greedy order, slower)")
      ->check(CLI::Range(0.01f, 1.0f));
  bool serial = false;
  app.add_flag("--serial", serial, "build on one thread (the MT is the same)");
  app.add_flag("--raw", raw,
               "no clean-up of the input (keep unused vertices, degenerate and duplicate triangles)");
  CLI11_PARSE(app, argc, argv);

  io::LoadOptions load_options;
  load_options.clean = !raw;
  auto loaded = io::load_mesh(input, load_options);
  if (!loaded) {
    fmt::print(stderr, "mtlod-build: {}\n", loaded.error().message);
    return 1;
  }
  const Mesh& mesh = loaded->mesh;
  fmt::print("{}: {} vertices, {} triangles\n  {}\n", input, mesh.vertex_count(), mesh.triangle_count(),
             loaded->cleanup.summary());

  BarState bar;
  const bool tty = isatty(fileno(stderr)) != 0;
  if (tty) {
    options.progress = draw_bar;
    options.progress_user = &bar;
  }
  mtlod::core::ThreadPool pool(serial ? 1u : std::thread::hardware_concurrency());  // 1: no other thread
  if (!serial) pool.attach(options);
  BuildStats stats;
  const auto start = std::chrono::steady_clock::now();
  auto mt = build_mt(mesh, options, &stats);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (tty) fmt::print(stderr, "\n");
  if (!mt) {
    fmt::print(stderr, "mtlod-build: {}\n", mt.error().message);
    return 1;
  }
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
      "  built in {:.3f} s ({:.0f} input triangles/s)\n"
      "  wrote {} ({} bytes), {:.1f} bytes per input triangle in memory\n",
      stats.input_triangles, stats.root_triangles, stats.nodes, stats.mt_triangles, stats.max_error,
      stats.passes, stats.complex_vertices, seconds, double(stats.input_triangles) / seconds, output, *size,
      per_triangle);
  return 0;
}
