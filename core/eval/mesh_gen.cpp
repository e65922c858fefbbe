// Synthetic meshes (see mesh_gen.hpp). Vertices are indexed from integer lattice coordinates, never
// welded by float position, so shared edges are exact and every mesh is watertight by construction.
#include "core/eval/mesh_gen.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>
#include <vector>

namespace mtlod::core::eval {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// Smooth deterministic noise on a direction or point: a few sine waves with seeded phases.
// Cheap, band-limited, and the same for the same input on every machine.
float wave_noise(float x, float y, float z, std::uint32_t seed) {
  float sum = 0.0f, amplitude = 1.0f, frequency = 2.0f;
  std::uint32_t h = seed * 2654435761u + 12345u;
  for (int octave = 0; octave < 4; ++octave) {
    h = h * 1664525u + 1013904223u;
    const float phase = static_cast<float>(h >> 8) * (1.0f / 16777216.0f) * 2.0f * kPi;
    sum += amplitude * std::sin(frequency * (x + 0.7f * y) + phase) *
           std::cos(frequency * (z - 0.4f * x) + 1.3f * phase);
    amplitude *= 0.5f;
    frequency *= 2.1f;
  }
  return sum;
}

void add_triangle(model::Mesh& mesh, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  mesh.triangles.insert(mesh.triangles.end(), {a, b, c});
}

std::uint32_t add_vertex(model::Mesh& mesh, float x, float y, float z) {
  const auto id = static_cast<std::uint32_t>(mesh.vertex_count());
  mesh.positions.insert(mesh.positions.end(), {x, y, z});
  return id;
}

model::Mesh generate_sphere(const GenerateOptions& o) {
  // Six n×n faces of a cube, 2 triangles per quad: 12·n² triangles.
  const auto n = static_cast<std::uint32_t>(std::max(1.0, std::round(std::sqrt(o.target_triangles / 12.0))));
  const std::uint32_t side = n + 1;
  // Lattice points (i, j, k) in [0, n]³ on the cube's surface get ids through a dense table.
  std::vector<std::uint32_t> id(static_cast<std::size_t>(side) * side * side, UINT32_MAX);
  model::Mesh mesh;
  mesh.positions.reserve(3 * (6 * std::size_t{n} * n + 2));
  mesh.triangles.reserve(3 * 12 * std::size_t{n} * n);
  auto vertex = [&](std::uint32_t i, std::uint32_t j, std::uint32_t k) {
    std::uint32_t& slot = id[(std::size_t{i} * side + j) * side + k];
    if (slot == UINT32_MAX) {
      float x = 2.0f * i / n - 1.0f, y = 2.0f * j / n - 1.0f, z = 2.0f * k / n - 1.0f;
      const float len = std::sqrt(x * x + y * y + z * z);
      x /= len, y /= len, z /= len;
      const float r = 1.0f + o.noise * wave_noise(x, y, z, o.seed);
      slot = add_vertex(mesh, r * x, r * y, r * z);
    }
    return slot;
  };
  // Each face: a fixed axis at 0 or n, two running axes (u, v) ordered so that u × v points outward.
  for (int axis = 0; axis < 3; ++axis) {
    for (int high = 0; high < 2; ++high) {
      const int ua = (axis + 1) % 3, va = (axis + 2) % 3;
      for (std::uint32_t u = 0; u < n; ++u) {
        for (std::uint32_t v = 0; v < n; ++v) {
          std::uint32_t c[4];
          const std::uint32_t du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
          for (int q = 0; q < 4; ++q) {
            std::uint32_t p[3];
            p[axis] = high ? n : 0;
            p[ua] = u + du[q];
            p[va] = v + dv[q];
            c[q] = vertex(p[0], p[1], p[2]);
          }
          if (high) {
            add_triangle(mesh, c[0], c[1], c[2]);
            add_triangle(mesh, c[0], c[2], c[3]);
          } else {
            add_triangle(mesh, c[0], c[2], c[1]);
            add_triangle(mesh, c[0], c[3], c[2]);
          }
        }
      }
    }
  }
  return mesh;
}

model::Mesh generate_terrain(const GenerateOptions& o) {
  // n×n samples, 2·(n−1)² triangles over [−1, 1]², heights from layered waves.
  const auto n =
      static_cast<std::uint32_t>(std::max(2.0, std::round(std::sqrt(o.target_triangles / 2.0)) + 1));
  model::Mesh mesh;
  mesh.positions.reserve(3 * std::size_t{n} * n);
  mesh.triangles.reserve(6 * std::size_t{n - 1} * (n - 1));
  for (std::uint32_t j = 0; j < n; ++j) {
    for (std::uint32_t i = 0; i < n; ++i) {
      const float x = 2.0f * i / (n - 1) - 1.0f, y = 2.0f * j / (n - 1) - 1.0f;
      // Broad hills from low frequencies plus the noise layer; noise = 0 still leaves hills.
      const float hills = 0.25f * std::sin(2.1f * x + 0.3f) * std::cos(1.7f * y - 0.2f);
      add_vertex(mesh, x, y, hills + 2.0f * o.noise * wave_noise(x, y, 0.5f, o.seed));
    }
  }
  for (std::uint32_t j = 0; j + 1 < n; ++j) {
    for (std::uint32_t i = 0; i + 1 < n; ++i) {
      const std::uint32_t a = j * n + i, b = a + 1, c = a + n + 1, d = a + n;
      add_triangle(mesh, a, b, c);  // z up: counter-clockwise seen from above
      add_triangle(mesh, a, c, d);
    }
  }
  return mesh;
}

model::Mesh generate_shell(const GenerateOptions& o) {
  // A circle of radius rho(u) swept along a logarithmic spiral of radius R(u) descending the axis:
  // both grow as e^(b·u), so whorls are similar, like a real shell. u runs over `kTurns` turns.
  constexpr float kTurns = 3.5f;
  constexpr float kGrowth = 0.18f;  // b: each turn scales by e^(2π·b) ≈ 3.1
  const float u_max = kTurns * 2.0f * kPi;
  // nu rings × nv segments: 2·nv·(nu−1) tube triangles + 2·nv cap triangles; rings ≈ 6× segments
  // because the tube is long.
  const double t = static_cast<double>(std::max<std::size_t>(o.target_triangles, 64));
  const auto nv = static_cast<std::uint32_t>(std::max(3.0, std::round(std::sqrt(t / 12.0))));
  const auto nu = static_cast<std::uint32_t>(std::max(2.0, std::round((t - 2.0 * nv) / (2.0 * nv)) + 1));
  model::Mesh mesh;
  mesh.positions.reserve(3 * (std::size_t{nu} * nv + 2));
  mesh.triangles.reserve(3 * (2 * std::size_t{nv} * nu + 2 * nv));
  const float scale = std::exp(-kGrowth * u_max);  // largest whorl ≈ unit size
  auto centre = [&](float u, float& radius, float& rho, float& height) {
    const float g = scale * std::exp(kGrowth * u);
    radius = 0.55f * g;
    rho = 0.42f * g;
    height = -1.1f * g;
  };
  for (std::uint32_t k = 0; k < nu; ++k) {
    const float u = u_max * k / (nu - 1);
    float radius, rho, height;
    centre(u, radius, rho, height);
    for (std::uint32_t s = 0; s < nv; ++s) {
      const float v = 2.0f * kPi * s / nv;
      const float bump = 1.0f + o.noise * wave_noise(u * 0.3f, std::cos(v), std::sin(v), o.seed);
      const float r = radius + bump * rho * std::cos(v);
      add_vertex(mesh, r * std::cos(u), r * std::sin(u), height + bump * rho * std::sin(v));
    }
  }
  for (std::uint32_t k = 0; k + 1 < nu; ++k) {
    for (std::uint32_t s = 0; s < nv; ++s) {
      const std::uint32_t a = k * nv + s, b = k * nv + (s + 1) % nv, c = b + nv, d = a + nv;
      add_triangle(mesh, a, c, b);
      add_triangle(mesh, a, d, c);
    }
  }
  // Caps: the apex ring closes onto its centre, the aperture ring onto its centre.
  float radius, rho, height;
  centre(0.0f, radius, rho, height);
  const std::uint32_t apex = add_vertex(mesh, radius, 0.0f, height);
  centre(u_max, radius, rho, height);
  const std::uint32_t mouth = add_vertex(mesh, radius * std::cos(u_max), radius * std::sin(u_max), height);
  const std::uint32_t last = (nu - 1) * nv;
  for (std::uint32_t s = 0; s < nv; ++s) {
    add_triangle(mesh, apex, s, (s + 1) % nv);
    add_triangle(mesh, mouth, last + (s + 1) % nv, last + s);
  }
  return mesh;
}

}  // namespace

bool parse_shape(std::string_view name, Shape& shape) {
  if (name == "sphere")
    shape = Shape::kSphere;
  else if (name == "terrain")
    shape = Shape::kTerrain;
  else if (name == "shell")
    shape = Shape::kShell;
  else
    return false;
  return true;
}

namespace {

// Each channel follows one axis across the bounding box: smooth, and different at every vertex.
void colour_by_position(model::Mesh& mesh) {
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], mesh.positions[i]);
    hi[i % 3] = std::max(hi[i % 3], mesh.positions[i]);
  }
  mesh.colors.resize(mesh.positions.size());
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    const int k = static_cast<int>(i % 3);
    const float t = hi[k] > lo[k] ? (mesh.positions[i] - lo[k]) / (hi[k] - lo[k]) : 0.5f;
    mesh.colors[i] = static_cast<std::uint8_t>(std::lround(255.0f * t));
  }
}

model::Mesh generate_shape(const GenerateOptions& options) {
  switch (options.shape) {
    case Shape::kSphere:
      return generate_sphere(options);
    case Shape::kTerrain:
      return generate_terrain(options);
    case Shape::kShell:
      return generate_shell(options);
  }
  assert(false && "unknown shape");
  return {};
}

}  // namespace

model::Mesh generate_mesh(const GenerateOptions& options) {
  model::Mesh mesh = generate_shape(options);
  if (options.colors) colour_by_position(mesh);
  return mesh;
}

}  // namespace mtlod::core::eval
