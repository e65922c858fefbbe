// Metro-style surface sampling and nearest-triangle distances (see surface_metrics.hpp).
#include "core/eval/surface_metrics.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "core/model/bounds.hpp"

namespace mtlod::core::eval {
namespace {

// splitmix64: a tiny generator whose sequence is the same on every platform and standard library
// (std:: distributions are not), so a seed names one sample set.
struct SplitMix64 {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return double(next() >> 11) * 0x1.0p-53; }  // [0, 1)
};

void load(std::span<const float> positions, std::uint32_t v, double out[3]) {
  for (int c = 0; c < 3; ++c) out[c] = positions[3 * std::size_t{v} + c];
}

double dot(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

double triangle_area(const double a[3], const double b[3], const double c[3]) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  return 0.5 * std::sqrt(dot(n, n));
}

double squared_distance(const double p[3], const double q[3]) {
  const double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
  return dot(d, d);
}

double point_segment_squared(const double p[3], const double a[3], const double b[3]) {
  const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  const double len2 = dot(ab, ab);
  const double t = len2 > 0 ? std::clamp(dot(ap, ab) / len2, 0.0, 1.0) : 0.0;
  const double q[3] = {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
  return squared_distance(p, q);
}

}  // namespace

void sample_surface(std::span<const float> positions, std::span<const std::uint32_t> triangles,
                    std::span<const std::uint8_t> triangle_mask, const SamplingOptions& options,
                    SurfaceSamples& out) {
  assert(triangles.size() % 3 == 0);
  assert(triangle_mask.empty() || triangle_mask.size() == triangles.size() / 3);
  out.points.clear();
  out.triangle_ids.clear();
  const std::size_t triangle_count = triangles.size() / 3;
  const auto selected = [&](std::size_t t) { return triangle_mask.empty() || triangle_mask[t] != 0; };

  if (options.include_vertices) {
    std::vector<std::uint8_t> taken(positions.size() / 3, 0);
    for (std::size_t t = 0; t < triangle_count; ++t) {
      if (!selected(t)) continue;
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t v = triangles[3 * t + k];
        if (taken[v]) continue;
        taken[v] = 1;
        out.points.insert(out.points.end(), &positions[3 * std::size_t{v}],
                          &positions[3 * std::size_t{v} + 3]);
        out.triangle_ids.push_back(static_cast<std::uint32_t>(t));
      }
    }
  }
  if (options.area_samples == 0) return;

  // Cumulative areas of the selected triangles; a sample picks its triangle by binary search.
  std::vector<double> cumulative(triangle_count);
  double total = 0.0;
  for (std::size_t t = 0; t < triangle_count; ++t) {
    if (selected(t)) {
      double a[3], b[3], c[3];
      load(positions, triangles[3 * t], a), load(positions, triangles[3 * t + 1], b),
          load(positions, triangles[3 * t + 2], c);
      total += triangle_area(a, b, c);
    }
    cumulative[t] = total;
  }
  if (!(total > 0.0)) return;
  SplitMix64 rng{options.seed};
  out.points.reserve(out.points.size() + 3 * options.area_samples);
  out.triangle_ids.reserve(out.triangle_ids.size() + options.area_samples);
  for (std::size_t s = 0; s < options.area_samples; ++s) {
    const double target = rng.uniform() * total;
    const std::size_t t = std::min<std::size_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), target) - cumulative.begin(),
        triangle_count - 1);
    // Uniform point in a triangle: fold the unit square onto the triangle (Turk, Graphics Gems I).
    double u = rng.uniform(), v = rng.uniform();
    if (u + v > 1.0) u = 1.0 - u, v = 1.0 - v;
    double a[3], b[3], c[3];
    load(positions, triangles[3 * t], a), load(positions, triangles[3 * t + 1], b),
        load(positions, triangles[3 * t + 2], c);
    for (int k = 0; k < 3; ++k)
      out.points.push_back(static_cast<float>(a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k])));
    out.triangle_ids.push_back(static_cast<std::uint32_t>(t));
  }
}

double point_triangle_distance(const double p[3], const double a[3], const double b[3], const double c[3]) {
  const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return std::sqrt(squared_distance(p, a));
  const double bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]};
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return std::sqrt(squared_distance(p, b));
  const double cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return std::sqrt(squared_distance(p, c));
  const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
  const double denom = va + vb + vc;
  // A degenerate (collinear) triangle has no face region: its nearest point lies on an edge.
  if (!(denom > 0) || !std::isfinite(1.0 / denom)) {
    return std::sqrt(std::min(
        {point_segment_squared(p, a, b), point_segment_squared(p, b, c), point_segment_squared(p, c, a)}));
  }
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return std::sqrt(point_segment_squared(p, a, b));
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return std::sqrt(point_segment_squared(p, a, c));
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return std::sqrt(point_segment_squared(p, b, c));
  const double v = vb / denom, w = vc / denom;
  const double q[3] = {a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w,
                       a[2] + ab[2] * v + ac[2] * w};
  return std::sqrt(squared_distance(p, q));
}

TriangleIndex::TriangleIndex(std::span<const float> positions, std::span<const std::uint32_t> triangles)
    : positions_(positions), triangles_(triangles) {
  assert(triangles.size() % 3 == 0);
  const std::size_t count = triangles.size() / 3;
  stamp_.assign(count, 0);
  cell_offsets_.assign(2, 0);
  if (count == 0) return;
  const model::Bounds box = model::bounds_of(positions, triangles);
  const std::array<double, 3> lo = model::to_double(box.lo), hi = model::to_double(box.hi);
  // Cubic cells sized to the triangles (twice the square root of the mean area), so a cell on the
  // surface holds a few triangles whatever the volume around the surface; the cell count is capped
  // at 8 per triangle (and 1024 per side) by growing the cells.
  double area = 0.0;
  for (std::size_t t = 0; t < count; ++t) {
    double a[3], b[3], c[3];
    load(positions, triangles[3 * t], a), load(positions, triangles[3 * t + 1], b),
        load(positions, triangles[3 * t + 2], c);
    area += triangle_area(a, b, c);
  }
  const double extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30});
  cell_size_ = std::max(2.0 * std::sqrt(area / double(count)), 1e-3 * extent);
  const auto cells_for = [&](double h) {
    double n = 1.0;
    for (int c = 0; c < 3; ++c) n *= std::min(1024.0, std::floor((hi[c] - lo[c]) / h) + 1.0);
    return n;
  };
  while (cells_for(cell_size_) > 8.0 * double(count) + 64.0) cell_size_ *= 1.25;
  std::size_t cells = 1;
  for (int c = 0; c < 3; ++c) {
    origin_[c] = lo[c];
    dims_[c] = static_cast<std::uint32_t>(std::min(1024.0, std::floor((hi[c] - lo[c]) / cell_size_) + 1.0));
    cells *= dims_[c];
  }
  const auto cell_range = [&](std::size_t t, std::uint32_t first[3], std::uint32_t last[3]) {
    for (int c = 0; c < 3; ++c) {
      double tlo = INFINITY, thi = -INFINITY;
      for (int k = 0; k < 3; ++k) {
        const double x = positions[3 * std::size_t{triangles[3 * t + k]} + c];
        tlo = std::min(tlo, x), thi = std::max(thi, x);
      }
      first[c] = static_cast<std::uint32_t>(std::clamp((tlo - origin_[c]) / cell_size_, 0.0, dims_[c] - 1.0));
      last[c] = static_cast<std::uint32_t>(std::clamp((thi - origin_[c]) / cell_size_, 0.0, dims_[c] - 1.0));
    }
  };
  // Two passes (count, then fill) into CSR.
  cell_offsets_.assign(cells + 1, 0);
  std::uint32_t first[3], last[3];
  for (std::size_t t = 0; t < count; ++t) {
    cell_range(t, first, last);
    for (std::uint32_t k = first[2]; k <= last[2]; ++k)
      for (std::uint32_t j = first[1]; j <= last[1]; ++j)
        for (std::uint32_t i = first[0]; i <= last[0]; ++i)
          ++cell_offsets_[(std::size_t{k} * dims_[1] + j) * dims_[0] + i + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) cell_offsets_[c + 1] += cell_offsets_[c];
  cell_triangles_.resize(cell_offsets_[cells]);
  std::vector<std::uint32_t> fill(cell_offsets_.begin(), cell_offsets_.end() - 1);
  for (std::size_t t = 0; t < count; ++t) {
    cell_range(t, first, last);
    for (std::uint32_t k = first[2]; k <= last[2]; ++k)
      for (std::uint32_t j = first[1]; j <= last[1]; ++j)
        for (std::uint32_t i = first[0]; i <= last[0]; ++i)
          cell_triangles_[fill[(std::size_t{k} * dims_[1] + j) * dims_[0] + i]++] =
              static_cast<std::uint32_t>(t);
  }
}

void TriangleIndex::visit_cell(std::uint32_t i, std::uint32_t j, std::uint32_t k, const double p[3],
                               double& best) {
  const std::size_t cell = (std::size_t{k} * dims_[1] + j) * dims_[0] + i;
  for (std::uint32_t s = cell_offsets_[cell]; s < cell_offsets_[cell + 1]; ++s) {
    const std::uint32_t t = cell_triangles_[s];
    if (stamp_[t] == query_) continue;
    stamp_[t] = query_;
    double a[3], b[3], c[3];
    load(positions_, triangles_[3 * std::size_t{t}], a),
        load(positions_, triangles_[3 * std::size_t{t} + 1], b),
        load(positions_, triangles_[3 * std::size_t{t} + 2], c);
    best = std::min(best, point_triangle_distance(p, a, b, c));
  }
}

double TriangleIndex::distance(float x, float y, float z) {
  if (triangles_.empty()) return std::numeric_limits<double>::infinity();
  if (++query_ == 0) {  // the stamp wrapped: forget every old stamp
    std::fill(stamp_.begin(), stamp_.end(), 0);
    query_ = 1;
  }
  const double p[3] = {x, y, z};
  // The query's cell, clamped into the grid. A cell r rings away is at least (r − 1) cells from p,
  // also when p lies outside the grid, so the search may stop once that exceeds the best distance.
  int centre[3], reach = 0;
  for (int c = 0; c < 3; ++c) {
    const double f = std::clamp(std::floor((p[c] - origin_[c]) / cell_size_), 0.0, dims_[c] - 1.0);
    centre[c] = static_cast<int>(f);
    reach = std::max({reach, centre[c], int(dims_[c]) - 1 - centre[c]});
  }
  double best = std::numeric_limits<double>::infinity();
  for (int r = 0; r <= reach; ++r) {
    if (r > 0 && double(r - 1) * cell_size_ > best) break;
    for (int dk = -r; dk <= r; ++dk) {
      const int k = centre[2] + dk;
      if (k < 0 || k >= int(dims_[2])) continue;
      for (int dj = -r; dj <= r; ++dj) {
        const int j = centre[1] + dj;
        if (j < 0 || j >= int(dims_[1])) continue;
        // Inside the shell only the two end cells of the row belong to ring r.
        const bool on_shell = std::abs(dk) == r || std::abs(dj) == r;
        for (int di = -r; di <= r; di += (on_shell || r == 0) ? 1 : 2 * r) {
          const int i = centre[0] + di;
          if (i < 0 || i >= int(dims_[0])) continue;
          // Skip a cell whose box is farther than the best distance (the outermost cells reach to
          // infinity: they hold whatever the clamping put there).
          const int idx[3] = {i, j, k};
          double gap2 = 0.0;
          for (int c = 0; c < 3; ++c) {
            const double lo = idx[c] == 0 ? -INFINITY : origin_[c] + idx[c] * cell_size_;
            const double hi = idx[c] == int(dims_[c]) - 1 ? INFINITY : origin_[c] + (idx[c] + 1) * cell_size_;
            const double gap = p[c] < lo ? lo - p[c] : (p[c] > hi ? p[c] - hi : 0.0);
            gap2 += gap * gap;
          }
          if (gap2 > best * best) continue;
          visit_cell(std::uint32_t(i), std::uint32_t(j), std::uint32_t(k), p, best);
        }
      }
    }
  }
  return best;
}

DistanceStats sample_distances(const SurfaceSamples& samples, TriangleIndex& to,
                               std::span<float> per_sample) {
  assert(per_sample.empty() || per_sample.size() == samples.size());
  DistanceStats stats;
  double sum = 0.0, sum2 = 0.0;
  for (std::size_t s = 0; s < samples.size(); ++s) {
    const double d = to.distance(samples.points[3 * s], samples.points[3 * s + 1], samples.points[3 * s + 2]);
    if (!per_sample.empty()) per_sample[s] = static_cast<float>(d);
    stats.max = std::max(stats.max, d);
    sum += d, sum2 += d * d;
  }
  stats.samples = samples.size();
  if (stats.samples > 0)
    stats.mean = sum / double(stats.samples), stats.rms = std::sqrt(sum2 / double(stats.samples));
  return stats;
}

DistanceStats sample_distances_masked(const SurfaceSamples& samples,
                                      std::span<const std::uint8_t> triangle_mask, TriangleIndex& to) {
  DistanceStats stats;
  double sum = 0.0, sum2 = 0.0;
  for (std::size_t s = 0; s < samples.size(); ++s) {
    if (!triangle_mask.empty() && triangle_mask[samples.triangle_ids[s]] == 0) continue;
    const double d = to.distance(samples.points[3 * s], samples.points[3 * s + 1], samples.points[3 * s + 2]);
    stats.max = std::max(stats.max, d);
    sum += d, sum2 += d * d;
    ++stats.samples;
  }
  if (stats.samples > 0)
    stats.mean = sum / double(stats.samples), stats.rms = std::sqrt(sum2 / double(stats.samples));
  return stats;
}

SurfaceError compare_surfaces(std::span<const float> positions_a, std::span<const std::uint32_t> triangles_a,
                              std::span<const float> positions_b, std::span<const std::uint32_t> triangles_b,
                              const SamplingOptions& options) {
  SurfaceSamples samples_a, samples_b;
  sample_surface(positions_a, triangles_a, {}, options, samples_a);
  SamplingOptions options_b = options;
  options_b.seed = options.seed + 1;
  sample_surface(positions_b, triangles_b, {}, options_b, samples_b);
  TriangleIndex index_a(positions_a, triangles_a), index_b(positions_b, triangles_b);
  return {sample_distances(samples_a, index_b), sample_distances(samples_b, index_a)};
}

}  // namespace mtlod::core::eval
