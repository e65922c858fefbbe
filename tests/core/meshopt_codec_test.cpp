// meshoptimizer payloads (core/codec/meshopt_encode.hpp) decode to the cut that was encoded: the same
// triangles (in the same order when it is kept) over its vertices numbered by first use, positions
// within half a step of the grid, normals within the octahedral bound, colours exact. Their streams
// decode with meshoptimizer alone, as EXT_meshopt_compression clients read them, and the decoder
// refuses damaged bytes or decodes them within the bounds its header sets.
#include <gtest/gtest.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "core/codec/meshopt_decode.hpp"
#include "core/codec/meshopt_encode.hpp"
#include "core/cut/refine.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/model/bounds.hpp"
#include "tests/core/mesh_compare.hpp"
#include "tests/core/mt_fixtures.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core {
namespace {

using Bytes = std::vector<std::uint8_t>;

// Colours that differ from vertex to vertex and cover the whole byte range.
std::vector<std::uint8_t> colours_of(std::size_t vertices) {
  std::vector<std::uint8_t> colours(3 * vertices);
  for (std::size_t i = 0; i < colours.size(); ++i) colours[i] = static_cast<std::uint8_t>(i * 37 % 256);
  return colours;
}

// The model vertex behind each decoded vertex when the cut's order is kept: the distinct vertices in
// order of first use, reading the cut's triangles corner by corner.
std::vector<std::uint32_t> first_use(std::span<const std::uint32_t> cut) {
  std::vector<std::uint32_t> order;
  std::vector<std::uint8_t> seen(cut.empty() ? 0 : *std::max_element(cut.begin(), cut.end()) + 1, 0);
  for (const std::uint32_t v : cut)
    if (!seen[v]) seen[v] = 1, order.push_back(v);
  return order;
}

// The largest distance between a decoded coordinate and the original: half a step of the grid,
// range / (2^bits − 1) / 2, plus the decoder's float arithmetic (origin + q · step rounds twice, each
// by half an ulp of a value below |origin| + range, and the stored step is itself rounded): 4 ulps of
// that size covers them.
float position_tolerance(const std::array<float, 3>& origin, float range, int bits) {
  const float size =
      std::max({std::abs(origin[0]), std::abs(origin[1]), std::abs(origin[2])}) + std::abs(range);
  return range / static_cast<float>((1 << bits) - 1) / 2 + 4 * std::numeric_limits<float>::epsilon() * size;
}

// The largest angle (radians) between a normal and its octahedral encoding with `bits` bits. The
// encoder rounds u and v to multiples of 1 / (2^(bits−1) − 1), moving each by at most e, half of that.
// On the octahedron |x| + |y| + |z| = 1 this moves the point by at most √6·e (x and y by e or less, z
// by |du| + |dv|, in the folded lower half too), and every point of it lies at least 1/√3 from the
// centre, so the direction turns by at most asin(√18·e). Rounding the result again to
// `stored_bits`-bit components (what meshopt_decodeFilterOct does) adds up to √3/2 of its unit. The
// last term covers float arithmetic on unit vectors.
double octahedral_bound(int bits, int stored_bits = 0) {
  const double e = 0.5 / ((1 << (bits - 1)) - 1);
  const double pi = std::acos(-1.0);
  double bound = std::sqrt(18.0) * e < 1 ? std::asin(std::sqrt(18.0) * e) : pi;  // π: no bound at all
  if (stored_bits > 0) bound += std::sqrt(3.0) / 2 / ((1 << (stored_bits - 1)) - 1);
  return bound + 1e-6;
}

double angle_between(const float* a, const float* b) {
  const double cx = double{a[1]} * b[2] - double{a[2]} * b[1], cy = double{a[2]} * b[0] - double{a[0]} * b[2],
               cz = double{a[0]} * b[1] - double{a[1]} * b[0];
  const double dot = double{a[0]} * b[0] + double{a[1]} * b[1] + double{a[2]} * b[2];
  return std::atan2(std::sqrt(cx * cx + cy * cy + cz * cz), dot);
}

// Triangles as the grid points of their corners, lround((p − origin) / step) per coordinate, each
// rotated to its smallest rotation (winding kept), sorted: equal for the same triangles of
// positions that round to the same grid points, whatever the vertex numbering and order.
using GridPoint = std::array<long, 3>;
std::vector<std::array<GridPoint, 3>> grid_triangles(std::span<const float> positions,
                                                     std::span<const std::uint32_t> triangles,
                                                     const std::array<float, 3>& origin, float step) {
  std::vector<std::array<GridPoint, 3>> out(triangles.size() / 3);
  for (std::size_t t = 0; t < out.size(); ++t) {
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k)
        out[t][c][k] =
            std::lround((double{positions[3 * std::size_t{triangles[3 * t + c]} + k]} - origin[k]) / step);
    // The smallest of the three rotations: two corners may share a grid point.
    const std::array<GridPoint, 3> r1 = {out[t][1], out[t][2], out[t][0]},
                                   r2 = {out[t][2], out[t][0], out[t][1]};
    out[t] = std::min({out[t], r1, r2});
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Decoded triangle t is the cut's triangle t through the first-use numbering, up to rotation.
void expect_same_triangles_in_order(std::span<const std::uint32_t> decoded,
                                    std::span<const std::uint32_t> cut) {
  const std::vector<std::uint32_t> order = first_use(cut);
  ASSERT_EQ(decoded.size(), cut.size());
  for (std::size_t t = 0; t < cut.size() / 3; ++t) {
    const auto* d = &decoded[3 * t];
    ASSERT_TRUE(d[0] < order.size() && d[1] < order.size() && d[2] < order.size()) << "triangle " << t;
    EXPECT_EQ(test::canonical(order[d[0]], order[d[1]], order[d[2]]),
              test::canonical(cut[3 * t], cut[3 * t + 1], cut[3 * t + 2]))
        << "triangle " << t;
  }
}

// A real cut: an MT of a generated shell refined for an allowed error that grows along x, from fine
// at one end to coarse at the other (as a focus would make it), so that nodes of many levels meet and
// the cut's vertices are scattered over the model's numbering. The MT has unit normals; the colours
// are made up.
struct ShellCut {
  const model::Mt* mt = nullptr;
  std::vector<std::uint32_t> triangles;
  std::vector<std::uint8_t> colours;
  model::Bounds model_box;
};

const ShellCut& shell_cut() {
  static const ShellCut cut = [] {
    ShellCut c;
    const test::MtCase* mc = test::shape_case(eval::Shape::kShell, 20'000);
    if (!mc) return c;
    c.mt = &mc->mt;
    c.model_box = model::bounds_of(c.mt->positions);
    const float diagonal = c.model_box.diagonal(), lo = c.model_box.lo[0], hi = c.model_box.hi[0];
    std::vector<float> field(c.mt->vertex_count());
    for (std::size_t v = 0; v < field.size(); ++v)
      field[v] = diagonal * (1e-6f + 5e-4f * (c.mt->positions[3 * v] - lo) / (hi - lo));
    cut::Refiner refiner(*c.mt);
    cut::CutMesh mesh;
    EXPECT_TRUE(refiner.refine(cut::Refinement::from_root(cut::AllowedError::from_vertices(field)), mesh));
    c.triangles = mesh.triangles;
    c.colours = colours_of(c.mt->vertex_count());
    return c;
  }();
  return cut;
}

codec::DracoInput input_of(const ShellCut& c, std::span<const std::uint32_t> triangles) {
  return {c.mt->positions, c.mt->normals, {}, triangles, c.colours};
}

// The payload's fields at the offsets the layout documents, read here without the codec's reader.
struct Container {
  std::uint8_t version = 1, flags = 0, position_bits = 14, normal_bits = 0;
  std::uint32_t vertices = 0, triangles = 0;
  std::array<float, 3> origin{};
  float step = 1;
  std::vector<Bytes> streams;  // positions, [normals], [colours], triangles
};

std::uint32_t get_u32(const std::uint8_t* at) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = v << 8 | at[i];
  return v;
}

void put_u32(Bytes& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

Container parse(const Bytes& payload) {
  Container c;
  EXPECT_GE(payload.size(), 32u);
  if (payload.size() < 32) return c;
  EXPECT_EQ(std::string(payload.begin(), payload.begin() + 4), "MOPT");
  c.version = payload[4], c.flags = payload[5], c.position_bits = payload[6], c.normal_bits = payload[7];
  c.vertices = get_u32(&payload[8]);
  c.triangles = get_u32(&payload[12]);
  for (int k = 0; k < 3; ++k) c.origin[k] = std::bit_cast<float>(get_u32(&payload[16 + 4 * k]));
  c.step = std::bit_cast<float>(get_u32(&payload[28]));
  for (std::size_t at = 32; at + 4 <= payload.size();) {
    const std::uint32_t length = get_u32(&payload[at]);
    EXPECT_LE(at + 4 + length, payload.size());
    if (at + 4 + length > payload.size()) break;
    c.streams.emplace_back(payload.begin() + at + 4, payload.begin() + at + 4 + length);
    at += 4 + length;
  }
  return c;
}

Bytes assemble(const Container& c) {
  Bytes out = {'M', 'O', 'P', 'T', c.version, c.flags, c.position_bits, c.normal_bits};
  put_u32(out, c.vertices);
  put_u32(out, c.triangles);
  for (const float f : c.origin) put_u32(out, std::bit_cast<std::uint32_t>(f));
  put_u32(out, std::bit_cast<std::uint32_t>(c.step));
  for (const Bytes& s : c.streams) {
    put_u32(out, static_cast<std::uint32_t>(s.size()));
    out.insert(out.end(), s.begin(), s.end());
  }
  return out;
}

template <class T>
Bytes vertex_stream(const std::vector<T>& values, std::size_t stride) {
  const std::size_t count = values.size() * sizeof(T) / stride;
  Bytes out(meshopt_encodeVertexBufferBound(count, stride));
  out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), values.data(), count, stride));
  return out;
}

Bytes index_stream(const std::vector<std::uint32_t>& indices, std::size_t vertices) {
  Bytes out(meshopt_encodeIndexBufferBound(indices.size(), vertices));
  out.resize(meshopt_encodeIndexBuffer(out.data(), out.size(), indices.data(), indices.size()));
  return out;
}

TEST(MeshoptCodec, TetrahedronFacesDecodeExactlyInFirstUseOrder) {
  // Two faces of the regular tetrahedron (corners ±1), listed from vertex 1: the payload's vertices
  // are 1, 3, 2, 0 in that order. Their own box has origin (−1, −1, −1) and side 2, so with one bit a
  // coordinate is 0 or 1 and the step is exactly 2: every position decodes exactly.
  const model::Mesh m = test::tetrahedron();
  const std::vector<std::uint32_t> cut = {1, 3, 2, 0, 1, 2};
  codec::MeshoptOptions options;
  options.position_bits = 1;
  options.keep_triangle_order = true;
  Bytes bytes;
  auto stats = codec::MeshoptEncoder().encode({m.positions, {}, {}, cut, {}}, options, bytes);
  ASSERT_TRUE(stats.ok()) << stats.error().message;
  EXPECT_EQ(stats->vertices, 4u);
  EXPECT_EQ(stats->triangles, 2u);
  EXPECT_EQ(stats->bytes, bytes.size());
  auto decoded = codec::decode_meshopt(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->origin, (std::array<float, 3>{-1, -1, -1}));
  EXPECT_EQ(decoded->step, 2.0f);
  const std::vector<float> expected = {1, -1, -1, -1, -1, 1, -1, 1, -1, 1, 1, 1};  // vertices 1, 3, 2, 0
  EXPECT_EQ(decoded->mesh.positions, expected);
  EXPECT_TRUE(decoded->mesh.normals.empty());
  EXPECT_TRUE(decoded->mesh.colors.empty());
  // {1, 3, 2} and {0, 1, 2} are {0, 1, 2} and {3, 0, 2} in payload ids, possibly rotated.
  ASSERT_EQ(decoded->mesh.triangles.size(), 6u);
  const auto& t = decoded->mesh.triangles;
  EXPECT_EQ(test::canonical(t[0], t[1], t[2]), test::canonical(0, 1, 2));
  EXPECT_EQ(test::canonical(t[3], t[4], t[5]), test::canonical(3, 0, 2));
}

TEST(MeshoptCodec, HeaderFollowsTheDocumentedLayout) {
  // A square of side 15 at the origin, on its own box with 4 bits: the step is 15 / (2^4 − 1) = 1.
  model::Mesh m = test::square();
  for (float& p : m.positions) p *= 15;
  m.normals = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  const std::vector<std::uint8_t> colours = colours_of(4);
  codec::MeshoptOptions options;
  options.position_bits = 4;
  options.normals = options.colors = true;
  options.normal_bits = 12;
  options.keep_triangle_order = true;
  Bytes bytes;
  ASSERT_TRUE(codec::MeshoptEncoder()
                  .encode({m.positions, m.normals, {}, m.triangles, colours}, options, bytes)
                  .ok());
  const Container c = parse(bytes);
  EXPECT_EQ(c.version, 1);
  EXPECT_EQ(c.flags, 1 | 2 | 4);  // normals, colours, 16-bit normals (12 bits need more than one byte)
  EXPECT_EQ(c.position_bits, 4);
  EXPECT_EQ(c.normal_bits, 12);
  EXPECT_EQ(c.vertices, 4u);
  EXPECT_EQ(c.triangles, 2u);
  EXPECT_EQ(c.origin, (std::array<float, 3>{0, 0, 0}));
  EXPECT_EQ(c.step, 1.0f);
  ASSERT_EQ(c.streams.size(), 4u);  // and nothing after them: parse read the payload to its end
  EXPECT_EQ(assemble(c), bytes);
  auto decoded = codec::decode_meshopt(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->mesh.positions, m.positions);  // integers on a unit step
  EXPECT_EQ(decoded->mesh.normals, m.normals);      // (0, 0, 1) is the octahedron's centre, exact
  EXPECT_EQ(decoded->mesh.colors, colours);
}

// (position bits, normal bits): the defaults, both widths of stored normals, the extremes.
class MeshoptShellCut : public testing::TestWithParam<std::pair<int, int>> {};

TEST_P(MeshoptShellCut, DecodesToTheCutsTrianglesWithinTheQuantizationBounds) {
  const ShellCut& c = shell_cut();
  ASSERT_TRUE(c.mt && c.mt->has_normals());
  ASSERT_GT(c.triangles.size() / 3, 3000u);
  codec::MeshoptOptions options;
  options.position_bits = GetParam().first;
  options.normal_bits = GetParam().second;
  options.normals = options.colors = true;
  options.keep_triangle_order = true;
  Bytes bytes;
  auto stats = codec::MeshoptEncoder().encode(input_of(c, c.triangles), options, bytes);
  ASSERT_TRUE(stats.ok()) << stats.error().message;
  const std::vector<std::uint32_t> order = first_use(c.triangles);
  EXPECT_EQ(stats->vertices, order.size());
  EXPECT_EQ(stats->triangles, c.triangles.size() / 3);
  EXPECT_EQ(stats->bytes, bytes.size());
  auto decoded = codec::decode_meshopt(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  const model::Mesh& d = decoded->mesh;
  ASSERT_EQ(d.vertex_count(), order.size());
  ASSERT_EQ(d.normals.size(), d.positions.size());
  ASSERT_EQ(d.colors.size(), d.positions.size());

  // The grid is the used vertices' own box: its corner and largest side over 2^bits − 1 steps.
  const model::Bounds box = model::bounds_of(c.mt->positions, c.triangles);
  EXPECT_EQ(decoded->origin, box.lo);
  EXPECT_EQ(decoded->step, box.largest_side() / static_cast<float>((1 << options.position_bits) - 1));
  EXPECT_EQ(grid_triangles(d.positions, d.triangles, box.lo, decoded->step),
            grid_triangles(c.mt->positions, c.triangles, box.lo, decoded->step));
  expect_same_triangles_in_order(d.triangles, c.triangles);

  const float tolerance = position_tolerance(box.lo, box.largest_side(), options.position_bits);
  const double angle = octahedral_bound(options.normal_bits);
  float worst_position = 0;
  double worst_angle = 0;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const std::size_t v = order[i];
    for (int k = 0; k < 3; ++k)
      worst_position =
          std::max(worst_position, std::abs(d.positions[3 * i + k] - c.mt->positions[3 * v + k]));
    worst_angle = std::max(worst_angle, angle_between(&d.normals[3 * i], &c.mt->normals[3 * v]));
    const float length = std::hypot(d.normals[3 * i], d.normals[3 * i + 1], d.normals[3 * i + 2]);
    EXPECT_NEAR(length, 1.0f, 1e-6f) << i;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(d.colors[3 * i + k], c.colours[3 * v + k]) << i;  // lossless
  }
  EXPECT_LE(worst_position, tolerance);
  EXPECT_LE(worst_angle, angle);
}
INSTANTIATE_TEST_SUITE_P(Bits, MeshoptShellCut,
                         testing::Values(std::pair{14, 10}, std::pair{16, 16}, std::pair{11, 8},
                                         std::pair{8, 9}, std::pair{1, 2}));

TEST(MeshoptCodec, ReorderedTrianglesAreTheSameTrianglesInFewerBytes) {
  // Reordered for a vertex cache (the default), the payload holds the cut's triangles over the cut's
  // vertices, numbered by first use in its own triangles. Vertices are matched by position: at 14 bits
  // a step is far below the shell's edge lengths.
  const ShellCut& c = shell_cut();
  ASSERT_TRUE(c.mt);
  codec::MeshoptOptions reorder, keep;
  reorder.normals = reorder.colors = keep.normals = keep.colors = true;
  keep.keep_triangle_order = true;
  Bytes reordered, kept;
  codec::MeshoptEncoder encoder;
  ASSERT_TRUE(encoder.encode(input_of(c, c.triangles), reorder, reordered).ok());
  ASSERT_TRUE(encoder.encode(input_of(c, c.triangles), keep, kept).ok());
  auto decoded = codec::decode_meshopt(reordered);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  const model::Mesh& d = decoded->mesh;
  EXPECT_EQ(grid_triangles(d.positions, d.triangles, decoded->origin, decoded->step),
            grid_triangles(c.mt->positions, c.triangles, decoded->origin, decoded->step));
  // Read corner by corner, the triangles meet vertex 0, 1, 2 ... each for the first time in turn.
  std::uint32_t next = 0;
  for (const std::uint32_t v : d.triangles) {
    ASSERT_LE(v, next);
    next += v == next;
  }
  EXPECT_EQ(next, d.vertex_count());
  const model::Bounds box = model::bounds_of(c.mt->positions, c.triangles);
  const float tolerance = position_tolerance(box.lo, box.largest_side(), reorder.position_bits);
  const auto match =
      test::match_vertices(d.positions, c.mt->positions, c.triangles, 4 * tolerance, tolerance);
  EXPECT_EQ(test::canonical_triangles(d.triangles, &match), test::canonical_triangles(c.triangles));
  const double angle = octahedral_bound(reorder.normal_bits);
  for (std::size_t i = 0; i < match.size(); ++i) {
    EXPECT_LE(angle_between(&d.normals[3 * i], &c.mt->normals[3 * std::size_t{match[i]}]), angle) << i;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(d.colors[3 * i + k], c.colours[3 * match[i] + k]) << i;
  }
  // The reordering pays: its triangles stream is at least a quarter smaller than the cut order's (31 %
  // here; 43 % on a budgeted 50k-triangle cut of the dragon, whose order is worse).
  auto with_reordering = codec::read_meshopt(reordered), without = codec::read_meshopt(kept);
  ASSERT_TRUE(with_reordering.ok() && without.ok());
  EXPECT_LT(4 * with_reordering->triangles.size(), 3 * without->triangles.size());
  EXPECT_LT(reordered.size(), kept.size());
}

TEST(MeshoptCodec, AFixedGridDecodesAVertexToTheSameFloatsInEveryPayload) {
  // Two overlapping parts of the cut, encoded on the model's grid: every vertex they share decodes bit
  // for bit the same in both, and within half a step of the grid from the original.
  const ShellCut& c = shell_cut();
  ASSERT_TRUE(c.mt);
  codec::MeshoptOptions options;
  options.position_grid = codec::DracoOptions::Grid{c.model_box.lo, c.model_box.largest_side()};
  options.keep_triangle_order = true;
  const std::size_t n = c.triangles.size() / 3;
  const std::vector<std::uint32_t> first(c.triangles.begin(), c.triangles.begin() + 3 * (2 * n / 3)),
      second(c.triangles.begin() + 3 * (n / 3), c.triangles.end());
  std::vector<std::vector<float>> positions;  // per part: decoded position of each model vertex, or NaN
  for (const auto* part : {&first, &second}) {
    Bytes bytes;
    ASSERT_TRUE(codec::MeshoptEncoder().encode(input_of(c, *part), options, bytes).ok());
    auto decoded = codec::decode_meshopt(bytes);
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    EXPECT_EQ(decoded->origin, c.model_box.lo);
    const std::vector<std::uint32_t> order = first_use(*part);
    ASSERT_EQ(decoded->mesh.vertex_count(), order.size());
    std::vector<float>& by_model = positions.emplace_back(c.mt->positions.size(), NAN);
    const float tolerance =
        position_tolerance(c.model_box.lo, c.model_box.largest_side(), options.position_bits);
    for (std::size_t i = 0; i < order.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        const float p = decoded->mesh.positions[3 * i + k];
        by_model[3 * order[i] + k] = p;
        EXPECT_LE(std::abs(p - c.mt->positions[3 * order[i] + k]), tolerance) << i;
      }
    }
  }
  std::size_t common = 0;
  for (std::size_t v = 0; v < c.mt->vertex_count(); ++v) {
    if (std::isnan(positions[0][3 * v]) || std::isnan(positions[1][3 * v])) continue;
    ++common;
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(std::bit_cast<std::uint32_t>(positions[0][3 * v + k]),
                std::bit_cast<std::uint32_t>(positions[1][3 * v + k]))
          << "vertex " << v;
  }
  EXPECT_GT(common, 100u);
}

TEST(MeshoptCodec, PositionsOutsideTheGridAreClampedToItsFaces) {
  // The square of side 15 on a grid of side 6 from the origin with 2 bits (step 2): corner (15, 15, 0)
  // lands on (6, 6, 0), the others on the grid as they are.
  model::Mesh m = test::square();
  for (float& p : m.positions) p *= 15;
  codec::MeshoptOptions options;
  options.position_bits = 2;
  options.position_grid = codec::DracoOptions::Grid{{0, 0, 0}, 6};
  options.keep_triangle_order = true;
  Bytes bytes;
  ASSERT_TRUE(codec::MeshoptEncoder().encode({m.positions, {}, {}, m.triangles, {}}, options, bytes).ok());
  auto decoded = codec::decode_meshopt(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->mesh.positions, (std::vector<float>{0, 0, 0, 6, 0, 0, 6, 6, 0, 0, 6, 0}));
}

TEST(MeshoptCodec, ReusedEncoderGivesTheSameBytesAsAFreshOne) {
  const ShellCut& c = shell_cut();
  ASSERT_TRUE(c.mt);
  const model::Mesh small = test::tetrahedron();
  for (const bool keep_order : {false, true}) {
    codec::MeshoptEncoder reused;
    codec::MeshoptOptions options;
    options.normals = options.colors = true;
    options.keep_triangle_order = keep_order;
    Bytes second, fresh;
    // A larger model, a smaller one, then partial cuts of the larger one in turn: nothing of a previous
    // cut's numbering is left behind.
    ASSERT_TRUE(reused.encode(input_of(c, c.triangles), options, second).ok());
    ASSERT_TRUE(reused.encode({small.positions, {}, {}, small.triangles, {}}, {}, second).ok());
    ASSERT_TRUE(
        codec::MeshoptEncoder().encode({small.positions, {}, {}, small.triangles, {}}, {}, fresh).ok());
    EXPECT_EQ(second, fresh);
    for (const std::size_t step : {3u, 2u, 5u}) {
      std::vector<std::uint32_t> part;
      for (std::size_t t = 0; t < c.triangles.size() / 3; t += step)
        part.insert(part.end(), &c.triangles[3 * t], &c.triangles[3 * t] + 3);
      ASSERT_TRUE(reused.encode(input_of(c, part), options, second).ok());
      ASSERT_TRUE(codec::MeshoptEncoder().encode(input_of(c, part), options, fresh).ok());
      EXPECT_EQ(second, fresh) << "every " << step << "th triangle, order kept " << keep_order;
    }
  }
}

TEST(MeshoptCodec, RejectsBadOptionsAndMissingAttributes) {
  const model::Mesh m = test::tetrahedron();
  const codec::DracoInput plain{m.positions, {}, {}, m.triangles, {}};
  codec::MeshoptEncoder encoder;
  auto refused = [&](const codec::DracoInput& input, const codec::MeshoptOptions& options, const char* says) {
    Bytes bytes = {1, 2, 3};
    auto stats = encoder.encode(input, options, bytes);
    ASSERT_FALSE(stats.ok()) << says;
    EXPECT_EQ(stats.error().code, ErrorCode::kInvalidArgument) << says;
    EXPECT_NE(stats.error().message.find(says), std::string::npos) << stats.error().message;
    EXPECT_TRUE(bytes.empty());
  };
  for (const auto& [position_bits, normal_bits] : {std::pair{0, 10}, {17, 10}, {14, 1}, {14, 17}}) {
    codec::MeshoptOptions options;
    options.position_bits = position_bits;
    options.normal_bits = normal_bits;
    refused(plain, options, "outside 1..16 / 2..16");
  }
  for (const auto& grid :
       {codec::DracoOptions::Grid{{0, 0, 0}, 0}, codec::DracoOptions::Grid{{0, 0, 0}, -1},
        codec::DracoOptions::Grid{{0, 0, 0}, NAN}, codec::DracoOptions::Grid{{INFINITY, 0, 0}, 1}}) {
    codec::MeshoptOptions options;
    options.position_grid = grid;
    refused(plain, options, "grid");
  }
  codec::MeshoptOptions want_normals;
  want_normals.normals = true;
  refused(plain, want_normals, "normals requested");
  codec::MeshoptOptions want_colours;
  want_colours.colors = true;
  refused(plain, want_colours, "colours requested");
  refused({m.positions, {}, {}, {}, {}}, {}, "no triangles");
}

TEST(MeshoptCodec, WritesIndexVersionOneWhateverMeshoptimizerIsSetTo) {
  // The triangles stream is ours (core/codec/index_encode.hpp): meshoptimizer's process-wide index
  // version, set to 0 by other code, changes nothing.
  const model::Mesh m = test::tetrahedron();
  Bytes expected, bytes;
  codec::MeshoptEncoder encoder;
  ASSERT_TRUE(encoder.encode({m.positions, {}, {}, m.triangles, {}}, {}, expected).ok());
  meshopt_encodeIndexVersion(0);
  auto stats = encoder.encode({m.positions, {}, {}, m.triangles, {}}, {}, bytes);
  meshopt_encodeIndexVersion(1);
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(bytes, expected);
  EXPECT_EQ(parse(bytes).streams.back()[0], 0xe1);
}

// The streams are EXT_meshopt_compression buffer views as they are: each decodes with meshoptimizer's
// own decoders given only the count and stride, positions as KHR_mesh_quantization u16 vectors,
// normals through the OCTAHEDRAL filter, triangles as mode TRIANGLES (index codec version 1).
class MeshoptExtStreams : public testing::TestWithParam<int> {};

TEST_P(MeshoptExtStreams, DecodeWithMeshoptimizerAlone) {
  const ShellCut& c = shell_cut();
  ASSERT_TRUE(c.mt);
  codec::MeshoptOptions options;
  options.normals = options.colors = true;
  options.normal_bits = GetParam();
  options.keep_triangle_order = true;
  Bytes bytes;
  ASSERT_TRUE(codec::MeshoptEncoder().encode(input_of(c, c.triangles), options, bytes).ok());
  const Container p = parse(bytes);
  const std::size_t stride = options.normal_bits <= 8 ? 4 : 8;
  ASSERT_EQ(p.streams.size(), 4u);
  const std::vector<std::uint32_t> order = first_use(c.triangles);
  const std::size_t n = order.size();
  ASSERT_EQ(p.vertices, n);
  ASSERT_EQ(p.triangles, c.triangles.size() / 3);
  // Vertex codec version 0 (0xa0) and index codec version 1 (0xe1), the ones the extension names.
  for (int s = 0; s < 3; ++s) EXPECT_EQ(p.streams[s][0], 0xa0) << "stream " << s;
  EXPECT_EQ(p.streams[3][0], 0xe1);

  // Positions: each stored coordinate is a nearest grid point of the original.
  std::vector<std::uint16_t> q(4 * n);
  ASSERT_EQ(meshopt_decodeVertexBuffer(q.data(), n, 8, p.streams[0].data(), p.streams[0].size()), 0);
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const double exact = (double{c.mt->positions[3 * order[i] + k]} - p.origin[k]) / p.step;
      EXPECT_LE(std::abs(q[4 * i + k] - exact), 0.5 + 1e-6) << i;
    }
    EXPECT_EQ(q[4 * i + 3], 0) << i;
  }

  // Normals through the filter, at the width they are stored.
  const double angle = octahedral_bound(options.normal_bits, 8 * static_cast<int>(stride) / 4);
  std::vector<std::uint8_t> raw(stride * n);
  ASSERT_EQ(meshopt_decodeVertexBuffer(raw.data(), n, stride, p.streams[1].data(), p.streams[1].size()), 0);
  meshopt_decodeFilterOct(raw.data(), n, stride);
  double worst = 0;
  for (std::size_t i = 0; i < n; ++i) {
    float normal[3];
    for (int k = 0; k < 3; ++k) {
      if (stride == 4) {
        normal[k] = static_cast<float>(static_cast<std::int8_t>(raw[4 * i + k])) / 127.0f;
      } else {
        std::int16_t value;
        std::memcpy(&value, &raw[8 * i + 2 * k], 2);
        normal[k] = static_cast<float>(value) / 32767.0f;
      }
    }
    worst = std::max(worst, angle_between(normal, &c.mt->normals[3 * order[i]]));
  }
  EXPECT_LE(worst, angle);

  std::vector<std::uint8_t> rgba(4 * n);
  ASSERT_EQ(meshopt_decodeVertexBuffer(rgba.data(), n, 4, p.streams[2].data(), p.streams[2].size()), 0);
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(rgba[4 * i + k], c.colours[3 * order[i] + k]) << i;
    EXPECT_EQ(rgba[4 * i + 3], 255) << i;
  }

  std::vector<std::uint32_t> indices(c.triangles.size());
  ASSERT_EQ(
      meshopt_decodeIndexBuffer(indices.data(), indices.size(), 4, p.streams[3].data(), p.streams[3].size()),
      0);
  expect_same_triangles_in_order(indices, c.triangles);
}
INSTANTIATE_TEST_SUITE_P(NormalBits, MeshoptExtStreams, testing::Values(8, 12));

// A small payload with every stream: the shell cut's first 40 triangles.
Bytes small_payload() {
  const ShellCut& c = shell_cut();
  EXPECT_TRUE(c.mt);
  if (!c.mt) return {};
  const std::vector<std::uint32_t> part(c.triangles.begin(), c.triangles.begin() + 3 * 40);
  codec::MeshoptOptions options;
  options.normals = options.colors = true;
  Bytes bytes;
  EXPECT_TRUE(codec::MeshoptEncoder().encode(input_of(c, part), options, bytes).ok());
  return bytes;
}

TEST(MeshoptDecode, RefusesEveryTruncation) {
  const Bytes bytes = small_payload();
  ASSERT_GT(bytes.size(), 100u);
  ASSERT_TRUE(codec::decode_meshopt(bytes).ok());
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    // A copy of exactly `length` bytes, so that ASan sees any read past its end.
    const Bytes prefix(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(length));
    auto decoded = codec::decode_meshopt(prefix);
    ASSERT_FALSE(decoded.ok()) << length << " bytes";
    EXPECT_EQ(decoded.error().code, ErrorCode::kCorrupt) << length << " bytes";
  }
}

TEST(MeshoptDecode, RandomDamageIsRefusedOrDecodesWithinItsHeader) {
  const Bytes bytes = small_payload();
  ASSERT_FALSE(bytes.empty());
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::size_t> position(0, bytes.size() - 1);
  std::uniform_int_distribution<int> flip(1, 255), flips(1, 4);
  std::size_t refused = 0, decoded_count = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    Bytes damaged = bytes;
    for (int f = flips(rng); f > 0; --f) damaged[position(rng)] ^= static_cast<std::uint8_t>(flip(rng));
    auto decoded = codec::decode_meshopt(damaged);
    if (!decoded.ok()) {
      ++refused;
      EXPECT_TRUE(decoded.error().code == ErrorCode::kCorrupt ||
                  decoded.error().code == ErrorCode::kUnsupported)
          << decoded.error().message;
      continue;
    }
    ++decoded_count;
    // Whatever the damage, the mesh is what its header promises: sizes, indices, positions in the
    // grid's box, unit normals.
    const model::Mesh& m = decoded->mesh;
    const std::size_t n = m.vertex_count();
    ASSERT_EQ(m.positions.size(), 3 * n);
    ASSERT_TRUE(m.normals.empty() || m.normals.size() == 3 * n);
    ASSERT_TRUE(m.colors.empty() || m.colors.size() == 3 * n);
    ASSERT_EQ(m.triangles.size() % 3, 0u);
    for (const std::uint32_t v : m.triangles) ASSERT_LT(v, n) << "trial " << trial;
    const float top = static_cast<float>((1 << decoded->position_bits) - 1) * decoded->step;
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        const float offset = m.positions[3 * i + k] - decoded->origin[k];
        // Above the top by no more than the rounding of origin + q · step and of this subtraction.
        const float slack = 4 * std::numeric_limits<float>::epsilon() * (std::abs(decoded->origin[k]) + top);
        ASSERT_TRUE(std::isfinite(offset) && offset >= 0 && offset <= top + slack) << "trial " << trial;
      }
      if (!m.normals.empty()) {
        ASSERT_NEAR(std::hypot(m.normals[3 * i], m.normals[3 * i + 1], m.normals[3 * i + 2]), 1.0f, 1e-5f);
      }
    }
  }
  // Most damage is caught; some (a changed coordinate or colour) is not detectable and decodes.
  EXPECT_GT(refused, 1000u);
  EXPECT_GT(decoded_count, 0u);
}

// Hand-made payloads around one valid three-vertex triangle: each breaks one rule.
Container one_triangle() {
  Container c;
  c.position_bits = 4;
  c.vertices = 3;
  c.triangles = 1;
  c.streams.push_back(vertex_stream(std::vector<std::uint16_t>{0, 0, 0, 0, 15, 0, 0, 0, 0, 15, 0, 0}, 8));
  c.streams.push_back(index_stream({0, 1, 2}, 3));
  return c;
}

TEST(MeshoptDecode, RefusesHandMadeDamage) {
  // meshoptimizer writes the index codec's version the library is set to; the format's is 1.
  meshopt_encodeIndexVersion(1);
  ASSERT_TRUE(codec::decode_meshopt(assemble(one_triangle())).ok());
  auto refused = [](const Bytes& bytes, const char* says, ErrorCode code = ErrorCode::kCorrupt) {
    auto decoded = codec::decode_meshopt(bytes);
    ASSERT_FALSE(decoded.ok()) << says;
    EXPECT_EQ(decoded.error().code, code) << decoded.error().message;
    EXPECT_NE(decoded.error().message.find(says), std::string::npos) << decoded.error().message;
  };
  Bytes bytes = assemble(one_triangle());
  bytes[0] = 'm';
  refused(bytes, "magic");
  Container c = one_triangle();
  c.version = 2;
  refused(assemble(c), "version 2", ErrorCode::kUnsupported);
  c = one_triangle(), c.flags = 8;
  refused(assemble(c), "flags");
  c = one_triangle(), c.flags = 4;  // 16-bit normals without normals
  refused(assemble(c), "flags");
  c = one_triangle(), c.position_bits = 17;
  refused(assemble(c), "position_bits 17");
  c = one_triangle(), c.normal_bits = 8;
  refused(assemble(c), "without normals");
  c = one_triangle(), c.vertices = 0xFFFFFFFF;  // refused before anything of that size is allocated
  refused(assemble(c), "cannot fit");
  c = one_triangle(), c.triangles = 0xFFFFFFFF;
  refused(assemble(c), "cannot fit");
  c = one_triangle(), c.triangles = 0;
  refused(assemble(c), "may be 0");
  c = one_triangle(), c.step = NAN;
  refused(assemble(c), "not finite");
  c = one_triangle(), c.origin[1] = 3e38f, c.step = 1e37f;  // finite, but 15 steps from it are not
  refused(assemble(c), "not finite");
  bytes = assemble(one_triangle());
  bytes.push_back(0);
  refused(bytes, "follow the last stream");
  bytes = assemble(one_triangle());
  bytes[32] = 0xff;  // the positions stream's length now runs past the end
  refused(bytes, "run past the end");
  // Streams meshoptimizer decodes, with values the header does not allow.
  c = one_triangle(), c.position_bits = 3;  // a coordinate of 15 needs 4 bits
  refused(assemble(c), "position 1");
  c = one_triangle(),
  c.streams[0] = vertex_stream(std::vector<std::uint16_t>{0, 0, 0, 1, 15, 0, 0, 0, 0, 15, 0, 0}, 8);
  refused(assemble(c), "position 0");
  c = one_triangle(), c.streams[1] = index_stream({0, 1, 5}, 6);
  refused(assemble(c), "names vertex 5 of 3");
  c = one_triangle(), c.streams[0][0] = 0xa1;
  refused(assemble(c), "not a version-0");
  c = one_triangle(), c.streams[1][0] = 0xe0;
  refused(assemble(c), "not a version-1");
  c = one_triangle(), c.streams[0].pop_back();
  refused(assemble(c), "does not decode");
  // Normals off the octahedron (a third component other than the 8-bit encoding of 1, 127), and a
  // colour whose alpha is not 255.
  c = one_triangle(), c.flags = 1, c.normal_bits = 8;
  c.streams.insert(c.streams.begin() + 1,
                   vertex_stream(std::vector<std::int8_t>{0, 0, 127, 0, 0, 0, 127, 0, 0, 0, 126, 0}, 4));
  refused(assemble(c), "normal 2");
  c = one_triangle(), c.flags = 2;
  c.streams.insert(c.streams.begin() + 1,
                   vertex_stream(std::vector<std::uint8_t>{1, 2, 3, 255, 4, 5, 6, 254, 7, 8, 9, 255}, 4));
  refused(assemble(c), "colour 1 has alpha 254");
}

}  // namespace
}  // namespace mtlod::core
