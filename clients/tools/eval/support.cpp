#include "clients/tools/eval/support.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <utility>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>

#include "core/build/mt_builder.hpp"
#include "core/eval/render.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "fmt/format.h"

namespace mtlod::eval_tool {

using namespace mtlod::core;
namespace fs = std::filesystem;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

Result<view::Camera> make_camera(const std::array<double, 3>& eye, const std::array<double, 3>& target,
                                 const std::array<double, 3>& up, double fov_deg, double near, double far,
                                 double aspect) {
  const glm::vec3 e(eye[0], eye[1], eye[2]), t(target[0], target[1], target[2]), u(up[0], up[1], up[2]);
  for (int c = 0; c < 3; ++c)
    if (!std::isfinite(e[c]) || !std::isfinite(t[c]) || !std::isfinite(u[c]))
      return make_error(ErrorCode::kInvalidArgument, "camera: --eye, --target and --up must be finite");
  if (glm::length(t - e) <= 0.0f)
    return make_error(ErrorCode::kInvalidArgument, "camera: --eye equals --target");
  if (glm::length(glm::cross(t - e, u)) <= 1e-6f * glm::length(t - e) * glm::length(u))
    return make_error(ErrorCode::kInvalidArgument, "camera: --up is zero or parallel to the view direction");
  if (!(fov_deg > 0.0 && fov_deg < 180.0))
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("camera: --fov {} is outside (0, 180)", fov_deg));
  if (!(near > 0.0 && far > near))
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("camera: near {} / far {} planes invalid", near, far));
  view::Camera camera;
  camera.view = glm::lookAt(e, t, u);
  camera.projection = glm::perspective(glm::radians(float(fov_deg)), float(aspect), float(near), float(far));
  return camera;
}

view::Camera orbit_camera(const model::Bounds& b, int k, int n) {
  const double azimuth = 2.0 * M_PI * k / n, elevation = glm::radians(k % 2 == 0 ? 25.0 : -10.0);
  const double fov = kOrbitFovDeg, distance = b.radius() / std::sin(glm::radians(fov / 2)) / 0.9;
  const glm::vec3 dir(std::cos(elevation) * std::sin(azimuth), std::sin(elevation),
                      std::cos(elevation) * std::cos(azimuth));
  const std::array<float, 3> c = b.centre();
  const glm::vec3 eye = glm::vec3(c[0], c[1], c[2]) + float(distance) * dir;
  auto camera =
      make_camera({eye.x, eye.y, eye.z}, {c[0], c[1], c[2]}, {0, 1, 0}, fov,
                  std::max(1e-3 * distance, distance - 2.0 * b.radius()), distance + 2.0 * b.radius());
  return *camera;  // never degenerate: the direction is never parallel to +y
}

view::Camera turned_camera(const view::Camera& camera, const model::Bounds& b, double degrees) {
  const std::array<float, 3> c = b.centre();
  const glm::vec3 centre(c[0], c[1], c[2]);
  view::Camera turned = camera;
  turned.model = glm::translate(glm::mat4(1.0f), centre) *
                 glm::rotate(glm::mat4(1.0f), glm::radians(float(degrees)), glm::vec3(0, 1, 0)) *
                 glm::translate(glm::mat4(1.0f), -centre) * camera.model;
  return turned;
}

Result<model::Mesh> load(const fs::path& path) {
  MTLOD_TRY(io::LoadedMesh loaded, io::load_mesh(path));
  if (loaded.mesh.triangle_count() == 0)
    return make_error(ErrorCode::kInvalidArgument, path.string() + ": no triangles");
  return std::move(loaded.mesh);
}

void render_shaded(const view::ViewMapping& mapping, std::span<const float> positions,
                   std::span<const std::uint32_t> triangles, std::span<const float> normals,
                   ShadedView& out) {
  const std::size_t n = mapping.grid().cell_count();
  out.rgb.resize(3 * n), out.luminance.resize(n), out.depth.resize(n);
  eval::RenderOptions options;
  options.vertex_normals = normals;
  out.covered_px = eval::render_mesh(mapping, positions, triangles, {}, options, out.rgb, out.depth);
  eval::luminance_from_rgb(out.rgb, out.luminance);
}

ImageMeasure measure_image(const ShadedView& a, const ShadedView& b, view::GridSize grid,
                           std::span<const float> acuity_weights, ImageScratch& scratch) {
  ImageMeasure m;
  scratch.covered.resize(grid.cell_count());
  double depth_sum = 0;
  for (std::size_t c = 0; c < grid.cell_count(); ++c) {
    const bool in_a = std::isfinite(a.depth[c]), in_b = std::isfinite(b.depth[c]);
    scratch.covered[c] = in_a || in_b;
    m.xor_px += in_a != in_b;
    if (in_a && in_b) {
      const double d = std::abs(double(a.depth[c]) - double(b.depth[c]));
      depth_sum += d, m.depth_max = std::max(m.depth_max, d), ++m.both_px;
    }
  }
  m.depth_mean = m.both_px ? depth_sum / double(m.both_px) : 0.0;
  scratch.map.resize(eval::ssim_map_size(grid).cell_count());
  m.image =
      eval::compare_images(a.luminance, b.luminance, grid, scratch.covered, acuity_weights, scratch.map);
  return m;
}

std::size_t normals_from_original(std::span<const float> a_positions, std::span<const float> a_normals,
                                  std::span<const float> b_positions,
                                  std::span<const std::uint32_t> b_triangles, std::vector<float>& b_normals) {
  const auto key = [](std::span<const float> p, std::size_t v) {
    std::array<std::uint32_t, 3> k;
    std::memcpy(k.data(), &p[3 * v], sizeof k);
    return k;
  };
  std::vector<std::pair<std::array<std::uint32_t, 3>, std::uint32_t>> by_position(a_positions.size() / 3);
  for (std::size_t v = 0; v < by_position.size(); ++v)
    by_position[v] = {key(a_positions, v), std::uint32_t(v)};
  std::sort(by_position.begin(), by_position.end());
  b_normals.resize(b_positions.size());
  eval::area_weighted_normals(b_positions, b_triangles, b_normals);
  std::size_t matched = 0;
  for (std::size_t v = 0; v < b_positions.size() / 3; ++v) {
    const auto k = key(b_positions, v);
    const auto it = std::lower_bound(by_position.begin(), by_position.end(), std::pair{k, std::uint32_t{0}});
    if (it == by_position.end() || it->first != k) continue;
    std::copy_n(&a_normals[3 * std::size_t{it->second}], 3, &b_normals[3 * v]);
    ++matched;
  }
  return matched;
}

void fail_study(const Error& error) {
  fmt::print(stderr, "mtlod-eval: {}\n", error.message);
  std::exit(1);
}

Result<model::Mt> cached_mt(const model::Mesh& mesh, const std::string& name, const fs::path& cache_dir) {
  const fs::path path = cache_dir / (name + ".mt");
  if (fs::exists(path)) {
    auto mt = io::read_mt_file(path, io::MtLoad::kRead);
    if (mt && mt->vertex_count() == mesh.vertex_count()) return mt;
  }
  MTLOD_TRY(model::Mt mt, build::build_mt(mesh));
  std::error_code ec;
  fs::create_directories(cache_dir, ec);
  MTLOD_TRY(auto bytes, io::write_mt_file(path, mt));
  (void)bytes;
  return mt;
}

std::array<float, 2> focus_point(std::span<const std::uint8_t> mask, view::GridSize grid) {
  double sx = 0, sy = 0, n = 0;
  for (std::uint32_t j = 0; j < grid.height; ++j)
    for (std::uint32_t i = 0; i < grid.width; ++i)
      if (mask[grid.cell(i, j)]) sx += i + 0.5, sy += j + 0.5, n += 1;
  if (n == 0) return {0.5f, 0.5f};
  double fx = sx / n, fy = sy / n, best = INFINITY;
  std::array<float, 2> out{float(fx / grid.width), float(fy / grid.height)};
  if (mask[grid.cell(std::uint32_t(fx), std::uint32_t(fy))]) return out;
  for (std::uint32_t j = 0; j < grid.height; ++j) {
    for (std::uint32_t i = 0; i < grid.width; ++i) {
      const double d = std::hypot(i + 0.5 - fx, j + 0.5 - fy);
      if (mask[grid.cell(i, j)] && d < best)
        best = d, out = {float((i + 0.5) / grid.width), float((j + 0.5) / grid.height)};
    }
  }
  return out;
}

bool parse_viewport(const std::string& text, view::GridSize& out) {
  unsigned w = 0, h = 0;
  char x = 0, rest = 0;
  const int n = std::sscanf(text.c_str(), "%u%c%u%c", &w, &x, &h, &rest);
  if (n == 1)
    h = w;
  else if (!(n == 3 && (x == 'x' || x == 'X')))
    return false;
  out = {w, h};
  return true;
}

std::size_t draco_payload_bytes(codec::DracoEncoder& encoder, std::span<const float> positions,
                                std::span<const std::uint32_t> triangles,
                                std::vector<std::uint8_t>& payload) {
  codec::DracoInput input;
  input.positions = positions;
  input.triangles = triangles;
  auto stats = encoder.encode(input, codec::DracoOptions{}, payload);
  return stats ? stats->bytes : 0;
}

void near_weights(std::span<const float> acuity, double e2_deg, double near_deg, std::span<float> out) {
  const float threshold = float(eval::acuity_weight(near_deg, e2_deg));
  for (std::size_t c = 0; c < acuity.size(); ++c) out[c] = acuity[c] >= threshold ? acuity[c] : 0.0f;
}

std::vector<std::size_t> usable_budgets(const std::vector<std::size_t>& budgets, const model::Mesh& mesh,
                                        const model::Mt& mt, const std::string& name,
                                        std::vector<std::string>& notes) {
  std::vector<std::size_t> out;
  for (const std::size_t b : budgets) {
    if (b <= mt.root_triangle_count() * 5 / 4 || 2 * b > mesh.triangle_count())
      notes.push_back(fmt::format("{}: budget {} skipped (root {} triangles, input {})", name, b,
                                  mt.root_triangle_count(), mesh.triangle_count()));
    else
      out.push_back(b);
  }
  return out;
}

Result<std::unique_ptr<ShadedModel>> load_shaded_model(const std::string& spec, const fs::path& cache_dir) {
  const auto eq = spec.find('=');
  if (eq == std::string::npos || eq == 0)
    return make_error(ErrorCode::kInvalidArgument, fmt::format("--mesh '{}' is not NAME=PATH", spec));
  auto model = std::make_unique<ShadedModel>();
  model->name = spec.substr(0, eq), model->path = spec.substr(eq + 1);
  MTLOD_TRY(model->mesh, load(model->path));
  auto mt = cached_mt(model->mesh, model->name, cache_dir);
  if (!mt) return make_error(mt.error().code, fmt::format("{}: {}", model->name, mt.error().message));
  model->mt = std::move(*mt);
  const model::Mesh& mesh = model->mesh;
  model->bounds = model::bounds_of(mesh.positions);
  model->normals = mesh.normals;
  if (model->normals.size() != mesh.positions.size()) {
    model->normals.assign(mesh.positions.size(), 0.0f);
    eval::area_weighted_normals(mesh.positions, mesh.triangles, model->normals);
  }
  normals_from_original(mesh.positions, model->normals, model->mt.positions, {}, model->mt_normals);
  model->mt.normals = model->mt_normals;
  return model;
}

}  // namespace mtlod::eval_tool
