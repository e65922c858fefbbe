// mtlod-eval: measures extractions against the original mesh (papers/000 §4 figures 3–5,
// papers/002 §4). Subcommands:
//   compare A B              object-space Hausdorff / mean / RMS, both directions (Metro-style)
//   silhouette A B --eye ... silhouette XOR and contour distances from one camera
//   image A B --eye ...      both rendered from one camera, shaded with A's normals: SSIM, mean
//                            absolute error and their foveated variants, coverage, depth
//   fidelity --mesh N=P...   image-space fidelity of the methods at equal triangles and equal bytes
//                            (clients/tools/eval/fidelity.hpp); writes FIDELITY.md, fidelity.csv, figures
//   score REF.png CUT.png    two renderings as pictures (the browser viewer's screenshots): the
//                            foveated error and SSIM as above, one JSON line (eval/score.hpp)
//   gaze --mesh N=P...       a gaze trace replayed: gaze-driven cuts against a uniform cut of the same
//                            bytes, recovery after saccades (eval/gaze_study.hpp); writes GAZE.md
//   experiment --mesh N=P... uniform vs silhouette-DT vs focus-DT budgeted refinement at equal
//                            triangle counts, plus meshoptimizer's meshopt_simplify as a peer, over
//                            several meshes, cameras and budgets; writes REPORT.md, results.csv, PNGs
#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>

#include "CLI/CLI.hpp"
#include "clients/tools/eval/fidelity.hpp"
#include "clients/tools/eval/gaze_study.hpp"
#include "clients/tools/eval/score.hpp"
#include "clients/tools/eval/support.hpp"
#include "core/build/mt_builder.hpp"
#include "core/cut/refine.hpp"
#include "core/eval/image_metrics.hpp"
#include "core/eval/render.hpp"
#include "core/eval/silhouette_metrics.hpp"
#include "core/eval/surface_metrics.hpp"
#include "core/io/image_io.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/model/bounds.hpp"
#include "core/view/labels.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/view_extract.hpp"
#include "core/view/view_grid.hpp"
#include "fmt/format.h"

namespace {

using namespace mtlod;
using namespace mtlod::core;
using namespace mtlod::eval_tool;
namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// compare and silhouette subcommands

// Two silhouette masks as one RGB image: pixels in both grey, only in `a` blue, only in `b` red.
void xor_image(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b,
               std::vector<std::uint8_t>& rgb) {
  rgb.resize(3 * a.size());
  for (std::size_t c = 0; c < a.size(); ++c) {
    const std::array<std::uint8_t, 3> colour = a[c] && b[c] ? std::array<std::uint8_t, 3>{175, 175, 175}
                                               : b[c]       ? std::array<std::uint8_t, 3>{220, 30, 30}
                                               : a[c]       ? std::array<std::uint8_t, 3>{30, 60, 220}
                                                            : std::array<std::uint8_t, 3>{255, 255, 255};
    std::copy(colour.begin(), colour.end(), &rgb[3 * c]);
  }
}

int run_compare(const std::string& a_path, const std::string& b_path, std::size_t samples) {
  auto a = load(a_path);
  if (!a) return fmt::print(stderr, "mtlod-eval: {}\n", a.error().message), 1;
  auto b = load(b_path);
  if (!b) return fmt::print(stderr, "mtlod-eval: {}\n", b.error().message), 1;
  const auto start = Clock::now();
  const eval::SurfaceError e =
      eval::compare_surfaces(a->positions, a->triangles, b->positions, b->triangles, {samples, true, 1});
  const double diag = model::bounds_of(a->positions).diagonal();
  fmt::print("A = {} ({} triangles), B = {} ({} triangles), A's bounding-box diagonal {:.6g}\n", a_path,
             a->triangle_count(), b_path, b->triangle_count(), diag);
  const auto row = [&](const char* name, const eval::DistanceStats& s) {
    fmt::print("  {}: {} samples, max {:.6g} ({:.4f} % of diagonal), mean {:.6g}, RMS {:.6g}\n", name,
               s.samples, s.max, 100 * s.max / diag, s.mean, s.rms);
  };
  row("A -> B", e.a_to_b);
  row("B -> A", e.b_to_a);
  fmt::print("  symmetric Hausdorff {:.6g} ({:.4f} %), RMS {:.6g}; {:.2f} s\n", e.hausdorff(),
             100 * e.hausdorff() / diag, e.rms(), seconds_since(start));
  return 0;
}

struct CameraFlags {
  std::vector<double> eye, target, up{0, 1, 0};
  double fov = 40, near = 0, far = 0;
  std::uint32_t size = 512;
};

// The camera flags shared by the subcommands that render (--size is the silhouette's own).
void add_camera_flags(CLI::App& app, CameraFlags& camera) {
  app.add_option("--eye", camera.eye, "X,Y,Z (default: in front of A along +z)")->delimiter(',')->expected(3);
  app.add_option("--target", camera.target, "X,Y,Z (default: A's bounding-box centre)")
      ->delimiter(',')
      ->expected(3);
  app.add_option("--up", camera.up, "X,Y,Z")->delimiter(',')->expected(3);
  app.add_option("--fov", camera.fov, "vertical field of view, degrees");
  app.add_option("--near", camera.near, "near plane (default: distance/100)");
  app.add_option("--far", camera.far, "far plane (default: distance·100)");
}

// The camera of the flags for a model with these bounds: without --eye, in front of the model
// along +z, far enough that its bounding sphere fills about 90 % of the field of view.
Result<view::Camera> camera_from_flags(const model::Bounds& bounds, const CameraFlags& f, double aspect) {
  std::array<double, 3> eye, target = model::to_double(bounds.centre()), up{f.up[0], f.up[1], f.up[2]};
  if (f.eye.empty()) {
    const double d = bounds.radius() / std::sin(glm::radians(f.fov / 2)) / 0.9;
    eye = {target[0], target[1], target[2] + d};
  } else {
    eye = {f.eye[0], f.eye[1], f.eye[2]};
  }
  if (!f.target.empty()) target = {f.target[0], f.target[1], f.target[2]};
  const double distance = std::hypot(eye[0] - target[0], eye[1] - target[1], eye[2] - target[2]);
  return make_camera(eye, target, up, f.fov, f.near > 0 ? f.near : distance / 100,
                     f.far > 0 ? f.far : distance * 100, aspect);
}

int run_silhouette(const std::string& a_path, const std::string& b_path, const CameraFlags& f,
                   const std::string& png) {
  auto a = load(a_path);
  if (!a) return fmt::print(stderr, "mtlod-eval: {}\n", a.error().message), 1;
  auto b = load(b_path);
  if (!b) return fmt::print(stderr, "mtlod-eval: {}\n", b.error().message), 1;
  if (f.size == 0 || f.size > view::kMaxGridSide)
    return fmt::print(stderr, "mtlod-eval: --size {} is outside [1, {}]\n", f.size, view::kMaxGridSide), 2;
  auto camera = camera_from_flags(model::bounds_of(a->positions), f, 1.0);
  if (!camera) return fmt::print(stderr, "mtlod-eval: {}\n", camera.error().message), 2;
  const view::GridSize grid{f.size, f.size};
  const view::ViewMapping mapping(*camera, grid);
  std::vector<std::uint8_t> mask_a(grid.cell_count()), mask_b(grid.cell_count());
  eval::rasterize_silhouette(mapping, a->positions, a->triangles, mask_a);
  eval::rasterize_silhouette(mapping, b->positions, b->triangles, mask_b);
  const eval::SilhouetteError e = eval::compare_silhouettes(mask_a, mask_b, grid);
  fmt::print(
      "{}x{} image: A covers {} px, B covers {} px, XOR {} px; contour distance mean {:.3f} px, max {:.3f} "
      "px "
      "(A->B mean {:.3f} max {:.3f}, B->A mean {:.3f} max {:.3f})\n",
      f.size, f.size, e.pixels_a, e.pixels_b, e.xor_pixels, e.mean_px(), e.max_px(), e.a_to_b.mean_px,
      e.a_to_b.max_px, e.b_to_a.mean_px, e.b_to_a.max_px);
  if (!png.empty()) {
    std::vector<std::uint8_t> rgb;
    xor_image(mask_a, mask_b, rgb);
    if (auto s = io::write_png_rgb(png, rgb, grid); !s)
      return fmt::print(stderr, "mtlod-eval: {}\n", s.error().message), 1;
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------
// image-space metrics: the helpers the image subcommand and the experiment share

// ---------------------------------------------------------------------------------------------
// experiment

struct ExperimentOptions {
  std::vector<std::string> meshes;  // NAME=PATH
  std::vector<std::size_t> budgets{1000, 4000, 16000};
  int cameras = 8;
  std::uint32_t image_px = 512;            // silhouette masks and figures
  std::uint32_t grid_px = 256;             // the view grid of the distance transforms (the server's default)
  std::size_t reference_samples = 100000;  // area samples on the original
  std::size_t cut_samples = 30000;         // area samples on each simplification
  std::vector<float> silhouette{2.0f, 0.2f};  // d (grid px), f
  std::vector<float> focus{0.08f, 0.1f};      // radius (fraction of the image side), f
  std::string out_dir = "tests/evaluation";
  std::string cache_dir = "build/eval-cache";
  std::vector<std::string> figure_meshes{"bunny", "dragon-871k"};
  std::vector<std::string> notes;  // extra lines for the report's setup section
};

enum Method { kUniform, kSilhouette, kFocus, kMeshopt, kMethodCount };
constexpr const char* kMethodNames[kMethodCount] = {"uniform", "silhouette-DT", "focus-DT", "meshopt"};
constexpr const char* kMethodFiles[kMethodCount] = {"uniform", "silhouette", "focus", "meshopt"};

struct Measure {
  double triangles = 0;  // a count; double so that means over cameras share the code of the other fields
  double xor_px = 0, contour_mean_px = 0, contour_max_px = 0;
  double hausdorff = 0, rms = 0;              // symmetric, fraction of the bounding-box diagonal
  double focus_hausdorff = 0, focus_rms = 0;  // restricted to the focus region, same units
};

struct Row {
  std::string mesh;
  std::size_t budget = 0;
  int camera = 0;
  std::array<Measure, kMethodCount> m;
};

// Object-space error of a cut against the original, both directions (samples of the original and
// its index are shared by every cut of the mesh).
struct Reference {
  const model::Mesh* mesh = nullptr;
  eval::SurfaceSamples samples;
  std::unique_ptr<eval::TriangleIndex> index;
  double diagonal = 1;
};

// Distances of the original's samples to a cut and of the cut's samples to the original, kept so
// that the focus-region error of any view is a masked reduction over them.
struct CutDistances {
  std::vector<float> ref_to_cut;
  eval::SurfaceSamples cut_samples;
  std::vector<float> cut_to_ref;
};

void measure_surface(Reference& ref, std::span<const float> positions, std::span<const std::uint32_t> cut,
                     std::size_t cut_samples, CutDistances& d, Measure& out) {
  eval::TriangleIndex cut_index(positions, cut);
  eval::sample_surface(positions, cut, {}, {cut_samples, true, 2}, d.cut_samples);
  d.ref_to_cut.resize(ref.samples.size());
  d.cut_to_ref.resize(d.cut_samples.size());
  const eval::DistanceStats to_cut = eval::sample_distances(ref.samples, cut_index, d.ref_to_cut);
  const eval::DistanceStats to_ref = eval::sample_distances(d.cut_samples, *ref.index, d.cut_to_ref);
  out.hausdorff = std::max(to_cut.max, to_ref.max) / ref.diagonal;
  out.rms = std::max(to_cut.rms, to_ref.rms) / ref.diagonal;
}

// Max and RMS of the distances whose sample lies on a masked triangle.
std::pair<double, double> masked_stats(std::span<const float> distance, const eval::SurfaceSamples& samples,
                                       std::span<const std::uint8_t> mask) {
  double max = 0, sum2 = 0;
  std::size_t n = 0;
  for (std::size_t s = 0; s < distance.size(); ++s) {
    if (!mask[samples.triangle_ids[s]]) continue;
    max = std::max<double>(max, distance[s]), sum2 += double(distance[s]) * distance[s], ++n;
  }
  return {max, n ? std::sqrt(sum2 / double(n)) : 0.0};
}

void measure_focus(const Reference& ref, const CutDistances& d, std::span<const std::uint8_t> ref_mask,
                   std::span<const std::uint8_t> cut_mask, Measure& out) {
  const auto [max_a, rms_a] = masked_stats(d.ref_to_cut, ref.samples, ref_mask);
  const auto [max_b, rms_b] = masked_stats(d.cut_to_ref, d.cut_samples, cut_mask);
  out.focus_hausdorff = std::max(max_a, max_b) / ref.diagonal;
  out.focus_rms = std::max(rms_a, rms_b) / ref.diagonal;
}

void measure_silhouette(const view::ViewMapping& image, std::span<const std::uint8_t> ref_mask,
                        std::span<const float> positions, std::span<const std::uint32_t> cut,
                        std::vector<std::uint8_t>& scratch, Measure& out) {
  eval::rasterize_silhouette(image, positions, cut, scratch);
  const eval::SilhouetteError e = eval::compare_silhouettes(ref_mask, scratch, image.grid());
  out.xor_px = double(e.xor_pixels);
  out.contour_mean_px = e.mean_px();
  out.contour_max_px = e.max_px();
}

Status write_render(const fs::path& path, const view::ViewMapping& image, std::span<const float> positions,
                    std::span<const std::uint32_t> triangles, const eval::RenderColors& colors,
                    bool wireframe) {
  eval::RenderOptions options;
  options.wireframe = wireframe;
  std::vector<std::uint8_t> rgb(3 * image.grid().cell_count());
  eval::render_mesh(image, positions, triangles, colors, options, rgb);
  return io::write_png_rgb(path, rgb, image.grid());
}

// Figures for one mesh at one camera and budget: the four extractions shaded with wireframe, the
// silhouette XOR of uniform and silhouette-DT, Hausdorff colour maps of the original against both,
// and the silhouette distance labels.
Status write_figures(const fs::path& dir, const std::string& name, std::size_t budget,
                     const view::ViewMapping& image, const model::Mesh& mesh, const model::Mt& mt,
                     const std::array<std::vector<std::uint32_t>, kMethodCount>& cuts,
                     const std::vector<float>& meshopt_positions, std::span<const std::uint8_t> ref_mask,
                     std::span<const std::uint16_t> silhouette_dt, const view::ViewMapping& dt_mapping,
                     std::vector<std::string>& figures) {
  const std::string stem = fmt::format("{}-{}", name, budget);
  for (int m = 0; m < kMethodCount; ++m) {
    const std::string file = fmt::format("{}-{}.png", stem, kMethodFiles[m]);
    const std::span<const float> positions =
        m == kMeshopt ? std::span<const float>(meshopt_positions) : mt.positions;
    MTLOD_TRY(auto ok, write_render(dir / file, image, positions, cuts[m], {}, true));
    (void)ok;
    figures.push_back(file);
  }
  // Silhouette XOR: shared pixels grey, only the original blue, only the cut red.
  std::vector<std::uint8_t> mask(image.grid().cell_count()), rgb;
  for (const int m : {kUniform, kSilhouette}) {
    eval::rasterize_silhouette(image, mt.positions, cuts[m], mask);
    xor_image(ref_mask, mask, rgb);
    const std::string file = fmt::format("{}-xor-{}.png", stem, kMethodFiles[m]);
    MTLOD_TRY(auto ok, io::write_png_rgb(dir / file, rgb, image.grid()));
    (void)ok;
    figures.push_back(file);
  }
  // Hausdorff colour map (papers/000 figure 5): every original vertex coloured by its distance to the
  // cut, on one scale for both methods (the uniform cut's largest vertex distance).
  std::array<std::vector<float>, 2> distance;
  for (int k = 0; k < 2; ++k) {
    eval::TriangleIndex index(mt.positions, cuts[k == 0 ? kUniform : kSilhouette]);
    distance[k].resize(mesh.vertex_count());
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v)
      distance[k][v] =
          float(index.distance(mesh.positions[3 * v], mesh.positions[3 * v + 1], mesh.positions[3 * v + 2]));
  }
  const float scale = std::max(1e-30f, *std::max_element(distance[0].begin(), distance[0].end()));
  std::vector<std::uint8_t> colours(3 * mesh.vertex_count());
  for (int k = 0; k < 2; ++k) {
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      const auto c = eval::ramp_color(distance[k][v] / scale);
      std::copy(c.begin(), c.end(), &colours[3 * v]);
    }
    const std::string file =
        fmt::format("{}-hausdorff-{}.png", stem, kMethodFiles[k == 0 ? kUniform : kSilhouette]);
    MTLOD_TRY(auto ok, write_render(dir / file, image, mesh.positions, mesh.triangles, {colours, {}}, false));
    (void)ok;
    figures.push_back(file);
  }
  // Silhouette labels of the original's vertices (papers/000 figure 2): 0 to 20 px on the ramp.
  std::vector<std::uint32_t> cells(mesh.vertex_count()), labels(mesh.vertex_count());
  std::vector<float> clip_w(mesh.vertex_count());
  view::map_vertices(dt_mapping, mesh.positions, cells, clip_w);
  view::label_vertices(cells, silhouette_dt, labels);
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const auto c = labels[v] >= view::kLabelUnreached ? std::array<std::uint8_t, 3>{128, 128, 128}
                                                      : eval::ramp_color(float(labels[v]) / (5.0f * 20.0f));
    std::copy(c.begin(), c.end(), &colours[3 * v]);
  }
  const std::string file = fmt::format("{}-labels.png", name);
  MTLOD_TRY(auto ok, write_render(dir / file, image, mesh.positions, mesh.triangles, {colours, {}}, false));
  (void)ok;
  figures.push_back(file);
  return Ok{};
}

double mean_of(const std::vector<Row>& rows, const std::string& mesh, std::size_t budget, int method,
               double Measure::*field) {
  double sum = 0;
  int n = 0;
  for (const Row& r : rows)
    if (r.mesh == mesh && r.budget == budget) sum += r.m[method].*field, ++n;
  return n ? sum / n : 0;
}

std::string report_markdown(const ExperimentOptions& o, const std::vector<Row>& rows,
                            const std::vector<std::pair<std::string, std::string>>& mesh_info,
                            const std::vector<std::string>& notes, const std::vector<std::string>& figures,
                            double total_s, const std::string& command);

int run_experiment(const ExperimentOptions& o, const std::string& command) {
  const auto start = Clock::now();
  if (o.meshes.empty())
    return fmt::print(stderr, "mtlod-eval: experiment needs at least one --mesh NAME=PATH\n"), 2;
  if (o.cameras < 1) return fmt::print(stderr, "mtlod-eval: --cameras {} must be at least 1\n", o.cameras), 2;
  if (o.silhouette.size() != 2 || o.focus.size() != 2)
    return fmt::print(stderr, "mtlod-eval: --silhouette and --focus take D,F\n"), 2;
  const fs::path out_dir = o.out_dir, figure_dir = out_dir / "figures";
  std::error_code ec;
  fs::create_directories(figure_dir, ec);
  if (ec)
    return fmt::print(stderr, "mtlod-eval: cannot create {}: {}\n", figure_dir.string(), ec.message()), 1;

  std::vector<Row> rows;
  std::vector<std::pair<std::string, std::string>> mesh_info;
  std::vector<std::string> notes, figures;
  const view::GridSize image_grid{o.image_px, o.image_px}, dt_grid{o.grid_px, o.grid_px};
  for (const std::string& spec : o.meshes) {
    const auto eq = spec.find('=');
    if (eq == std::string::npos || eq == 0)
      return fmt::print(stderr, "mtlod-eval: --mesh '{}' is not NAME=PATH\n", spec), 2;
    const std::string name = spec.substr(0, eq), path = spec.substr(eq + 1);
    const auto mesh_start = Clock::now();
    auto mesh = load(path);
    if (!mesh) return fmt::print(stderr, "mtlod-eval: {}\n", mesh.error().message), 1;
    auto mt = cached_mt(*mesh, name, o.cache_dir);
    if (!mt) return fmt::print(stderr, "mtlod-eval: {}: {}\n", name, mt.error().message), 1;
    const std::unique_ptr<view::OccupancyLevels> levels = must(view::OccupancyLevels::make(*mt));
    view::ViewExtractor extractor(*mt, *levels);
    cut::Refiner refiner(*mt);
    const model::Bounds bounds = model::bounds_of(mesh->positions);

    Reference ref;
    ref.mesh = &*mesh;
    ref.diagonal = bounds.diagonal();
    // Vertices as samples too while they are few; big meshes get area samples only (said in the report).
    const bool with_vertices = mesh->vertex_count() <= o.reference_samples;
    eval::sample_surface(mesh->positions, mesh->triangles, {}, {o.reference_samples, with_vertices, 1},
                         ref.samples);
    ref.index = std::make_unique<eval::TriangleIndex>(mesh->positions, mesh->triangles);
    mesh_info.push_back(
        {name, fmt::format("{} | {} | {} | {} | {}", path, mesh->vertex_count(), mesh->triangle_count(),
                           mt->root_triangle_count(), ref.samples.size())});

    const std::vector<std::size_t> budgets = usable_budgets(o.budgets, *mesh, *mt, name, notes);
    // meshopt_simplify on the full-resolution mesh, once per budget (it does not depend on the view).
    std::map<std::size_t, std::vector<std::uint32_t>> meshopt;
    std::map<std::size_t, Measure> meshopt_surface;
    std::map<std::size_t, CutDistances> meshopt_distances;
    for (const std::size_t b : budgets) {
      std::vector<std::uint32_t> out(mesh->triangles.size());
      out.resize(meshopt_simplify(out.data(), mesh->triangles.data(), mesh->triangles.size(),
                                  mesh->positions.data(), mesh->vertex_count(), 3 * sizeof(float), 3 * b,
                                  1e3f));
      meshopt[b] = std::move(out);
      Measure m;
      m.triangles = double(meshopt[b].size() / 3);
      measure_surface(ref, mesh->positions, meshopt[b], o.cut_samples, meshopt_distances[b], m);
      meshopt_surface[b] = m;
    }

    std::vector<std::uint8_t> ref_mask(image_grid.cell_count()), scratch(image_grid.cell_count());
    std::vector<std::uint8_t> ref_focus(mesh->triangle_count()), cut_focus;
    CutDistances distances;
    std::vector<float> sil_field, focus_field;
    std::vector<std::uint16_t> sil_dt0;
    view::ViewMapping dt_mapping0;
    for (int k = 0; k < o.cameras; ++k) {
      const view::Camera camera = orbit_camera(bounds, k, o.cameras);
      const view::ViewMapping image(camera, image_grid);
      eval::rasterize_silhouette(image, mesh->positions, mesh->triangles, ref_mask);
      const std::array<float, 2> focus = focus_point(ref_mask, image_grid);
      const float focus_radius_img = o.focus[0] * float(o.image_px);
      eval::triangles_near_point(image, mesh->positions, mesh->triangles, focus[0] * o.image_px,
                                 focus[1] * o.image_px, focus_radius_img, ref_focus);

      // The two view-dependent fields: a tiny bound e so that every triangle fails and the budget
      // alone stops the refinement; the ranking error / allowed then depends only on the factors.
      const auto field = [&](bool silhouette, std::vector<float>& out) {
        view::ViewRequest request;
        request.camera = camera;
        request.grid = dt_grid;
        request.allowed.error = 1e-9f * bounds.radius();
        if (silhouette) {
          request.allowed.criteria[view::Criterion::kSilhouette] =
              view::RegionLaw{view::FalloffLaw::kStep, o.silhouette[0], o.silhouette[1], 16.0f, 2.3f};
        } else {
          request.allowed.criteria[view::Criterion::kFocus] = view::RegionLaw{
              view::FalloffLaw::kStep, o.focus[0] * float(o.grid_px), o.focus[1], 16.0f, 2.3f};
          request.points[view::Criterion::kFocus] = {focus};
        }
        const std::span<const float> f = extractor.allowed_error_field(request);
        out.assign(f.begin(), f.end());
        if (silhouette && k == 0) {
          const auto dt = extractor.distance_transform(view::Criterion::kSilhouette);
          sil_dt0.assign(dt.begin(), dt.end());
          dt_mapping0 = extractor.mapping();
        }
      };
      field(true, sil_field);
      field(false, focus_field);
      const std::array<cut::AllowedError, 3> allowed{cut::AllowedError::everywhere(0.0f),
                                                     cut::AllowedError::from_vertices(sil_field),
                                                     cut::AllowedError::from_vertices(focus_field)};

      for (const std::size_t b : budgets) {
        // Equal counts: run each method at the budget, then all at the smallest count, until equal.
        std::array<cut::CutMesh, 3> cuts;
        std::size_t target = b;
        for (int round = 0; round < 6; ++round) {
          for (int m = 0; m < 3; ++m)
            must(refiner.refine(cut::Refinement::from_root(allowed[m]).within(target), cuts[m]));
          const std::size_t lo =
              std::min({cuts[0].triangle_count(), cuts[1].triangle_count(), cuts[2].triangle_count()});
          const std::size_t hi =
              std::max({cuts[0].triangle_count(), cuts[1].triangle_count(), cuts[2].triangle_count()});
          if (lo == hi) break;
          target = lo;
        }
        Row row{name, b, k, {}};
        for (int m = 0; m < 3; ++m) {
          Measure& r = row.m[m];
          r.triangles = double(cuts[m].triangle_count());
          cut_focus.resize(cuts[m].triangle_count());
          eval::triangles_near_point(image, mt->positions, cuts[m].triangles, focus[0] * o.image_px,
                                     focus[1] * o.image_px, focus_radius_img, cut_focus);
          measure_surface(ref, mt->positions, cuts[m].triangles, o.cut_samples, distances, r);
          measure_focus(ref, distances, ref_focus, cut_focus, r);
          measure_silhouette(image, ref_mask, mt->positions, cuts[m].triangles, scratch, r);
        }
        Measure& mo = row.m[kMeshopt];
        mo = meshopt_surface[b];
        cut_focus.resize(meshopt[b].size() / 3);
        eval::triangles_near_point(image, mesh->positions, meshopt[b], focus[0] * o.image_px,
                                   focus[1] * o.image_px, focus_radius_img, cut_focus);
        measure_focus(ref, meshopt_distances[b], ref_focus, cut_focus, mo);
        measure_silhouette(image, ref_mask, mesh->positions, meshopt[b], scratch, mo);
        rows.push_back(row);

        if (k == 0 && b == budgets.front() &&
            std::find(o.figure_meshes.begin(), o.figure_meshes.end(), name) != o.figure_meshes.end()) {
          std::array<std::vector<std::uint32_t>, kMethodCount> tris{cuts[0].triangles, cuts[1].triangles,
                                                                    cuts[2].triangles, meshopt[b]};
          // The meshopt cut indexes the loaded mesh, whose vertices are the MT's (same ids).
          if (auto s = write_figures(figure_dir, name, b, image, *mesh, *mt, tris, mesh->positions, ref_mask,
                                     sil_dt0, dt_mapping0, figures);
              !s)
            return fmt::print(stderr, "mtlod-eval: {}\n", s.error().message), 1;
        }
      }
    }
    fmt::print("{}: {} triangles, {} budgets x {} cameras in {:.1f} s\n", name, mesh->triangle_count(),
               budgets.size(), o.cameras, seconds_since(mesh_start));
    std::fflush(stdout);
  }

  // results.csv: one line per mesh, budget, camera and method.
  std::string csv =
      "mesh,budget,camera,method,triangles,xor_px,contour_mean_px,contour_max_px,hausdorff,rms,"
      "focus_hausdorff,focus_rms\n";
  for (const Row& r : rows)
    for (int m = 0; m < kMethodCount; ++m)
      csv += fmt::format("{},{},{},{},{:.0f},{:.0f},{:.4f},{:.4f},{:.6g},{:.6g},{:.6g},{:.6g}\n", r.mesh,
                         r.budget, r.camera, kMethodFiles[m], r.m[m].triangles, r.m[m].xor_px,
                         r.m[m].contour_mean_px, r.m[m].contour_max_px, r.m[m].hausdorff, r.m[m].rms,
                         r.m[m].focus_hausdorff, r.m[m].focus_rms);
  const std::string report =
      report_markdown(o, rows, mesh_info, notes, figures, seconds_since(start), command);
  for (const auto& [file, text] :
       {std::pair{out_dir / "results.csv", csv}, std::pair{out_dir / "REPORT.md", report}}) {
    std::FILE* f = std::fopen(file.c_str(), "wb");
    const bool ok = f && std::fwrite(text.data(), 1, text.size(), f) == text.size();
    if (f) std::fclose(f);
    if (!ok) return fmt::print(stderr, "mtlod-eval: cannot write {}\n", file.string()), 1;
  }
  fmt::print("wrote {} and {} figures in {:.1f} s\n", (out_dir / "REPORT.md").string(), figures.size(),
             seconds_since(start));
  return 0;
}

std::string report_markdown(const ExperimentOptions& o, const std::vector<Row>& rows,
                            const std::vector<std::pair<std::string, std::string>>& mesh_info,
                            const std::vector<std::string>& notes, const std::vector<std::string>& figures,
                            double total_s, const std::string& command) {
  std::string md;
  const auto add = [&](const std::string& s) { md += s, md += '\n'; };
  add("# Evaluation: distance-transform-weighted extraction against uniform extraction and meshoptimizer");
  add("");
  add(fmt::format("Generated by `{}` (from `scripts/evaluate.sh`) in {:.0f} s. Do not edit by hand.", command,
                  total_s));
  add("");
  add("## Setup");
  add("");
  add(fmt::format(
      "- {} cameras per mesh on an orbit around the bounding sphere (azimuth every {:.0f}°, elevation "
      "alternating +25° and −10°, 40° field of view, the sphere filling ~90 % of the view).",
      o.cameras, 360.0 / o.cameras));
  add("- Methods, all from the same Multi-Tessellation (core/build/mt_builder) by budgeted refinement "
      "(core/cut/refine `refine_budget`, worst error/allowed ratio first):");
  add("  - **uniform**: one allowed error everywhere (the ranking is the triangles' own error);");
  add(fmt::format(
      "  - **silhouette-DT**: the papers' step law on the 5-7-11 silhouette transform of a {}×{} view grid "
      "(core/view/view_extract): allowed error ×{} within {} grid px of the external silhouette;",
      o.grid_px, o.grid_px, o.silhouette[1], o.silhouette[0]));
  add(fmt::format(
      "  - **focus-DT**: the same law on the focus transform: ×{} within {:.0f} grid px ({:.0f} % of the "
      "view) of a focus at the centroid of the model's image;",
      o.focus[1], o.focus[0] * o.grid_px, 100 * o.focus[0]));
  add("  - **meshopt**: `meshopt_simplify` (meshoptimizer 0.18, Debian) on the full-resolution mesh, target "
      "index count "
      "3 × budget, no error limit; view-independent, so one result per budget.");
  add("- Equal counts: each MT method is refined to the budget, then all three again to the smallest count, "
      "until the "
      "counts agree (a node adds or removes about two triangles, so this converges within a few rounds). The "
      "tables "
      "give the actual counts (mean over the cameras).");
  add(fmt::format(
      "- Silhouette error: masks of the original and the simplification rasterised at {}×{} (pixel "
      "centres), XOR pixel count, and the mean / max distance between the two contours in pixels (exact "
      "EDT of the other contour; symmetric).",
      o.image_px, o.image_px));
  add(fmt::format(
      "- Object-space error, Metro-style: {} area samples on the original (plus its vertices when it has "
      "at most that many), {} area samples plus the vertices on each simplification; exact point–triangle "
      "distances through a uniform grid; symmetric Hausdorff (max of both directions) and RMS (worse "
      "direction), in % of the original's bounding-box diagonal.",
      o.reference_samples, o.cut_samples));
  add(fmt::format(
      "- Focus-region error: the same restricted to the triangles (of the original and of the "
      "simplification) whose projection comes within {:.0f} image px of the focus, visible or not.",
      o.focus[0] * o.image_px));
  add("- Numbers are means over the cameras. Ratios in the target table are ratios of those means.");
  for (const std::string& n : o.notes) add(fmt::format("- {}", n));
  add("");
  add("| mesh | file | vertices | triangles | MT root triangles | reference samples |");
  add("| --- | --- | ---: | ---: | ---: | ---: |");
  for (const auto& [name, info] : mesh_info) add(fmt::format("| {} | {} |", name, info));
  for (const std::string& n : notes) add(fmt::format("- {}", n));
  add("");

  // Cases: (mesh, budget).
  std::vector<std::pair<std::string, std::size_t>> cases;
  for (const Row& r : rows)
    if (std::find(cases.begin(), cases.end(), std::pair{r.mesh, r.budget}) == cases.end())
      cases.push_back({r.mesh, r.budget});

  struct Target {
    const char* what;
    int method, against;
    double Measure::*field;
    double limit;
  };
  const Target targets[] = {
      {"silhouette XOR, silhouette-DT / uniform", kSilhouette, kUniform, &Measure::xor_px, 0.5},
      {"silhouette XOR, silhouette-DT / meshopt", kSilhouette, kMeshopt, &Measure::xor_px, 0.6},
      {"focus-region Hausdorff, focus-DT / uniform", kFocus, kUniform, &Measure::focus_hausdorff, 0.5},
      {"focus-region RMS, focus-DT / uniform", kFocus, kUniform, &Measure::focus_rms, 0.5},
      {"global Hausdorff, silhouette-DT / uniform", kSilhouette, kUniform, &Measure::hausdorff, 1.3},
      {"global Hausdorff, focus-DT / uniform", kFocus, kUniform, &Measure::hausdorff, 1.3},
  };
  add("## Targets");
  add("");
  add("Each cell: the ratio of the means over the cameras for one mesh and budget; ✓ when it meets the "
      "target.");
  add("");
  std::string header = "| mesh | budget |", rule = "| --- | ---: |", limits = "| **target** | |";
  for (const Target& t : targets)
    header += fmt::format(" {} |", t.what), rule += " ---: |", limits += fmt::format(" ≤ {} |", t.limit);
  add(header);
  add(rule);
  add(limits);
  std::vector<int> met(std::size(targets), 0);
  for (const auto& [mesh, budget] : cases) {
    std::string line = fmt::format("| {} | {} |", mesh, budget);
    for (std::size_t k = 0; k < std::size(targets); ++k) {
      const Target& t = targets[k];
      const double a = mean_of(rows, mesh, budget, t.method, t.field),
                   b = mean_of(rows, mesh, budget, t.against, t.field);
      const double ratio = b > 0 ? a / b : (a > 0 ? INFINITY : 1.0);
      met[k] += ratio <= t.limit;
      line += fmt::format(" {:.2f}{} |", ratio, ratio <= t.limit ? " ✓" : "");
    }
    add(line);
  }
  std::string total = "| **met** | |";
  for (const int m : met) total += fmt::format(" {}/{} |", m, cases.size());
  add(total);
  add("");

  add("## Results per mesh");
  add("");
  add("Means over the cameras. Triangles: actual counts. XOR and contour distances in pixels of the "
      "silhouette image; Hausdorff and RMS in % of the bounding-box diagonal.");
  add("");
  const auto cells = [&](const std::string& mesh, std::size_t budget, double Measure::*field,
                         const char* format, double scale) {
    std::string s;
    for (int m = 0; m < kMethodCount; ++m)
      s += fmt::format(fmt::runtime(format), scale * mean_of(rows, mesh, budget, m, field)) +
           (m + 1 < kMethodCount ? " / " : "");
    return s;
  };
  std::string last_mesh;
  for (std::size_t c = 0; c < cases.size(); ++c) {
    const auto& [mesh, budget] = cases[c];
    if (mesh != last_mesh) {
      add(fmt::format("### {}", mesh));
      add("");
      add("Each cell: uniform / silhouette-DT / focus-DT / meshopt.");
      add("");
      add("| budget | triangles | XOR px | contour mean px | contour max px | Hausdorff % | RMS % | focus "
          "Hausdorff % | "
          "focus RMS % |");
      add("| ---: | --- | --- | --- | --- | --- | --- | --- | --- |");
      last_mesh = mesh;
    }
    add(fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} |", budget,
                    cells(mesh, budget, &Measure::triangles, "{:.0f}", 1),
                    cells(mesh, budget, &Measure::xor_px, "{:.0f}", 1),
                    cells(mesh, budget, &Measure::contour_mean_px, "{:.2f}", 1),
                    cells(mesh, budget, &Measure::contour_max_px, "{:.1f}", 1),
                    cells(mesh, budget, &Measure::hausdorff, "{:.3f}", 100),
                    cells(mesh, budget, &Measure::rms, "{:.4f}", 100),
                    cells(mesh, budget, &Measure::focus_hausdorff, "{:.3f}", 100),
                    cells(mesh, budget, &Measure::focus_rms, "{:.4f}", 100)));
    const bool last_of_mesh = c + 1 == cases.size() || cases[c + 1].first != mesh;
    if (last_of_mesh) add("");
  }

  add("## Figures");
  add("");
  add("Camera 0, smallest budget. Renders: flat shading with the cut's wireframe. XOR: grey = both, blue = "
      "only the "
      "original, red = only the simplification. Hausdorff: the original's vertices coloured by their "
      "distance to the "
      "simplification, blue = 0 to red = the uniform cut's largest (one scale for both images, as in the "
      "paper's "
      "figure 5). Labels: the 5-7-11 silhouette distance of every vertex, blue = 0 to red = 20 grid px.");
  add("");
  for (const std::string& f : figures) add(fmt::format("![{}](figures/{})", f, f));
  add("");
  add("Raw numbers for every camera: [`results.csv`](results.csv).");
  return md;
}

// ---------------------------------------------------------------------------------------------
// image subcommand

struct ImageFlags {
  CameraFlags camera;
  std::string viewport = "512x512";
  std::vector<double> focus;       // normalised viewport coordinates; empty: the centroid of A's image
  double viewing_distance_px = 0;  // 0: the camera's centre of projection
  double e2_deg = 2.3;
  bool flat = false;
  std::string diff_png, renders_prefix;
  double diff_scale = 0.25;
};

int run_image(const std::string& a_path, const std::string& b_path, const ImageFlags& f) {
  auto a = load(a_path);
  if (!a) return fmt::print(stderr, "mtlod-eval: {}\n", a.error().message), 1;
  auto b = load(b_path);
  if (!b) return fmt::print(stderr, "mtlod-eval: {}\n", b.error().message), 1;
  view::GridSize grid;
  const std::uint32_t min_side = 2 * eval::SsimOptions{}.window_radius + 1;
  if (!parse_viewport(f.viewport, grid) || grid.width < min_side || grid.height < min_side ||
      grid.width > view::kMaxGridSide || grid.height > view::kMaxGridSide)
    return fmt::print(stderr, "mtlod-eval: --viewport '{}' is not WxH with sides in [{}, {}]\n", f.viewport,
                      min_side, view::kMaxGridSide),
           2;
  if (!f.focus.empty() && !(f.focus[0] >= 0 && f.focus[0] <= 1 && f.focus[1] >= 0 && f.focus[1] <= 1))
    return fmt::print(stderr, "mtlod-eval: --focus {},{} is outside [0, 1]²\n", f.focus[0], f.focus[1]), 2;
  if (!(f.viewing_distance_px >= 0) || !(f.e2_deg > 0) || !(f.diff_scale > 0))
    return fmt::print(stderr, "mtlod-eval: --viewing-distance-px, --e2 and --diff-scale must be positive\n"),
           2;
  const model::Bounds bounds = model::bounds_of(a->positions);
  auto camera = camera_from_flags(bounds, f.camera, double(grid.width) / grid.height);
  if (!camera) return fmt::print(stderr, "mtlod-eval: {}\n", camera.error().message), 2;
  const view::ViewMapping mapping(*camera, grid);

  // "Shaded with the original normals": A's own (from its file, else area-weighted), handed to B's
  // vertices by position.
  std::vector<float> a_normals = a->normals, b_normals;
  if (a_normals.empty()) {
    a_normals.resize(a->positions.size());
    eval::area_weighted_normals(a->positions, a->triangles, a_normals);
  }
  const std::size_t matched =
      normals_from_original(a->positions, a_normals, b->positions, b->triangles, b_normals);
  ShadedView va, vb;
  render_shaded(mapping, a->positions, a->triangles, f.flat ? std::span<const float>{} : a_normals, va);
  render_shaded(mapping, b->positions, b->triangles, f.flat ? std::span<const float>{} : b_normals, vb);

  std::vector<std::uint8_t> mask_a(grid.cell_count());
  for (std::size_t c = 0; c < mask_a.size(); ++c) mask_a[c] = std::isfinite(va.depth[c]);
  const std::array<float, 2> focus01 = f.focus.empty()
                                           ? focus_point(mask_a, grid)
                                           : std::array<float, 2>{float(f.focus[0]), float(f.focus[1])};
  eval::Foveation foveation;
  foveation.focus_x_px = focus01[0] * float(grid.width);
  foveation.focus_y_px = focus01[1] * float(grid.height);
  foveation.focal_px =
      f.viewing_distance_px > 0 ? f.viewing_distance_px : eval::focal_px_from_fov(grid.height, f.camera.fov);
  foveation.e2_deg = f.e2_deg;
  std::vector<float> weights(grid.cell_count());
  eval::foveation_weights(grid, foveation, weights);
  ImageScratch scratch;
  const ImageMeasure m = measure_image(va, vb, grid, weights, scratch);

  const double diagonal = bounds.diagonal();
  if (f.flat)
    fmt::print("A = {} ({} triangles), B = {} ({} triangles), flat shading\n", a_path, a->triangle_count(),
               b_path, b->triangle_count());
  else
    fmt::print(
        "A = {} ({} triangles), B = {} ({} triangles; {} of its {} vertices shaded with A's normals)\n",
        a_path, a->triangle_count(), b_path, b->triangle_count(), matched, b->vertex_count());
  fmt::print(
      "{}x{} image, {}° vertical field of view, eye {:.1f} px from the image ({:.1f} px/degree at the "
      "centre); focus ({:.3f}, {:.3f}) = pixel ({:.1f}, {:.1f}){}, e2 = {}°\n",
      grid.width, grid.height, f.camera.fov, foveation.focal_px, foveation.focal_px * M_PI / 180, focus01[0],
      focus01[1], foveation.focus_x_px, foveation.focus_y_px,
      f.focus.empty() ? " (centroid of A's image)" : "", f.e2_deg);
  fmt::print(
      "  coverage: A {} px, B {} px, either {} px, XOR {} px; depth where both cover: mean |dz| {:.6g} "
      "({:.4f} % of A's diagonal), max {:.6g} ({:.3f} %)\n",
      va.covered_px, vb.covered_px, m.image.covered_pixels, m.xor_px, m.depth_mean,
      100 * m.depth_mean / diagonal, m.depth_max, 100 * m.depth_max / diagonal);
  fmt::print("  SSIM {:.5f} (covered pixels {:.5f}, foveated {:.5f})\n", m.image.ssim, m.image.ssim_covered,
             m.image.foveated_ssim);
  fmt::print("  MAE  {:.5f} (covered pixels {:.5f}, foveated {:.5f}); luminance in [0, 1]\n", m.image.mae,
             m.image.mae_covered, m.image.foveated_mae);

  if (!f.diff_png.empty()) {
    // |ΔY| on the figures' ramp, blue = 0 to red = diff_scale; white where neither covers.
    std::vector<std::uint8_t> rgb(3 * grid.cell_count(), 255);
    for (std::size_t c = 0; c < grid.cell_count(); ++c) {
      if (!scratch.covered[c]) continue;
      const auto colour = eval::ramp_color(float(std::abs(va.luminance[c] - vb.luminance[c]) / f.diff_scale));
      std::copy(colour.begin(), colour.end(), &rgb[3 * c]);
    }
    if (auto s = io::write_png_rgb(f.diff_png, rgb, grid); !s)
      return fmt::print(stderr, "mtlod-eval: {}\n", s.error().message), 1;
  }
  if (!f.renders_prefix.empty()) {
    for (const auto& [suffix, view] : {std::pair{"-a.png", &va}, std::pair{"-b.png", &vb}})
      if (auto s = io::write_png_rgb(f.renders_prefix + suffix, view->rgb, grid); !s)
        return fmt::print(stderr, "mtlod-eval: {}\n", s.error().message), 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Measure extractions against the original mesh: object-space (Hausdorff, RMS), silhouette (XOR, "
      "contour distance) and focus-region error; run the evaluation experiment."};
  app.require_subcommand(1);

  std::string a, b;
  std::size_t samples = 200000;
  auto* compare = app.add_subcommand("compare", "Hausdorff / mean / RMS between two meshes, both directions");
  compare->add_option("a", a, "original mesh")->required();
  compare->add_option("b", b, "simplified mesh")->required();
  compare->add_option("--samples", samples, "area samples on each mesh (vertices are added)");

  CameraFlags camera;
  std::string xor_png;
  auto* silhouette = app.add_subcommand("silhouette", "silhouette XOR and contour distances from one camera");
  silhouette->add_option("a", a, "original mesh")->required();
  silhouette->add_option("b", b, "simplified mesh")->required();
  add_camera_flags(*silhouette, camera);
  silhouette->add_option("--size", camera.size, "image side in pixels");
  silhouette->add_option("--xor-png", xor_png,
                         "write the two masks as PNG (grey both, red B only, blue A only)");

  ImageFlags image_flags;
  auto* image = app.add_subcommand(
      "image", "render A and B from one camera, shaded with A's normals: SSIM, MAE, foveated SSIM/MAE");
  image->add_option("a", a, "original mesh")->required();
  image->add_option("b", b, "simplified mesh (its vertices A's, in any order)")->required();
  add_camera_flags(*image, image_flags.camera);
  image->add_option("--viewport", image_flags.viewport, "image size WxH in pixels (the camera's aspect)")
      ->capture_default_str();
  image
      ->add_option("--focus", image_flags.focus,
                   "X,Y in normalised viewport coordinates (default: A's centroid)")
      ->delimiter(',')
      ->expected(2);
  image->add_option("--viewing-distance-px", image_flags.viewing_distance_px,
                    "eye to image in pixels, for eccentricity (default: the camera's, (H/2)/tan(fov/2))");
  image->add_option("--e2", image_flags.e2_deg, "eccentricity in degrees at which acuity halves")
      ->capture_default_str();
  image->add_flag("--flat", image_flags.flat, "flat shading from the faces instead of A's vertex normals");
  image->add_option("--dump-diff", image_flags.diff_png, "write |luminance difference| as PNG (ramp)");
  image->add_option("--diff-scale", image_flags.diff_scale, "luminance difference drawn red in --dump-diff")
      ->capture_default_str();
  image->add_option("--dump-renders", image_flags.renders_prefix, "write PREFIX-a.png and PREFIX-b.png");

  ScoreOptions score_options;
  auto* score = app.add_subcommand(
      "score",
      "two renderings given as PNG files: foveated error (1 - foveated SSIM), SSIM, MAE; one JSON line");
  score->add_option("reference", score_options.reference, "the full model's rendering (PNG)")->required();
  score->add_option("candidate", score_options.candidate, "the cut's rendering from the same camera (PNG)")
      ->required();
  score
      ->add_option("--focus", score_options.focus,
                   "X,Y normalised (default: the centroid of the reference's model)")
      ->delimiter(',')
      ->expected(2);
  score->add_option("--fov", score_options.fov_deg, "vertical field of view of the renderings, degrees")
      ->capture_default_str();
  score->add_option("--viewing-distance-px", score_options.viewing_distance_px,
                    "eye to image in pixels, for eccentricity (default: the camera's, (H/2)/tan(fov/2))");
  score->add_option("--e2", score_options.e2_deg, "eccentricity in degrees at which acuity halves")
      ->capture_default_str();
  score->add_option(
      "--background", score_options.background,
      "RRGGBB: pixels of this colour in both images are not the model's (default: the reference's "
      "top-left pixel)");

  ExperimentOptions ex;
  auto* experiment =
      app.add_subcommand("experiment", "the whole study; writes REPORT.md, results.csv, figures/");
  experiment->add_option("--mesh", ex.meshes, "NAME=PATH, repeatable")->required();
  experiment->add_option("--budgets", ex.budgets, "triangle budgets")->delimiter(',');
  experiment->add_option("--cameras", ex.cameras, "cameras per mesh");
  experiment->add_option("--image", ex.image_px, "silhouette image and figure side, pixels");
  experiment->add_option("--grid", ex.grid_px, "view grid side of the distance transforms");
  experiment->add_option("--reference-samples", ex.reference_samples, "area samples on each original");
  experiment->add_option("--cut-samples", ex.cut_samples, "area samples on each simplification");
  experiment->add_option("--silhouette", ex.silhouette, "D,F: step law within D grid px of the silhouette")
      ->delimiter(',')
      ->expected(2);
  experiment->add_option("--focus", ex.focus, "R,F: step law within R (fraction of the view) of the focus")
      ->delimiter(',')
      ->expected(2);
  experiment->add_option("--out-dir", ex.out_dir, "report directory");
  experiment->add_option("--cache-dir", ex.cache_dir, "where MT files are cached");
  experiment->add_option("--note", ex.notes, "a line for the report's setup section, repeatable");
  experiment->add_option("--figures", ex.figure_meshes, "meshes to draw figures for")->delimiter(',');
  FidelityOptions fid;
  auto* fidelity = app.add_subcommand(
      "fidelity",
      "image-space fidelity of each method at equal triangles and equal bytes; writes FIDELITY.md");
  fidelity->add_option("--mesh", fid.meshes, "NAME=PATH, repeatable")->required();
  fidelity->add_option("--budgets", fid.budgets, "triangle budgets")->delimiter(',');
  fidelity->add_option("--cameras", fid.cameras, "cameras per mesh");
  fidelity->add_option("--image", fid.image_px, "rendered image side, pixels");
  fidelity->add_option("--grid", fid.grid_px, "view grid side of the distance transforms");
  fidelity->add_option(
      "--method", fid.methods,
      "NAME=SPEC or a standard method's NAME, repeatable (default: the standard set; see FIDELITY.md "
      "for SPEC)");
  fidelity->add_option("--target", fid.target, "the method the targets are about")->capture_default_str();
  fidelity->add_flag("!--no-equal-triangles", fid.equal_triangles, "compare at equal bytes only");
  fidelity->add_flag("!--no-curves", fid.curves, "no error-against-bytes plots");
  fidelity->add_option("--out-dir", fid.out_dir, "report directory");
  fidelity->add_option("--report", fid.report, "report file name in the directory")->capture_default_str();
  fidelity->add_option("--csv", fid.csv, "raw numbers file name in the directory")->capture_default_str();
  fidelity->add_option("--cache-dir", fid.cache_dir, "where MT files are cached");
  fidelity->add_option("--figures", fid.figure_meshes, "meshes to draw figures for")->delimiter(',');
  fidelity
      ->add_option("--turns", fid.turns,
                   "also score the equal-bytes cuts of uniform, the target and meshopt with the model turned "
                   "by these degrees")
      ->delimiter(',')
      ->capture_default_str();
  fidelity->add_flag_callback(
      "--no-turns", [&fid] { fid.turns.clear(); }, "no turned views");
  fidelity->add_option("--note", fid.notes, "a line for the report's setup section, repeatable");
  GazeStudyOptions gz;
  auto* gaze = app.add_subcommand(
      "gaze",
      "replay a gaze trace: gaze-driven cuts against a uniform cut of the same bytes; writes GAZE.md");
  gaze->add_option("--mesh", gz.meshes, "NAME=PATH, repeatable")->required();
  gaze->add_option("--trace", gz.trace, "CSV time_ms,x,y (default: synthesised fixations and saccades)");
  gaze->add_option("--duration", gz.duration_ms, "synthesised trace length, ms")->capture_default_str();
  gaze->add_option("--hz", gz.hz, "synthesised sample rate and frame rate")->capture_default_str();
  gaze->add_option("--seed", gz.seed, "synthesised trace seed")->capture_default_str();
  gaze->add_option("--latencies", gz.latencies_ms, "gaze-to-screen latencies, ms")->delimiter(',');
  gaze->add_option("--budget", gz.budget, "triangles of the gaze-driven cuts")->capture_default_str();
  gaze->add_option("--image", gz.image_px, "rendered image side, pixels")->capture_default_str();
  gaze->add_option("--near", gz.near_deg, "degrees around the gaze that count as near")
      ->capture_default_str();
  gaze->add_option("--out-dir", gz.out_dir, "report directory");
  gaze->add_option("--report", gz.report, "report file name in the directory")->capture_default_str();
  gaze->add_option("--csv", gz.csv, "per-frame numbers file name in the directory")->capture_default_str();
  gaze->add_option("--cache-dir", gz.cache_dir, "where MT files are cached");
  gaze->add_option("--note", gz.notes, "a line for the report's setup section, repeatable");
  CLI11_PARSE(app, argc, argv);

  if (compare->parsed()) return run_compare(a, b, samples);
  if (silhouette->parsed()) return run_silhouette(a, b, camera, xor_png);
  if (image->parsed()) return run_image(a, b, image_flags);
  if (score->parsed()) return run_score(score_options);
  std::string command = "mtlod-eval";
  for (int i = 1; i < argc; ++i) command += std::string(" ") + argv[i];
  if (fidelity->parsed()) return run_fidelity(fid, command);
  if (gaze->parsed()) return run_gaze_study(gz, command);
  return run_experiment(ex, command);
}
