// Angle-weighted vertex normals (see vertex_normals.hpp).
#include "core/build/vertex_normals.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>

namespace mtlod::core::build {
namespace {

struct Vec {
  double x, y, z;
};
Vec sub(const Vec& a, const Vec& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
Vec cross(const Vec& a, const Vec& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double dot(const Vec& a, const Vec& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
double length(const Vec& a) {
  return std::sqrt(dot(a, a));
}

}  // namespace

bool usable_normal(const float* n) {
  return std::isfinite(n[0]) && std::isfinite(n[1]) && std::isfinite(n[2]) &&
         (n[0] != 0.0f || n[1] != 0.0f || n[2] != 0.0f);
}

void make_unit(float* n) {
  const double l = std::sqrt(double{n[0]} * n[0] + double{n[1]} * n[1] + double{n[2]} * n[2]);
  for (int k = 0; k < 3; ++k) n[k] = static_cast<float>(n[k] / l);
}

void NormalAccumulator::add(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t lo,
                            std::uint32_t hi, bool concurrently) {
  const std::uint32_t v[3] = {a, b, c};
  const bool any = (a >= lo && a < hi) || (b >= lo && b < hi) || (c >= lo && c < hi);
  if (!any) return;
  Vec p[3];
  for (int k = 0; k < 3; ++k) {
    const float* q = positions_.data() + 3 * std::size_t{v[k]};
    p[k] = {q[0], q[1], q[2]};
  }
  // Edge k runs from corner k to corner k + 1. Any two edges' cross product is the normal times
  // twice the area, so the angle at corner k is atan2(twice the area, the dot product of its two
  // edges), robust near 0 and π where acos is not; the angles sum to π, which saves the third
  // atan2. A triangle with an area has no zero-length edge. The angles are computed the same way
  // whichever corners are added, so that the sums do not depend on how the vertices are shared out.
  const Vec e[3] = {sub(p[1], p[0]), sub(p[2], p[1]), sub(p[0], p[2])};
  const Vec n = cross(e[0], e[1]);
  const double area2 = length(n);
  if (!(area2 > 0.0) || !std::isfinite(area2)) return;
  double angle[3];
  angle[0] = std::atan2(area2, -dot(e[0], e[2]));
  angle[1] = std::atan2(area2, -dot(e[1], e[0]));
  angle[2] = std::max(0.0, std::numbers::pi - angle[0] - angle[1]);
  for (int k = 0; k < 3; ++k) {
    if (v[k] < lo || v[k] >= hi) continue;
    const double w = angle[k] * kScale / area2;
    const double x[3] = {w * n.x, w * n.y, w * n.z};
    std::int64_t* s = sums_.data() + 3 * std::size_t{v[k]};
    for (int c = 0; c < 3; ++c) {
      // Rounded half away from zero, as llround, without its library call (|x| < 2^33 here).
      const auto units = static_cast<std::int64_t>(x[c] < 0 ? x[c] - 0.5 : x[c] + 0.5);
      if (concurrently)
        std::atomic_ref<std::int64_t>(s[c]).fetch_add(units, std::memory_order_relaxed);
      else
        s[c] += units;
    }
  }
}

std::size_t NormalAccumulator::finish(std::span<const std::int64_t> sums, std::span<float> normals) {
  std::size_t undirected = 0;
  for (std::size_t i = 0; i + 2 < sums.size(); i += 3) {
    const double x = static_cast<double>(sums[i]), y = static_cast<double>(sums[i + 1]),
                 z = static_cast<double>(sums[i + 2]);
    const double l = std::sqrt(x * x + y * y + z * z);
    float* n = normals.data() + i;
    if (l > 0) {
      n[0] = static_cast<float>(x / l), n[1] = static_cast<float>(y / l), n[2] = static_cast<float>(z / l);
    } else {
      n[0] = 0.0f, n[1] = 0.0f, n[2] = 1.0f;
      ++undirected;
    }
  }
  return undirected;
}

std::vector<float> vertex_normals(std::span<const float> positions,
                                  std::span<const std::uint32_t> triangles) {
  std::vector<std::int64_t> sums(positions.size(), 0);
  NormalAccumulator accumulator(positions, sums);
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
    accumulator.add(triangles[t], triangles[t + 1], triangles[t + 2]);
  std::vector<float> normals(positions.size());
  NormalAccumulator::finish(sums, normals);
  return normals;
}

Result<std::vector<float>> vertex_normals(const model::Mt& mt) {
  std::vector<std::int64_t> sums(mt.positions.size(), 0);
  NormalAccumulator accumulator(mt.positions, sums);
  for (std::uint32_t n = 0; n < mt.node_count(); ++n) {
    if (!mt.require_node(n)) return mt.check_node(n).take_error();
    for (std::uint32_t t = mt.node_triangle_offsets[n]; t < mt.node_triangle_offsets[n + 1]; ++t) {
      if (mt.triangle_remover[t] != model::kNoNode) continue;  // not part of the full-resolution mesh
      accumulator.add(mt.first_corner(model::TriangleId{t}, model::NodeId{n}),
                      mt.triangle_corners[2 * std::size_t{t}], mt.triangle_corners[2 * std::size_t{t} + 1]);
    }
  }
  std::vector<float> normals(mt.positions.size());
  NormalAccumulator::finish(sums, normals);
  return normals;
}

Result<bool> ensure_normals(model::Mt& mt) {
  if (mt.has_normals()) return false;
  MTLOD_TRY(std::vector<float> normals, vertex_normals(mt));
  mt.attach_normals(std::make_shared<const std::vector<float>>(std::move(normals)));
  return true;
}

NormalRepair repair_normals(std::vector<float>& normals, std::span<const float> positions,
                            std::span<const std::uint32_t> triangles) {
  NormalRepair repair;
  repair.had_normals = !normals.empty();
  const std::size_t n = positions.size() / 3;
  if (normals.size() != 3 * n) {
    normals = vertex_normals(positions, triangles);
    repair.computed = n;
    return repair;
  }
  std::size_t bad = 0;
  for (std::size_t v = 0; v < n; ++v) bad += !usable_normal(&normals[3 * v]);
  std::vector<float> computed;
  if (bad) computed = vertex_normals(positions, triangles);
  for (std::size_t v = 0; v < n; ++v) {
    float* own = &normals[3 * v];
    if (!usable_normal(own)) {
      std::copy_n(&computed[3 * v], 3, own);
      continue;
    }
    make_unit(own);
  }
  repair.computed = bad;
  return repair;
}

}  // namespace mtlod::core::build
