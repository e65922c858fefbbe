// mtlod-labels: runs the grid stages (core/ARCHITECTURE.md §1) on a mesh for one camera (mapping,
// occupancy, silhouette and focus transforms, vertex labels), prints their times and label counts,
// and writes the debug images (occupancy, distance transforms) like the papers' figures 2–3.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "CLI/CLI.hpp"
#include "core/io/image_io.hpp"
#include "core/io/mesh_io.hpp"
#include "core/view/distance_transform.hpp"
#include "core/view/labels.hpp"
#include "core/view/occupancy.hpp"
#include "core/view/view_grid.hpp"
#include "fmt/format.h"

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  using namespace mtlod::core;
  CLI::App app{"Grid mapping, occupancy, distance transforms and labels of a mesh for one camera."};
  std::string input, coarse_input, out_dir;
  std::vector<float> eye, target, up{0.0f, 1.0f, 0.0f};
  std::vector<std::vector<float>> foci;
  float fov_deg = 45.0f, depth_jump = 0.0f;
  std::uint32_t grid_side = 256;
  app.add_option("input", input, "mesh whose vertices are labelled")->required();
  app.add_option("--coarse", coarse_input, "mesh rasterized for the occupancy (default: the input)");
  app.add_option("--eye", eye, "camera position X,Y,Z (default: in front of the model on +z)")
      ->delimiter(',')
      ->expected(3);
  app.add_option("--target", target, "point looked at X,Y,Z (default: bounding-box centre)")
      ->delimiter(',')
      ->expected(3);
  app.add_option("--up", up, "up vector X,Y,Z")->delimiter(',')->expected(3);
  app.add_option("--fov", fov_deg, "vertical field of view in degrees")->check(CLI::Range(1.0f, 170.0f));
  app.add_option("--grid", grid_side, "grid cells per side")->check(CLI::Range(1u, view::kMaxGridSide));
  app.add_option("--focus", foci, "focus X,Y in normalised viewport coordinates (repeatable)")
      ->delimiter(',')
      ->expected(2)
      ->allow_extra_args(false);
  app.add_option("--depth-jump", depth_jump,
                 "seed internal silhouettes where depth jumps by this ratio (0: off)");
  app.add_option("--out-dir", out_dir, "write occupancy.png, silhouette.png and focus.png here");
  CLI11_PARSE(app, argc, argv);

  io::LoadOptions load;
  load.clean = false;  // vertex ids as in the file
  auto loaded = io::load_mesh(input, load);
  if (!loaded) {
    fmt::print(stderr, "mtlod-labels: {}\n", loaded.error().message);
    return 1;
  }
  const model::Mesh& mesh = loaded->mesh;
  model::Mesh coarse_mesh;
  if (!coarse_input.empty()) {
    auto coarse = io::load_mesh(coarse_input, load);
    if (!coarse) {
      fmt::print(stderr, "mtlod-labels: {}\n", coarse.error().message);
      return 1;
    }
    coarse_mesh = std::move(coarse->mesh);
  }
  const model::Mesh& raster = coarse_input.empty() ? mesh : coarse_mesh;

  glm::vec3 lo(1e30f), hi(-1e30f);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const glm::vec3 p(mesh.positions[3 * v], mesh.positions[3 * v + 1], mesh.positions[3 * v + 2]);
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const glm::vec3 centre = target.empty() ? 0.5f * (lo + hi) : glm::vec3(target[0], target[1], target[2]);
  const float radius = 0.5f * glm::length(hi - lo);
  const glm::vec3 eye_point =
      eye.empty() ? centre + glm::vec3(0.0f, 0.0f, radius / std::tan(glm::radians(fov_deg) / 2.0f) * 1.1f)
                  : glm::vec3(eye[0], eye[1], eye[2]);
  const float distance = glm::length(eye_point - centre);
  view::Camera camera;
  camera.view = glm::lookAt(eye_point, centre, glm::vec3(up[0], up[1], up[2]));
  camera.projection =
      glm::perspective(glm::radians(fov_deg), 1.0f, std::max(1e-4f * distance, distance - 2.0f * radius),
                       distance + 2.0f * radius);
  const view::ViewMapping mapping(camera, view::GridSize{grid_side, grid_side});
  const view::GridSize grid = mapping.grid();

  std::vector<std::uint32_t> cells(mesh.vertex_count()), labels(mesh.vertex_count());
  std::vector<float> clip_w(mesh.vertex_count());
  std::vector<std::uint8_t> occupancy(grid.cell_count());
  std::vector<float> depth(depth_jump > 0.0f ? grid.cell_count() : 0);
  std::vector<std::uint16_t> silhouette(grid.cell_count()), focus(grid.cell_count());
  view::DistanceTransformer transformer;

  auto start = Clock::now();
  view::map_vertices(mapping, mesh.positions, cells, clip_w);
  const double map_ms = ms_since(start);
  start = Clock::now();
  view::rasterize_occupancy(mapping, raster.positions, raster.triangles, occupancy, depth);
  const double occupancy_ms = ms_since(start);
  std::vector<std::uint8_t> seeds = occupancy;
  std::size_t internal = 0;
  if (depth_jump > 0.0f) internal = view::mark_depth_discontinuities(depth, grid, depth_jump, seeds);
  start = Clock::now();
  transformer.chamfer(view::DistanceMetric::kChamfer5711, seeds, grid, silhouette);
  const double dt_ms = ms_since(start);
  start = Clock::now();
  view::label_vertices(cells, silhouette, labels);
  const double label_ms = ms_since(start);

  std::size_t in_view = 0, contour = 0, object_cells = 0;
  for (const std::uint32_t l : labels) {
    in_view += l != view::kLabelNoCell;
    contour += l == 5;
  }
  for (const std::uint8_t o : occupancy) object_cells += o != 0;
  fmt::print("{}: {} vertices, {} triangles rasterized, grid {}x{}\n", input, mesh.vertex_count(),
             raster.triangle_count(), grid.width, grid.height);
  fmt::print("  map {:.2f} ms, occupancy {:.2f} ms ({} object cells), 5-7-11 {:.3f} ms, labels {:.2f} ms\n",
             map_ms, occupancy_ms, object_cells, dt_ms, label_ms);
  fmt::print("  {} vertices in view, {} in contour cells (label 5){}\n", in_view, contour,
             depth_jump > 0.0f ? fmt::format(", {} internal-silhouette seeds", internal) : std::string());

  std::vector<std::uint32_t> focus_cells;
  for (const auto& f : foci) focus_cells.push_back(view::focus_cell(grid, f[0], f[1]));
  if (!focus_cells.empty()) {
    start = Clock::now();
    transformer.chamfer_from_cells(view::DistanceMetric::kChamfer5711, focus_cells, grid, focus);
    fmt::print("  focus 5-7-11 from {} foci {:.3f} ms\n", focus_cells.size(), ms_since(start));
  }
  if (!out_dir.empty()) {
    const std::filesystem::path dir = out_dir;
    std::filesystem::create_directories(dir);
    for (auto status : {io::write_occupancy_png(dir / "occupancy.png", occupancy, grid),
                        io::write_distance_png(dir / "silhouette.png", silhouette, grid, 5)}) {
      if (!status) {
        fmt::print(stderr, "mtlod-labels: {}\n", status.error().message);
        return 1;
      }
    }
    if (!focus_cells.empty()) {
      if (auto status = io::write_distance_png(dir / "focus.png", focus, grid, 5); !status) {
        fmt::print(stderr, "mtlod-labels: {}\n", status.error().message);
        return 1;
      }
    }
    fmt::print("  images written to {}\n", dir.string());
  }
  return 0;
}
