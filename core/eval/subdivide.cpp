// Streaming regular subdivision with noise displacement (see subdivide.hpp). The base's edge table
// is an open-addressing hash of unordered id pairs, filled face by face so that edge ids follow
// first use and stay spatially coherent in the output; it is freed once the edges are numbered.
#include "core/eval/subdivide.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <numeric>

namespace mtlod::core::eval {
namespace {

constexpr std::uint64_t kEmptyKey = UINT64_MAX;  // no pair of 32-bit ids packs to this
constexpr int kOctaves = 4;

// murmur3's 64-bit finaliser: every input bit reaches every output bit.
std::uint64_t mix(std::uint64_t h) {
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ull;
  h ^= h >> 33;
  return h;
}

// Value at an integer lattice point, uniform in [-1, 1).
double lattice_value(std::int64_t x, std::int64_t y, std::int64_t z, std::uint64_t key) {
  const std::uint64_t h = mix(key ^ (static_cast<std::uint64_t>(x) * 0x9E3779B97F4A7C15ull) ^
                              (static_cast<std::uint64_t>(y) * 0xC2B2AE3D27D4EB4Full) ^
                              (static_cast<std::uint64_t>(z) * 0x165667B19E3779F9ull));
  return static_cast<double>(h >> 11) * 0x1p-52 - 1.0;
}

// Quintic fade: C² across lattice cells, so the surface has no creases along cell faces.
double fade(double t) {
  return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}

// Value noise: a convex combination of the eight surrounding lattice values, so within [-1, 1].
double value_noise(double x, double y, double z, std::uint64_t key) {
  // Beyond ±2^50 lattice cells a double has no fraction left; clamping keeps the integer
  // conversion defined (the noise is then flat there).
  constexpr double kLimit = 0x1p50;
  x = std::clamp(x, -kLimit, kLimit), y = std::clamp(y, -kLimit, kLimit), z = std::clamp(z, -kLimit, kLimit);
  const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy),
             iz = static_cast<std::int64_t>(fz);
  const double u = fade(x - fx), v = fade(y - fy), w = fade(z - fz);
  double along_x[4];
  for (int c = 0; c < 4; ++c) {
    const std::int64_t cy = iy + (c & 1), cz = iz + (c >> 1);
    const double a = lattice_value(ix, cy, cz, key), b = lattice_value(ix + 1, cy, cz, key);
    along_x[c] = a + (b - a) * u;
  }
  const double y0 = along_x[0] + (along_x[1] - along_x[0]) * v;
  const double y1 = along_x[2] + (along_x[3] - along_x[2]) * v;
  return y0 + (y1 - y0) * w;
}

// Octaves of halving amplitude and doubling frequency, divided by the amplitude sum: within [-1, 1].
// Each octave has its own lattice (key) and a seeded offset, so octaves do not share lattice points.
double fractal_noise(double x, double y, double z, std::uint32_t seed) {
  double sum = 0.0, weight = 1.0, total = 0.0, frequency = 1.0;
  for (int octave = 0; octave < kOctaves; ++octave) {
    const std::uint64_t key = mix((std::uint64_t{seed} << 8) | static_cast<std::uint64_t>(octave));
    const double offset = static_cast<double>(key >> 40) * 0x1p-14;  // up to 1024 cells
    sum += weight * value_noise(x * frequency + offset, y * frequency - offset, z * frequency + offset, key);
    total += weight;
    weight *= 0.5;
    frequency *= 2.0;
  }
  return sum / total;
}

const float* vertex(const std::vector<float>& positions, std::uint32_t v) {
  return &positions[3 * std::size_t{v}];
}

// Lexicographic position order with ties broken by id: edges that coincide in space (a crack
// between duplicate vertices) are cut in the same direction, so their cuts are exact duplicates.
bool comes_first(const std::vector<float>& positions, std::uint32_t a, std::uint32_t b) {
  const float* pa = vertex(positions, a);
  const float* pb = vertex(positions, b);
  for (int c = 0; c < 3; ++c) {
    if (pa[c] != pb[c]) return pa[c] < pb[c];
  }
  return a <= b;
}

// Fixed-size output buffers, flushed to the sink when full.
class VertexChunk {
 public:
  VertexChunk(SubdivisionSink& sink, std::size_t capacity, bool colors)
      : sink_(sink), capacity_(capacity), colors_(colors) {
    positions_.reserve(3 * capacity);
    if (colors) colors_out_.reserve(3 * capacity);
  }
  float* add(const std::uint8_t* color) {
    if (colors_) colors_out_.insert(colors_out_.end(), color, color + 3);
    positions_.resize(positions_.size() + 3);
    return &positions_[positions_.size() - 3];
  }
  bool full() const { return positions_.size() == 3 * capacity_; }
  Status flush() {
    if (positions_.empty()) return Ok{};
    Status status = sink_.vertices(positions_, colors_out_);
    positions_.clear();
    colors_out_.clear();
    return status;
  }

 private:
  SubdivisionSink& sink_;
  std::size_t capacity_;
  bool colors_;
  std::vector<float> positions_;
  std::vector<std::uint8_t> colors_out_;
};

std::uint8_t to_color(float c) {
  return static_cast<std::uint8_t>(std::clamp(std::lround(c), 0l, 255l));
}

}  // namespace

Subdivider::Subdivider(const model::Mesh& base, const SubdivideOptions& options)
    : base_(base), options_(options) {
  assert(options.split >= 1 && options.chunk_vertices >= 1 && options.chunk_triangles >= 1);
  assert(base.triangle_count() <= UINT32_MAX / 3);  // edge ids are 32-bit
  const std::size_t vertex_count = base.vertex_count(), triangle_count = base.triangle_count();
  number_edges();
  const std::size_t edge_count = edge_vertices_.size() / 2;

  const std::uint64_t n = options.split;
  counts_.base_vertices = vertex_count;
  counts_.base_edges = edge_count;
  counts_.base_triangles = triangle_count;
  counts_.vertices = vertex_count + edge_count * (n - 1) + triangle_count * ((n - 1) * (n - 2) / 2);
  counts_.triangles = triangle_count * n * n;

  measure_edges();
  compute_normals();
}

void Subdivider::number_edges() {
  const model::Mesh& base = base_;
  const std::vector<float>& p = base.positions;
  const std::size_t triangle_count = base.triangle_count();
  // Edge table. Capacity 4.5 slots per triangle keeps the load at or below 2/3 even when no edge
  // is shared (3 edges per triangle), and near 1/3 on a closed mesh (1.5).
  const std::size_t capacity = std::bit_ceil(std::max<std::size_t>(16, triangle_count * 9 / 2));
  const int shift = 64 - std::countr_zero(capacity);
  {
    std::vector<std::uint64_t> keys(capacity, kEmptyKey);
    std::vector<std::uint32_t> ids(capacity);
    triangle_edges_.resize(3 * triangle_count);
    for (std::size_t t = 0; t < triangle_count; ++t) {
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = base.triangles[3 * t + k], b = base.triangles[3 * t + (k + 1) % 3];
        assert(a < base.vertex_count() && b < base.vertex_count());
        const std::uint64_t key = (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
        std::size_t slot = (key * 0x9E3779B97F4A7C15ull) >> shift;
        while (keys[slot] != kEmptyKey && keys[slot] != key) slot = (slot + 1) & (capacity - 1);
        if (keys[slot] == kEmptyKey) {
          keys[slot] = key;
          ids[slot] = static_cast<std::uint32_t>(edge_vertices_.size() / 2);
          const bool a_first = comes_first(p, a, b);
          edge_vertices_.push_back(a_first ? a : b);
          edge_vertices_.push_back(a_first ? b : a);
        }
        triangle_edges_[3 * t + k] = ids[slot];
      }
    }
  }
  edge_vertices_.shrink_to_fit();
}

void Subdivider::measure_edges() {
  const std::vector<float>& p = base_.positions;
  const std::size_t edge_count = edge_vertices_.size() / 2;
  double length_sum = 0.0;
  for (std::size_t e = 0; e < edge_count; ++e) {
    const float* a = vertex(p, edge_vertices_[2 * e]);
    const float* b = vertex(p, edge_vertices_[2 * e + 1]);
    double squared = 0.0;
    for (int c = 0; c < 3; ++c) squared += (double{b[c]} - a[c]) * (double{b[c]} - a[c]);
    length_sum += std::sqrt(squared);
  }
  mean_edge_length_ = edge_count == 0 ? 0.0 : length_sum / static_cast<double>(edge_count);
  amplitude_ = double{options_.noise} * mean_edge_length_;
  const double wavelength = double{options_.wavelength} * mean_edge_length_;
  noise_frequency_ = wavelength > 0.0 ? 1.0 / wavelength : 0.0;
}

void Subdivider::compute_normals() {
  const model::Mesh& base = base_;
  const std::vector<float>& p = base.positions;
  const std::size_t vertex_count = base.vertex_count(), triangle_count = base.triangle_count();

  // Vertex normals, summed in double: the base's own, or area-weighted face normals (the cross
  // product's length is twice the area).
  std::vector<double> sums(3 * vertex_count, 0.0);
  if (base.has_normals()) {
    std::copy(base.normals.begin(), base.normals.end(), sums.begin());
  } else {
    for (std::size_t t = 0; t < triangle_count; ++t) {
      const std::uint32_t* tri = &base.triangles[3 * t];
      const float *a = vertex(p, tri[0]), *b = vertex(p, tri[1]), *c = vertex(p, tri[2]);
      const double u[3] = {double{b[0]} - a[0], double{b[1]} - a[1], double{b[2]} - a[2]};
      const double v[3] = {double{c[0]} - a[0], double{c[1]} - a[1], double{c[2]} - a[2]};
      const double cross[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                               u[0] * v[1] - u[1] * v[0]};
      for (int k = 0; k < 3; ++k) {
        for (int c3 = 0; c3 < 3; ++c3) sums[3 * std::size_t{tri[k]} + c3] += cross[c3];
      }
    }
  }
  // Vertices with the same exact position (-0 and +0 alike) share the sum of their normals.
  std::vector<std::uint32_t> order(vertex_count);
  std::iota(order.begin(), order.end(), 0u);
  auto position_less = [&](std::uint32_t a, std::uint32_t b) {
    const float* pa = vertex(p, a);
    const float* pb = vertex(p, b);
    return std::lexicographical_compare(pa, pa + 3, pb, pb + 3);
  };
  auto same_position = [&](std::uint32_t a, std::uint32_t b) {
    return std::equal(vertex(p, a), vertex(p, a) + 3, vertex(p, b));
  };
  std::sort(order.begin(), order.end(), position_less);
  normals_.assign(3 * vertex_count, 0.0f);
  for (std::size_t begin = 0; begin < vertex_count;) {
    std::size_t end = begin + 1;
    while (end < vertex_count && same_position(order[begin], order[end])) ++end;
    double sum[3] = {0.0, 0.0, 0.0};
    for (std::size_t k = begin; k < end; ++k) {
      for (int c = 0; c < 3; ++c) sum[c] += sums[3 * std::size_t{order[k]} + c];
    }
    const double length = std::sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
    if (length > 0.0 && std::isfinite(length)) {
      for (std::size_t k = begin; k < end; ++k) {
        for (int c = 0; c < 3; ++c)
          normals_[3 * std::size_t{order[k]} + c] = static_cast<float>(sum[c] / length);
      }
    }
    begin = end;
  }
}

void Subdivider::displace(float p[3], const float n[3]) const {
  if (amplitude_ == 0.0) return;
  const double length = std::sqrt(double{n[0]} * n[0] + double{n[1]} * n[1] + double{n[2]} * n[2]);
  // Opposite normals can cancel between base vertices; such a point has no direction to move in.
  if (!(length > 1e-12)) return;
  const double offset = amplitude_ *
                        fractal_noise(p[0] * noise_frequency_, p[1] * noise_frequency_,
                                      p[2] * noise_frequency_, options_.seed) /
                        length;
  for (int c = 0; c < 3; ++c) p[c] = static_cast<float>(p[c] + offset * n[c]);
}

Status Subdivider::run(SubdivisionSink& sink) const {
  assert(fits());
  MTLOD_RETURN_IF_ERROR(stream_vertices(sink));
  return stream_triangles(sink);
}

Status Subdivider::stream_vertices(SubdivisionSink& sink) const {
  const std::vector<float>& p = base_.positions;
  const std::vector<std::uint8_t>& colors = base_.colors;
  const bool with_colors = base_.has_colors();
  const std::uint32_t n = options_.split;
  const float inv_n = 1.0f / static_cast<float>(n);
  const auto vertex_count = static_cast<std::uint32_t>(counts_.base_vertices);
  const std::size_t edge_count = counts_.base_edges, triangle_count = counts_.base_triangles;

  VertexChunk chunk(sink, options_.chunk_vertices, with_colors);
  std::uint8_t color[3] = {0, 0, 0};
  float normal[3];
  for (std::uint32_t v = 0; v < vertex_count; ++v) {
    float* out = chunk.add(with_colors ? &colors[3 * std::size_t{v}] : color);
    std::copy_n(vertex(p, v), 3, out);
    displace(out, &normals_[3 * std::size_t{v}]);
    if (chunk.full()) MTLOD_RETURN_IF_ERROR(chunk.flush());
  }
  for (std::size_t e = 0; e < edge_count; ++e) {
    const std::uint32_t a = edge_vertices_[2 * e], b = edge_vertices_[2 * e + 1];
    const float *pa = vertex(p, a), *pb = vertex(p, b);
    const float *na = &normals_[3 * std::size_t{a}], *nb = &normals_[3 * std::size_t{b}];
    for (std::uint32_t i = 1; i < n; ++i) {
      const float t = static_cast<float>(i) * inv_n;
      if (with_colors) {
        for (int c = 0; c < 3; ++c) {
          const float ca = colors[3 * std::size_t{a} + c], cb = colors[3 * std::size_t{b} + c];
          color[c] = to_color(ca + (cb - ca) * t);
        }
      }
      float* out = chunk.add(color);
      for (int c = 0; c < 3; ++c) {
        out[c] = pa[c] + (pb[c] - pa[c]) * t;
        normal[c] = na[c] + (nb[c] - na[c]) * t;
      }
      displace(out, normal);
      if (chunk.full()) MTLOD_RETURN_IF_ERROR(chunk.flush());
    }
  }
  if (n >= 3) {
    for (std::size_t f = 0; f < triangle_count; ++f) {
      const std::uint32_t* tri = &base_.triangles[3 * f];
      const float *p0 = vertex(p, tri[0]), *p1 = vertex(p, tri[1]), *p2 = vertex(p, tri[2]);
      const float* n0 = &normals_[3 * std::size_t{tri[0]}];
      const float* n1 = &normals_[3 * std::size_t{tri[1]}];
      const float* n2 = &normals_[3 * std::size_t{tri[2]}];
      // Interior lattice points (i, j), barycentric ((n−i−j)/n, i/n, j/n), row by row.
      for (std::uint32_t j = 1; j + 2 <= n; ++j) {
        for (std::uint32_t i = 1; i + j < n; ++i) {
          const float w1 = static_cast<float>(i) * inv_n, w2 = static_cast<float>(j) * inv_n;
          const float w0 = static_cast<float>(n - i - j) * inv_n;
          if (with_colors) {
            for (int c = 0; c < 3; ++c) {
              color[c] = to_color(w0 * colors[3 * std::size_t{tri[0]} + c] +
                                  w1 * colors[3 * std::size_t{tri[1]} + c] +
                                  w2 * colors[3 * std::size_t{tri[2]} + c]);
            }
          }
          float* out = chunk.add(color);
          for (int c = 0; c < 3; ++c) {
            out[c] = w0 * p0[c] + w1 * p1[c] + w2 * p2[c];
            normal[c] = w0 * n0[c] + w1 * n1[c] + w2 * n2[c];
          }
          displace(out, normal);
          if (chunk.full()) MTLOD_RETURN_IF_ERROR(chunk.flush());
        }
      }
    }
  }
  return chunk.flush();
}

Status Subdivider::stream_triangles(SubdivisionSink& sink) const {
  const std::uint32_t n = options_.split;
  const auto vertex_count = static_cast<std::uint32_t>(counts_.base_vertices);
  const std::size_t triangle_count = counts_.base_triangles;
  const std::uint64_t interior_per_triangle = (std::uint64_t{n} - 1) * (n >= 2 ? n - 2 : 0) / 2;
  const std::uint64_t interior_base = counts_.base_vertices + counts_.base_edges * (n - 1);
  std::vector<std::uint32_t> out;
  out.reserve(3 * options_.chunk_triangles);
  // Adds a triangle and tells whether the chunk is full.
  auto emit = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    out.insert(out.end(), {a, b, c});
    return out.size() == 3 * options_.chunk_triangles;
  };
  auto flush = [&]() -> Status {
    Status status = sink.triangles(out);
    out.clear();
    return status;
  };
  for (std::size_t f = 0; f < triangle_count; ++f) {
    const std::uint32_t* tri = &base_.triangles[3 * f];
    // Per side k (v_k → v_{k+1}): the id of the cut s steps from v_k, for 0 < s < n.
    std::uint32_t edge_first[3];
    bool forward[3];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t e = triangle_edges_[3 * f + k];
      edge_first[k] = static_cast<std::uint32_t>(vertex_count + std::uint64_t{e} * (n - 1));
      forward[k] = edge_vertices_[2 * std::size_t{e}] == tri[k];
    }
    auto cut = [&](int k, std::uint32_t s) { return edge_first[k] + (forward[k] ? s - 1 : n - 1 - s); };
    const std::uint64_t interior_first = interior_base + f * interior_per_triangle;
    auto id = [&](std::uint64_t i, std::uint64_t j) -> std::uint32_t {
      if (j == 0) return i == 0 ? tri[0] : (i == n ? tri[1] : cut(0, static_cast<std::uint32_t>(i)));
      if (i == 0) return j == n ? tri[2] : cut(2, static_cast<std::uint32_t>(n - j));
      if (i + j == n) return cut(1, static_cast<std::uint32_t>(j));
      // Row j holds n−1−j interior points; rows 1 .. j−1 come before it.
      return static_cast<std::uint32_t>(interior_first + (j - 1) * (n - 1) - (j - 1) * j / 2 + (i - 1));
    };
    for (std::uint32_t j = 0; j < n; ++j) {
      for (std::uint32_t i = 0; i + j < n; ++i) {
        // (i, j), (i+1, j), (i, j+1) winds like v0, v1, v2; so does the inverted triangle beside it.
        if (emit(id(i, j), id(i + 1, j), id(i, j + 1))) MTLOD_RETURN_IF_ERROR(flush());
        if (i + j + 2 <= n && emit(id(i + 1, j), id(i + 1, j + 1), id(i, j + 1))) {
          MTLOD_RETURN_IF_ERROR(flush());
        }
      }
    }
  }
  if (!out.empty()) MTLOD_RETURN_IF_ERROR(sink.triangles(out));
  return Ok{};
}

model::Mesh subdivide(const model::Mesh& base, const SubdivideOptions& options) {
  const Subdivider subdivider(base, options);
  assert(subdivider.fits());
  struct Collector final : SubdivisionSink {
    model::Mesh mesh;
    Status vertices(std::span<const float> positions, std::span<const std::uint8_t> colors) override {
      mesh.positions.insert(mesh.positions.end(), positions.begin(), positions.end());
      mesh.colors.insert(mesh.colors.end(), colors.begin(), colors.end());
      return Ok{};
    }
    Status triangles(std::span<const std::uint32_t> triangles) override {
      mesh.triangles.insert(mesh.triangles.end(), triangles.begin(), triangles.end());
      return Ok{};
    }
  } collector;
  collector.mesh.positions.reserve(3 * subdivider.counts().vertices);
  collector.mesh.triangles.reserve(3 * subdivider.counts().triangles);
  if (subdivider.has_colors()) collector.mesh.colors.reserve(3 * subdivider.counts().vertices);
  const Status status = subdivider.run(collector);
  assert(status.ok());
  (void)status;
  return std::move(collector.mesh);
}

}  // namespace mtlod::core::eval
