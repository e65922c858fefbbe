// Refinement (core/ARCHITECTURE.md §2.4): hand-made cases, a naive fixpoint for minimality,
// conformity and the error bound on real scans, budgets, and dynamic == static after random field
// sequences.
#include "core/cut/refine.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "core/cut/cut_delta.hpp"
#include "tests/core/cut_validator.hpp"
#include "tests/core/mt_fixtures.hpp"

namespace mtlod::core {
namespace {

using test::MtCase;
constexpr float kInf = std::numeric_limits<float>::infinity();

// Reference: the minimal passing cut by the definition, recomputed from scratch each round — add the
// remover (and its ancestors) of every failing triangle of the current mesh until none fails.
std::vector<std::uint8_t> naive_minimal_cut(const model::Mt& mt, const cut::AllowedError& allowed) {
  std::vector<std::uint8_t> in(mt.node_count(), 0);
  in[0] = 1;
  std::vector<std::uint32_t> creator(mt.triangle_count());
  for (std::uint32_t t = 0; t < mt.triangle_count(); ++t) creator[t] = mt.triangle_creator(t);
  auto add_with_ancestors = [&](auto&& self, std::uint32_t n) -> void {
    if (in[n]) return;
    in[n] = 1;
    for (std::uint32_t j = mt.node_parent_offsets[n]; j < mt.node_parent_offsets[n + 1]; ++j)
      self(self, mt.node_parents[j]);
  };
  for (bool changed = true; changed;) {
    changed = false;
    for (std::uint32_t t = 0; t < mt.triangle_count(); ++t) {
      const std::uint32_t r = mt.triangle_remover[t];
      if (!in[creator[t]] || r == model::kNoNode || in[r]) continue;
      std::uint32_t v[3];
      mt.triangle_vertices(t, v);
      const float a =
          allowed.per_vertex.empty()
              ? allowed.uniform
              : std::min({allowed.per_vertex[v[0]], allowed.per_vertex[v[1]], allowed.per_vertex[v[2]]});
      if (mt.triangle_error(t) > a) {
        add_with_ancestors(add_with_ancestors, r);
        changed = true;
      }
    }
  }
  return in;
}

std::vector<std::uint32_t> sorted_nodes(const cut::Refiner& r) {
  std::vector<std::uint32_t> nodes(r.cut_nodes().begin(), r.cut_nodes().end());
  std::sort(nodes.begin(), nodes.end());
  return nodes;
}

float bbox_diagonal(const model::Mesh& mesh) {
  float lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v)
    for (int k = 0; k < 3; ++k)
      lo[k] = std::min(lo[k], mesh.positions[3 * v + k]), hi[k] = std::max(hi[k], mesh.positions[3 * v + k]);
  return std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                   (hi[2] - lo[2]) * (hi[2] - lo[2]));
}

// Allowed error growing with distance from a focus vertex (a stand-in for the DT labels of the
// next issue): fine near the focus, coarse far away.
std::vector<float> focus_field(const model::Mesh& mesh, std::mt19937& rng, float fine, float coarse) {
  std::uniform_int_distribution<std::size_t> pick(0, mesh.vertex_count() - 1);
  const float* f = &mesh.positions[3 * pick(rng)];
  const float radius = bbox_diagonal(mesh) * std::uniform_real_distribution<float>(0.05f, 0.5f)(rng);
  std::vector<float> field(mesh.vertex_count());
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const float* p = &mesh.positions[3 * v];
    const float d = std::sqrt((p[0] - f[0]) * (p[0] - f[0]) + (p[1] - f[1]) * (p[1] - f[1]) +
                              (p[2] - f[2]) * (p[2] - f[2]));
    field[v] = fine + (coarse - fine) * std::min(1.0f, d / radius);
  }
  return field;
}

// "FILE": a shared scan built by build_mt; "large:FILE": the same scan built out of core in blocks of
// 3,000 triangles (core/build/large_build.hpp). Null when the file is absent.
const MtCase* scan_or_large_case(std::string_view name) {
  constexpr std::string_view kLarge = "large:";
  if (name.starts_with(kLarge)) return test::large_scan_case(std::string(name.substr(kLarge.size())), 3'000);
  return test::scan_case(std::string(name));
}

// Independent per-vertex noise: the harshest case for dynamic refinement (no spatial coherence).
std::vector<float> noise_field(std::size_t n, std::mt19937& rng, float lo, float hi) {
  std::vector<float> field(n);
  std::uniform_real_distribution<float> u(std::log(lo), std::log(hi));
  for (float& x : field) x = std::exp(u(rng));
  return field;
}

float max_node_error(const model::Mt& mt) {
  return *std::max_element(mt.node_error.begin(), mt.node_error.end());
}

// A refiner on the 8k-triangle sphere whose cut moves to fields focused at random vertices: 1e-3 of
// the largest node error at the focus, `coarse` of it far away.
struct SphereFocusJumps {
  explicit SphereFocusJumps(std::uint32_t seed) : rng(seed) {}
  Status jump(float coarse) {
    return refiner.refine(cut::Refinement::move(cut::AllowedError::from_vertices(
                              focus_field(c->mesh, rng, top * 1e-3f, top * coarse))),
                          cut);
  }
  const MtCase* c = test::shape_case(eval::Shape::kSphere, 8'000);
  std::mt19937 rng;
  const float top = max_node_error(c->mt);
  cut::Refiner refiner{c->mt};
  cut::CutMesh cut;
};

TEST(Refine, SquareSwitchesBetweenItsTwoCutsAtTheNodeError) {
  // The square's MT has one collapse, of error e1 ≈ 1/√2: at allowed ≥ e1 the root triangle
  // passes; any smaller allowed error needs the two input triangles.
  model::Mesh square = test::square();
  auto mt = test::build_mt_renumbering(square);
  ASSERT_TRUE(mt.ok());
  const float e1 = mt->node_error[1];
  cut::CutMesh out;
  cut::refine_static(*mt, cut::AllowedError::everywhere(e1), out);
  EXPECT_EQ(out.triangle_count(), 1u);
  EXPECT_EQ(out.max_error, e1);
  EXPECT_EQ(out.node_count, 1u);
  cut::refine_static(*mt, cut::AllowedError::everywhere(std::nextafter(e1, 0.0f)), out);
  EXPECT_EQ(test::triangle_set(out.triangles), test::triangle_set(square.triangles));
  EXPECT_EQ(out.max_error, 0.0f);
  EXPECT_EQ(out.node_count, 2u);
  // Per vertex: one fine corner is enough, since a triangle takes the minimum of its corners.
  std::vector<float> field = {kInf, kInf, kInf, kInf};
  field[mt->root_first_corner[0]] = 0.5f;
  cut::refine_static(*mt, cut::AllowedError::from_vertices(field), out);
  EXPECT_EQ(out.triangle_count(), 2u);
}

TEST(Refine, ExtremeThresholdsGiveTheInputAndTheRoot) {
  for (const char* file : {"bunny-npm-3k.ply", "dragon-vrip-res4-11k.ply"}) {
    const MtCase* c = test::scan_case(file);
    if (!c) continue;
    cut::CutMesh out;
    // Error ≥ 0 > -1 for every triangle that has a remover: everything is refined.
    cut::refine_static(c->mt, cut::AllowedError::everywhere(-1.0f), out);
    EXPECT_EQ(test::triangle_set(out.triangles), test::triangle_set(c->mesh.triangles)) << file;
    EXPECT_EQ(out.node_count, c->mt.node_count());
    cut::refine_static(c->mt, cut::AllowedError::everywhere(kInf), out);
    EXPECT_EQ(out.triangle_count(), c->mt.root_triangle_count()) << file;
    EXPECT_EQ(out.node_count, 1u);
  }
}

TEST(Refine, StaticEqualsTheNaiveFixpointOnRandomFields) {
  std::mt19937 rng(7);
  for (const MtCase* c :
       {test::shape_case(eval::Shape::kSphere, 8'000), test::shape_case(eval::Shape::kTerrain, 3'000),
        test::scan_case("bunny-npm-3k.ply"), test::scan_case("dragon-vrip-res4-11k.ply")}) {
    if (!c) continue;
    const float top = max_node_error(c->mt);
    cut::Refiner refiner(c->mt);
    cut::CutMesh out;
    for (int round = 0; round < 6; ++round) {
      std::vector<float> field = round % 2
                                     ? focus_field(c->mesh, rng, top * 1e-3f, top * 0.3f)
                                     : noise_field(c->mesh.vertex_count(), rng, top * 1e-3f, top * 0.5f);
      const cut::AllowedError allowed = cut::AllowedError::from_vertices(field);
      EXPECT_TRUE(refiner.refine(cut::Refinement::from_root(allowed), out));
      const std::vector<std::uint8_t> expected = naive_minimal_cut(c->mt, allowed);
      std::vector<std::uint32_t> expected_nodes;
      for (std::uint32_t n = 0; n < expected.size(); ++n)
        if (expected[n]) expected_nodes.push_back(n);
      ASSERT_EQ(sorted_nodes(refiner), expected_nodes) << "round " << round;
      ASSERT_TRUE(test::validate_cut(c->reference, out.triangles)) << "round " << round;
    }
  }
}

// A field's values, counting how often each vertex is asked for.
class Recorder final : public cut::VertexErrorSource {
 public:
  explicit Recorder(const std::vector<float>& field) : field_(field), asked_(field.size(), 0) {}
  float vertex_allowed_error(std::uint32_t v) const override {
    ++asked_[v];
    return field_[v];
  }
  const std::vector<int>& asked() const { return asked_; }

 private:
  const std::vector<float>& field_;
  mutable std::vector<int> asked_;
};

// On demand: the same cut as with every vertex's value, asking only for the root's vertices and
// the cut's split vertices, each once, and writing exactly those entries.
TEST(Refine, OnDemandEqualsTheFullFieldAndAsksOnlyForTheCutsVertices) {
  std::mt19937 rng(5);
  for (const MtCase* c :
       {test::shape_case(eval::Shape::kSphere, 8'000), test::scan_case("bunny-npm-3k.ply"),
        test::scan_case("dragon-vrip-res4-11k.ply"), test::scan_case("armadillo-52k.ply")}) {
    if (!c) continue;
    const float top = max_node_error(c->mt);
    cut::Refiner full(c->mt), lazy(c->mt);
    cut::CutMesh expected, out;
    for (int round = 0; round < 6; ++round) {
      const std::vector<float> field =
          round % 2 ? focus_field(c->mesh, rng, top * 1e-3f, top * 0.3f)
                    : noise_field(c->mesh.vertex_count(), rng, top * 1e-3f, top * 0.5f);
      EXPECT_TRUE(full.refine(cut::Refinement::from_root(cut::AllowedError::from_vertices(field)), expected));
      const Recorder source(field);
      std::vector<float> written(field.size(), -1.0f);
      EXPECT_TRUE(lazy.refine(cut::Refinement::from_root(source, written), out));
      ASSERT_EQ(sorted_nodes(lazy), sorted_nodes(full)) << "round " << round;
      EXPECT_EQ(test::triangle_set(out.triangles), test::triangle_set(expected.triangles));
      EXPECT_EQ(out.max_error, expected.max_error);
      // Asked for: the root triangles' corners and the split vertex of every other cut node.
      std::vector<std::uint8_t> needed(field.size(), 0);
      for (std::uint32_t t = 0; t < c->mt.root_triangle_count(); ++t) {
        std::uint32_t v[3];
        c->mt.triangle_vertices(t, v);
        for (const std::uint32_t x : v) needed[x] = 1;
      }
      for (const std::uint32_t n : lazy.cut_nodes())
        if (n != 0) needed[c->mt.node_vertex[n]] = 1;
      for (std::uint32_t v = 0; v < field.size(); ++v) {
        ASSERT_EQ(source.asked()[v], needed[v]) << "vertex " << v << " round " << round;  // once each
        ASSERT_EQ(written[v], needed[v] ? field[v] : -1.0f) << "vertex " << v;
      }
      // Every corner of the cut was asked for: the refinement read only values it had asked for.
      for (const std::uint32_t v : out.triangles) ASSERT_TRUE(needed[v]) << "vertex " << v;
    }
  }
}

// Budgeted on demand (a new view with a budget): the same cut as with every vertex's value, worst
// first from the root and kept for gazes, asking for each vertex at most once and for every vertex
// of the cut.
TEST(Refine, BudgetOnDemandEqualsTheFullField) {
  std::mt19937 rng(8);
  for (const MtCase* c :
       {test::shape_case(eval::Shape::kSphere, 8'000), test::scan_case("armadillo-52k.ply")}) {
    if (!c) continue;
    const float top = max_node_error(c->mt);
    for (int round = 0; round < 4; ++round) {
      const std::vector<float> field =
          round % 2 ? focus_field(c->mesh, rng, top * 1e-3f, top * 0.3f)
                    : noise_field(c->mesh.vertex_count(), rng, top * 1e-3f, top * 0.5f);
      const std::size_t budget = 500 + 1500 * std::size_t(round);
      for (const bool keep : {false, true}) {
        cut::Refiner full(c->mt), lazy(c->mt);
        cut::CutMesh expected, out;
        const Recorder source(field);
        std::vector<float> written(field.size(), -1.0f);
        if (keep) {
          EXPECT_TRUE(full.refine(
              cut::Refinement::from_root(cut::AllowedError::from_vertices(field)).within(budget).keeping(),
              expected));
          EXPECT_TRUE(lazy.refine(cut::Refinement::from_root(source, written).within(budget).keeping(), out));
          EXPECT_EQ(lazy.budget_threshold(), full.budget_threshold());
        } else {
          EXPECT_TRUE(full.refine(
              cut::Refinement::from_root(cut::AllowedError::from_vertices(field)).within(budget), expected));
          EXPECT_TRUE(lazy.refine(cut::Refinement::from_root(source, written).within(budget), out));
        }
        EXPECT_EQ(test::triangle_set(out.triangles), test::triangle_set(expected.triangles)) << round;
        EXPECT_EQ(out.max_error, expected.max_error);
        std::size_t asked = 0;
        for (std::uint32_t v = 0; v < field.size(); ++v) {
          ASSERT_LE(source.asked()[v], 1) << "vertex " << v;
          asked += source.asked()[v];
          if (source.asked()[v]) ASSERT_EQ(written[v], field[v]);
        }
        for (const std::uint32_t v : out.triangles) ASSERT_EQ(source.asked()[v], 1) << "vertex " << v;
        EXPECT_LT(asked, field.size() / 2) << "a budgeted cut asks for a fraction of the vertices";
        // A gaze after a kept start moves the cut as with the full field.
        if (keep) {
          std::vector<float> moved = focus_field(c->mesh, rng, top * 1e-3f, top * 0.3f);
          EXPECT_TRUE(full.refine(
              cut::Refinement::move(cut::AllowedError::from_vertices(moved), {}).within(budget), expected));
          EXPECT_TRUE(lazy.refine(
              cut::Refinement::move(cut::AllowedError::from_vertices(moved), {}).within(budget), out));
          EXPECT_EQ(test::triangle_set(out.triangles), test::triangle_set(expected.triangles)) << round;
        }
      }
    }
  }
}

TEST(Refine, UniformStaticEqualsTheNaiveFixpoint) {
  // The uniform case reads the cut off a prefix of the node order; the reference forces from the root.
  for (const MtCase* c :
       {test::shape_case(eval::Shape::kSphere, 8'000), test::scan_case("dragon-vrip-res4-11k.ply")}) {
    if (!c) continue;
    const float top = max_node_error(c->mt);
    cut::Refiner refiner(c->mt);
    cut::CutMesh out;
    for (const float e : {top * 2, top, top * 0.3f, top * 0.01f, top * 1e-4f, 0.0f, -1.0f}) {
      const cut::AllowedError allowed = cut::AllowedError::everywhere(e);
      EXPECT_TRUE(refiner.refine(cut::Refinement::from_root(allowed), out));
      const std::vector<std::uint8_t> expected = naive_minimal_cut(c->mt, allowed);
      std::vector<std::uint32_t> expected_nodes;
      for (std::uint32_t n = 0; n < expected.size(); ++n)
        if (expected[n]) expected_nodes.push_back(n);
      ASSERT_EQ(sorted_nodes(refiner), expected_nodes) << "e " << e;
      EXPECT_EQ(out.node_count, expected_nodes.size());
    }
  }
}

// Conformity on every shared scan up to 70k triangles, uniform and per-vertex fields.
TEST(Refine, RandomThresholdsGiveConformingCutsOnRealScans) {
  std::mt19937 rng(11);
  int meshes = 0;
  for (const char* name :
       {"bunny-npm-3k.ply", "dragon-vrip-res4-11k.ply", "lucy-15k.ply", "armadillo-52k.ply",
        "bunny-zipper-69k.ply", "large:dragon-vrip-res4-11k.ply", "large:armadillo-52k.ply"}) {
    const MtCase* c = scan_or_large_case(name);
    const char* file = name;
    if (!c) continue;
    ++meshes;
    const float top = max_node_error(c->mt);
    std::uniform_real_distribution<float> exponent(-5.0f, 0.0f);
    cut::Refiner refiner(c->mt);
    cut::CutMesh out;
    for (int round = 0; round < 8; ++round) {
      const float e = top * std::pow(10.0f, exponent(rng));
      if (round % 2 == 0) {
        EXPECT_TRUE(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(e)), out));
        EXPECT_LE(out.max_error, e);
      } else {
        const std::vector<float> field = focus_field(c->mesh, rng, e * 0.01f, e);
        EXPECT_TRUE(refiner.refine(cut::Refinement::from_root(cut::AllowedError::from_vertices(field)), out));
      }
      ASSERT_TRUE(test::validate_cut(c->reference, out.triangles))
          << file << " round " << round << " e " << e;
    }
  }
  if (meshes == 0) GTEST_SKIP() << "no shared meshes";
}

// For a uniform threshold e, every input vertex lies within e of the cut (exact point–triangle
// distances). The 1e-5 relative slack covers float rounding of positions inside the distance.
TEST(Refine, EveryInputVertexIsWithinTheThresholdOfTheCut) {
  int meshes = 0;
  for (const char* file :
       {"bunny-npm-3k.ply", "lucy-15k.ply", "armadillo-52k.ply", "bunny-zipper-69k.ply",
        "dragon-vrip-res4-11k.ply", "large:dragon-vrip-res4-11k.ply", "large:armadillo-52k.ply"}) {
    const MtCase* c = scan_or_large_case(file);
    if (!c) continue;
    ++meshes;
    const float diagonal = bbox_diagonal(c->mesh);
    cut::CutMesh out;
    for (const float relative : {0.001f, 0.004f, 0.02f, 0.1f}) {
      const float e = diagonal * relative;
      cut::refine_static(c->mt, cut::AllowedError::everywhere(e), out);
      ASSERT_LE(out.max_error, e);
      std::vector<double> bound(c->mesh.vertex_count(), double(e) * (1 + 1e-5));
      EXPECT_TRUE(test::every_vertex_within(c->mesh, out.triangles, bound))
          << file << " e " << e << " (" << out.triangle_count() << " triangles)";
    }
  }
  if (meshes == 0) GTEST_SKIP() << "no shared meshes";
}

TEST(Refine, BudgetIsNeverExceededAndCutsStayConforming) {
  std::mt19937 rng(5);
  for (const MtCase* c :
       {test::scan_case("bunny-npm-3k.ply"), test::scan_case("dragon-vrip-res4-11k.ply"),
        test::scan_case("armadillo-52k.ply"), test::shape_case(eval::Shape::kTerrain, 3'000)}) {
    if (!c) continue;
    cut::Refiner refiner(c->mt);
    cut::CutMesh out;
    const std::size_t root = c->mt.root_triangle_count(), full = c->mesh.triangle_count();
    std::size_t previous = 0;
    std::vector<std::size_t> budgets;
    for (int i = 0; i < 6; ++i)
      budgets.push_back(std::uniform_int_distribution<std::size_t>(root, full)(rng));
    std::sort(budgets.begin(), budgets.end());
    for (const std::size_t budget : budgets) {
      // allowed 0 everywhere: every triangle with an error fails, ranked by error.
      EXPECT_TRUE(refiner.refine(
          cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(budget), out));
      EXPECT_TRUE(out.within_budget);
      ASSERT_LE(out.triangle_count(), budget);
      EXPECT_GE(out.triangle_count(), previous) << "a larger budget gave fewer triangles";
      previous = out.triangle_count();
      ASSERT_TRUE(test::validate_cut(c->reference, out.triangles));
      // A per-vertex field goes through the ratio heap instead of the node order.
      const float top = max_node_error(c->mt);
      const std::vector<float> field = focus_field(c->mesh, rng, top * 1e-4f, top * 0.1f);
      EXPECT_TRUE(refiner.refine(
          cut::Refinement::from_root(cut::AllowedError::from_vertices(field)).within(budget), out));
      ASSERT_LE(out.triangle_count(), budget);
      ASSERT_TRUE(test::validate_cut(c->reference, out.triangles));
    }
    // Allowed -1: every triangle with a remover fails, so an ample budget ends at the input.
    EXPECT_TRUE(
        refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(-1.0f)).within(full), out));
    EXPECT_EQ(test::triangle_set(out.triangles), test::triangle_set(c->mesh.triangles));
    EXPECT_TRUE(refiner.refine(
        cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(root - 1), out));
    EXPECT_FALSE(out.within_budget);
    EXPECT_EQ(out.triangle_count(), root);
  }
}

TEST(Refine, UnlimitedBudgetEqualsStaticRefinement) {
  std::mt19937 rng(3);
  for (const MtCase* c :
       {test::scan_case("bunny-npm-3k.ply"), test::shape_case(eval::Shape::kSphere, 8'000)}) {
    if (!c) continue;
    const float top = max_node_error(c->mt);
    cut::Refiner refiner(c->mt);
    cut::CutMesh budgeted, fixed;
    for (int round = 0; round < 4; ++round) {
      const std::vector<float> field = focus_field(c->mesh, rng, top * 1e-3f, top * 0.2f);
      const cut::AllowedError allowed = cut::AllowedError::from_vertices(field);
      EXPECT_TRUE(refiner.refine(
          cut::Refinement::from_root(allowed).within(std::numeric_limits<std::size_t>::max()), budgeted));
      cut::refine_static(c->mt, allowed, fixed);
      EXPECT_EQ(test::triangle_set(budgeted.triangles), test::triangle_set(fixed.triangles));
    }
  }
}

TEST(Refine, BudgetRefinesTheWorstRatioFirst) {
  // Uniform allowed error: worst ratio first means largest error first. When the budget stops the
  // refinement with max error m left in the cut, every triangle above m was refined (so the cut
  // contains the static cut for m), and only triangles of error ≥ m were (so it lies inside the
  // static cut for the float just below m). Any other order breaks the second inclusion.
  for (const MtCase* c :
       {test::scan_case("bunny-npm-3k.ply"), test::shape_case(eval::Shape::kSphere, 8'000)}) {
    if (!c) continue;
    cut::Refiner budgeted(c->mt), fixed(c->mt);
    cut::CutMesh out, reference;
    for (std::size_t budget = c->mt.root_triangle_count() + 10; budget < c->mesh.triangle_count();
         budget += 397) {
      EXPECT_TRUE(budgeted.refine(
          cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(budget), out));
      const std::vector<std::uint32_t> nodes = sorted_nodes(budgeted);
      EXPECT_TRUE(
          fixed.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(out.max_error)), reference));
      const std::vector<std::uint32_t> lower = sorted_nodes(fixed);
      EXPECT_TRUE(fixed.refine(
          cut::Refinement::from_root(cut::AllowedError::everywhere(std::nextafter(out.max_error, 0.0f))),
          reference));
      const std::vector<std::uint32_t> upper = sorted_nodes(fixed);
      EXPECT_TRUE(std::includes(nodes.begin(), nodes.end(), lower.begin(), lower.end())) << budget;
      EXPECT_TRUE(std::includes(upper.begin(), upper.end(), nodes.begin(), nodes.end())) << budget;
    }
  }
}

// CutMesh::ids names each triangle: the MT triangle with that id has exactly those corners.
void expect_ids_name_triangles(const model::Mt& mt, const cut::CutMesh& cut) {
  ASSERT_EQ(cut.ids.size(), cut.triangle_count());
  for (std::size_t i = 0; i < cut.ids.size(); ++i) {
    std::uint32_t corners[3];
    mt.triangle_vertices(cut.ids[i], corners);
    ASSERT_TRUE(std::equal(corners, corners + 3, &cut.triangles[3 * i]))
        << "triangle " << i << " id " << cut.ids[i];
  }
}

// Dynamic refinement after random sequences of fields equals static refinement of the last field.
void expect_dynamic_matches_static(const MtCase* c, std::uint32_t seed, int steps) {
  std::mt19937 rng(seed);
  const float top = max_node_error(c->mt);
  cut::Refiner dynamic(c->mt), fixed(c->mt);
  cut::CutMesh moving, reference;
  std::vector<float> field = focus_field(c->mesh, rng, top * 1e-3f, top * 0.3f);
  std::vector<std::uint32_t> changed;
  for (int step = 0; step < steps; ++step) {
    const int kind = std::uniform_int_distribution<int>(0, 6)(rng);
    float uniform = -1.0f;  // < 0: use the per-vertex field
    if (kind == 0) {
      uniform = top * std::pow(10.0f, std::uniform_real_distribution<float>(-4, 0)(rng));
    } else if (kind == 1) {
      field = focus_field(c->mesh, rng, top * 1e-3f, top * 0.3f);
    } else if (kind == 2) {
      field = noise_field(c->mesh.vertex_count(), rng, top * 1e-3f, top * 0.3f);
    } else if (kind == 3 || kind == 4) {
      // A small change: a few vertices rescaled (kind 4 tells the refiner which ones).
      std::uniform_int_distribution<std::uint32_t> pick(0, std::uint32_t(field.size() - 1));
      std::uniform_real_distribution<float> scale(0.2f, 5.0f);
      changed.clear();
      for (int i = 0; i < 20; ++i) {
        changed.push_back(pick(rng));
        field[changed.back()] *= scale(rng);
      }
    }  // kind 6: the same field again
    const cut::AllowedError allowed =
        uniform >= 0 ? cut::AllowedError::everywhere(uniform) : cut::AllowedError::from_vertices(field);
    if (kind == 5) {
      cut::CutMesh other;  // interleaved budgeted and static calls reset the kept cut
      if (std::uniform_int_distribution<int>(0, 1)(rng))
        EXPECT_TRUE(dynamic.refine(cut::Refinement::from_root(allowed).within(500), other));
      else
        EXPECT_TRUE(dynamic.refine(cut::Refinement::from_root(allowed), other));
      expect_ids_name_triangles(c->mt, other);
    }
    if (kind == 4 && step % 2 == 0) {
      EXPECT_TRUE(dynamic.refine(cut::Refinement::move(allowed, changed), moving));
    } else if (kind == 4) {
      // The same through a view (of the kept mesh, or of the scratch after a restart).
      cut::CutMesh scratch;
      moving.assign(dynamic.refine_view(cut::Refinement::move(allowed, changed), scratch).value());
    } else if (kind == 6) {
      const std::size_t unchanged = dynamic.unchanged_updates();
      const std::vector<std::uint32_t> before = moving.ids;
      EXPECT_TRUE(dynamic.refine(cut::Refinement::move(allowed, std::span<const std::uint32_t>()),
                                 moving));  // nothing changed
      // Returned as kept: the same triangles in the same order (a delta of nothing).
      if (dynamic.unchanged_updates() > unchanged) {
        ASSERT_EQ(moving.ids, before) << "step " << step;
      }
    } else {
      EXPECT_TRUE(dynamic.refine(cut::Refinement::move(allowed), moving));
    }
    EXPECT_TRUE(fixed.refine(cut::Refinement::from_root(allowed), reference));
    ASSERT_EQ(test::triangle_set(moving.triangles), test::triangle_set(reference.triangles))
        << "step " << step;
    ASSERT_EQ(sorted_nodes(dynamic), sorted_nodes(fixed)) << "step " << step;
    ASSERT_EQ(moving.max_error, reference.max_error);
    ASSERT_EQ(moving.node_count, reference.node_count);
    expect_ids_name_triangles(c->mt, moving);
    expect_ids_name_triangles(c->mt, reference);
  }
  // Both ways of updating ran: moving the kept cut, and refining afresh from the nodes that stay
  // after a large drop or addition.
  EXPECT_GT(dynamic.restarts(), 0u);
  EXPECT_GT(dynamic.moves(), static_cast<std::size_t>(steps) / 8);
  EXPECT_GT(dynamic.unchanged_updates(), 0u);  // and returning the kept cut when nothing changed
}

// What a session does with an on-demand field (core/view/view_extract.cpp): values for the vertices asked
// for, which become known; at each new field the known vertices whose value changed are updated
// and listed; at times everything but the cut's vertices is forgotten. Unknown entries hold -1,
// which fails every triangle: a refinement that read one would refine more than the reference.
class KnownField final : public cut::VertexErrorSource {
 public:
  explicit KnownField(std::size_t n) : field(n, -1.0f), known_(n, 0) {}
  float vertex_allowed_error(std::uint32_t v) const override {
    known_[v] = 1;
    ++asked;
    return (*current_)[v];
  }
  // The next field: updates the known vertices and lists those that changed.
  void set(const std::vector<float>& next, std::vector<std::uint32_t>& changed) {
    current_ = &next;
    changed.clear();
    for (std::uint32_t v = 0; v < field.size(); ++v) {
      if (!known_[v] || field[v] == next[v]) continue;
      field[v] = next[v];
      changed.push_back(v);
    }
  }
  void forget_all_but_the_cut(cut::Refiner& refiner) {
    std::vector<std::uint8_t> read(field.size(), 0);
    refiner.for_each_cut_vertex([&](std::uint32_t v) { read[v] = 1; });
    for (std::uint32_t v = 0; v < field.size(); ++v) {
      ASSERT_TRUE(!read[v] || known_[v]) << "the cut reads vertex " << v << ", never asked for";
      if (!read[v]) known_[v] = 0, field[v] = -1.0f;
    }
  }
  std::vector<float> field;
  mutable std::size_t asked = 0;

 private:
  const std::vector<float>* current_ = nullptr;
  mutable std::vector<std::uint8_t> known_;
};

// On-demand updates (a session's gazes) give the cuts of the full field while reading only values
// they asked for since the view began, with or without a budget, whatever was forgotten meanwhile.
TEST(Refine, OnDemandUpdatesEqualTheFullFieldAndReadOnlyWhatWasAskedFor) {
  std::mt19937 rng(19);
  for (const MtCase* c :
       {test::shape_case(eval::Shape::kSphere, 8'000), test::scan_case("armadillo-52k.ply")}) {
    if (!c) continue;
    const model::Mt& mt = c->mt;
    const float top = max_node_error(mt);
    for (const bool budgeted : {false, true}) {
      cut::Refiner lazy(mt), full(mt);
      KnownField known(mt.vertex_count());
      cut::CutMesh out, expected;
      std::vector<std::uint32_t> changed;
      std::vector<float> field;
      const std::size_t budget = 3'000;
      for (int step = 0; step < 30; ++step) {
        // Mostly small moves of a focus, a jump now and then.
        field = focus_field(c->mesh, rng, top * 1e-3f, top * 0.3f);
        known.set(field, changed);
        cut::CutSpan cut;
        if (step == 0) {
          if (budgeted) {
            EXPECT_TRUE(
                lazy.refine(cut::Refinement::from_root(known, known.field).within(budget).keeping(), out));
          } else {
            EXPECT_TRUE(lazy.refine(cut::Refinement::from_root(known, known.field), out));
          }
          cut = cut::CutSpan::of(out);
        } else if (budgeted) {
          EXPECT_TRUE(lazy.refine(cut::Refinement::move(known, known.field, changed).within(budget), out));
          cut = cut::CutSpan::of(out);
        } else {
          cut = lazy.refine_view(cut::Refinement::move(known, known.field, changed), out).value();
        }
        if (budgeted) {
          EXPECT_TRUE(full.refine(
              cut::Refinement::from_root(cut::AllowedError::from_vertices(field)).within(budget), expected));
        } else {
          EXPECT_TRUE(
              full.refine(cut::Refinement::from_root(cut::AllowedError::from_vertices(field)), expected));
        }
        ASSERT_EQ(test::triangle_set(cut.triangles), test::triangle_set(expected.triangles))
            << "step " << step << (budgeted ? ", budgeted" : "");
        if (step % 4 == 3) known.forget_all_but_the_cut(lazy);
      }
      EXPECT_GT(lazy.moves() + lazy.restarts(), 0u);
      EXPECT_LT(known.asked, 30 * mt.vertex_count() / 4) << "asked for a fraction of the vertices each step";
    }
  }
}

TEST(Refine, DynamicEqualsStaticAfterRandomSequences) {
  int meshes = 0;
  for (const char* file : {"bunny-npm-3k.ply", "dragon-vrip-res4-11k.ply", "armadillo-52k.ply",
                           "large:dragon-vrip-res4-11k.ply"}) {
    if (const MtCase* c = scan_or_large_case(file)) {
      ++meshes;
      expect_dynamic_matches_static(c, 17, 40);
    }
  }
  expect_dynamic_matches_static(test::shape_case(eval::Shape::kTerrain, 3'000), 23, 60);
  expect_dynamic_matches_static(test::shape_case(eval::Shape::kSphere, 8'000), 29, 60);
}

TEST(Refine, MovedCutsKeepTheOrderOfTheTrianglesThatStay) {
  // A client's delta is one ordered pass when the triangles two consecutive cuts share come in the
  // same order in both, but for those appended anew (core/cut/cut_delta.hpp): after small moves,
  // and after jumps of the focus that refine afresh from the nodes kept. Matched in order as that
  // pass does, nearly all shared triangles match; in any other order few would.
  SphereFocusJumps s(37);
  const cut::Refiner& refiner = s.refiner;
  const cut::CutMesh& cut = s.cut;
  std::vector<std::uint32_t> previous;
  std::vector<std::uint8_t> in_cut(s.c->mt.triangle_count());
  std::size_t afresh_shared = 0;
  for (int step = 0; step < 40; ++step) {
    const std::size_t restarts = refiner.restarts();
    ASSERT_TRUE(s.jump(0.02f));
    std::fill(in_cut.begin(), in_cut.end(), 0);
    for (const std::uint32_t id : cut.ids) in_cut[id] = 1;
    std::size_t shared = 0, matched = 0;
    for (const std::uint32_t id : previous) {
      shared += in_cut[id];
      if (matched < cut.ids.size() && cut.ids[matched] == id) ++matched;
    }
    // Those that do not match came back with a node dropped and forced again, appended.
    EXPECT_GE(10 * matched, 7 * shared)
        << "step " << step << (refiner.restarts() > restarts ? ", afresh" : "");
    afresh_shared += refiner.restarts() > restarts ? shared : 0;
    previous = cut.ids;
  }
  EXPECT_GT(refiner.restarts(), 10u);  // the jumps refined afresh
  EXPECT_GT(afresh_shared, 1'000u);
}

// Budgeted dynamic refinement after sequences of fields equals the budgeted refinement from the root
// of the last field: a focus moving in steps (told which vertices changed), jumping, per-vertex
// noise, budgets from near the root's size to more than the whole error-bound cut.
void expect_dynamic_budget_matches_static(const MtCase* c, std::uint32_t seed, int steps) {
  const model::Mt& mt = c->mt;
  // What the method relies on: every node adds triangles, so a cut's size grows with its nodes.
  std::vector<std::uint32_t> removed(mt.node_count(), 0);
  for (std::uint32_t t = 0; t < mt.triangle_count(); ++t)
    if (mt.triangle_remover[t] != model::kNoNode) ++removed[mt.triangle_remover[t]];
  for (std::uint32_t n = 1; n < mt.node_count(); ++n)
    ASSERT_GT(mt.node_triangle_offsets[n + 1] - mt.node_triangle_offsets[n], removed[n]) << "node " << n;

  std::mt19937 rng(seed);
  const float top = max_node_error(mt);
  const float diagonal = bbox_diagonal(c->mesh);
  cut::Refiner dynamic(mt), fixed(mt);
  cut::CutMesh moving, reference, other;
  std::vector<float> field(c->mesh.vertex_count()), previous;
  std::vector<std::uint32_t> changed;
  // Budgets from just above the root's size to twice the error-bound cut's (chosen anew at times).
  std::size_t budget = 0;
  auto pick_budget = [&](std::size_t bound_cut) {
    const std::size_t root = mt.root_triangle_count();
    const std::size_t choices[] = {root + 40, root + (bound_cut - root) / 4, root + (bound_cut - root) / 2,
                                   root + 3 * (bound_cut - root) / 4, 2 * bound_cut};
    budget = choices[std::uniform_int_distribution<int>(0, 4)(rng)];
  };
  float fx = 0.0f, fy = 0.0f, fz = 0.0f;
  std::size_t binding = 0, lowered = 0;
  for (int step = 0; step < steps; ++step) {
    const int kind = std::uniform_int_distribution<int>(0, 9)(rng);
    const float* p =
        &c->mesh.positions[3 * std::uniform_int_distribution<std::size_t>(0, field.size() - 1)(rng)];
    if (step == 0 || kind == 0) {  // the focus jumps
      fx = p[0], fy = p[1], fz = p[2];
    } else if (kind <= 6) {  // it moves a little towards a random vertex
      fx += 0.05f * (p[0] - fx), fy += 0.05f * (p[1] - fy), fz += 0.05f * (p[2] - fz);
    }
    for (std::size_t v = 0; v < field.size(); ++v) {
      const float* q = &c->mesh.positions[3 * v];
      const float d =
          std::sqrt((q[0] - fx) * (q[0] - fx) + (q[1] - fy) * (q[1] - fy) + (q[2] - fz) * (q[2] - fz));
      field[v] = top * (1e-5f + 0.02f * std::min(1.0f, d / (0.3f * diagonal)));
    }
    if (kind == 7) field = noise_field(field.size(), rng, top * 1e-5f, top * 0.02f);
    // Full detail (allowed error 0) near a second point at times, as along a silhouette with factor
    // 0: those triangles rank above all others, by error alone.
    if (step % 3 == 0) {
      for (std::size_t v = 0; v < field.size(); ++v) {
        const float* q = &c->mesh.positions[3 * v];
        const float d = std::abs(q[0] - p[0]) + std::abs(q[1] - p[1]) + std::abs(q[2] - p[2]);
        if (d < (step % 2 ? 0.1f : 0.3f) * diagonal) field[v] = 0.0f;
      }
    }
    changed.clear();
    for (std::uint32_t v = 0; v < field.size(); ++v)
      if (previous.empty() || field[v] != previous[v]) changed.push_back(v);
    const cut::AllowedError allowed = cut::AllowedError::from_vertices(field);
    EXPECT_TRUE(fixed.refine(cut::Refinement::from_root(allowed), other));
    if (step == 0 || kind == 8) pick_budget(other.triangle_count());
    binding += other.triangle_count() > budget;
    if (kind == 9) {
      // Other refinements in between: the next budgeted update starts again or moves from their cut.
      if (std::uniform_int_distribution<int>(0, 1)(rng))
        EXPECT_TRUE(dynamic.refine(cut::Refinement::move(allowed), other));
      else
        EXPECT_TRUE(dynamic.refine(cut::Refinement::from_root(allowed).within(budget / 2), other));
    }
    const std::optional<cut::Rank> before = dynamic.budget_threshold();
    if (step % 7 == 3)
      EXPECT_TRUE(dynamic.refine(cut::Refinement::from_root(allowed).within(budget).keeping(), moving));
    else
      EXPECT_TRUE(dynamic.refine(cut::Refinement::move(allowed, changed).within(budget), moving));
    lowered += before && dynamic.budget_threshold() && *dynamic.budget_threshold() < *before;
    previous = field;
    EXPECT_TRUE(fixed.refine(cut::Refinement::from_root(allowed).within(budget), reference));
    ASSERT_EQ(test::triangle_set(moving.triangles), test::triangle_set(reference.triangles))
        << "step " << step << " budget " << budget;
    ASSERT_EQ(moving.max_error, reference.max_error) << "step " << step;
    ASSERT_EQ(moving.node_count, reference.node_count) << "step " << step;
    ASSERT_EQ(moving.within_budget, reference.within_budget) << "step " << step;
    if (reference.within_budget) {
      ASSERT_LE(moving.triangle_count(), budget);
    }
    expect_ids_name_triangles(mt, moving);
  }
  // The budget bound the cut (the error-bound cut was larger) in most steps; the threshold was
  // raised past the budget, lowered far below it, and kept between.
  EXPECT_GT(binding, std::size_t(steps) / 2);
  EXPECT_GT(dynamic.budget_raises(), 0u);
  EXPECT_GT(lowered, 0u);
  EXPECT_LT(dynamic.budget_starts(), std::size_t(steps) / 2);
}

// Moves of a kept cut whose field changes only where listed while its threshold rises and falls,
// as a scene's shared budget moves each instance's (a rise is tested against the witnesses alone).
TEST(Refine, MovesAcrossRisingAndFallingThresholdsEqualStatic) {
  const MtCase* c = test::scan_case("dragon-vrip-res4-11k.ply");
  if (!c) GTEST_SKIP() << "no shared meshes";
  std::mt19937 rng(23);
  const float top = max_node_error(c->mt);
  cut::Refiner dynamic(c->mt), fixed(c->mt);
  cut::CutMesh moving, reference;
  std::vector<float> field = focus_field(c->mesh, rng, top * 1e-3f, top * 0.3f);
  std::vector<std::uint32_t> changed;
  std::uniform_int_distribution<std::uint32_t> pick(0, std::uint32_t(field.size() - 1));
  std::uniform_real_distribution<float> scale(0.2f, 5.0f), exponent(0.0f, 1.5f);
  int rises = 0, falls = 0;
  cut::Rank previous;
  for (int step = 0; step < 40; ++step) {
    changed.clear();
    if (step % 3 == 2) {  // now and then a few vertices change too
      for (int i = 0; i < 20; ++i) {
        changed.push_back(pick(rng));
        field[changed.back()] *= scale(rng);
      }
    }
    cut::AllowedError allowed = cut::AllowedError::from_vertices(field);
    allowed.threshold = cut::Rank{0, std::pow(10.0f, exponent(rng))};
    rises += previous < allowed.threshold, falls += allowed.threshold < previous;
    previous = allowed.threshold;
    EXPECT_TRUE(dynamic.refine(cut::Refinement::move(allowed, changed), moving));
    EXPECT_TRUE(fixed.refine(cut::Refinement::from_root(allowed), reference));
    ASSERT_EQ(test::triangle_set(moving.triangles), test::triangle_set(reference.triangles))
        << "step " << step << " threshold " << allowed.threshold.key;
    ASSERT_EQ(moving.node_count, reference.node_count) << "step " << step;
  }
  EXPECT_GT(rises, 5);
  EXPECT_GT(falls, 5);
}

TEST(Refine, DynamicBudgetEqualsBudgetFromTheRoot) {
  for (const char* file : {"bunny-npm-3k.ply", "dragon-vrip-res4-11k.ply", "armadillo-52k.ply"})
    if (const MtCase* c = test::scan_case(file)) expect_dynamic_budget_matches_static(c, 41, 60);
  expect_dynamic_budget_matches_static(test::shape_case(eval::Shape::kTerrain, 3'000), 43, 80);
  expect_dynamic_budget_matches_static(test::shape_case(eval::Shape::kSphere, 8'000), 47, 80);
}

TEST(CutDelta, AppliedChangesRebuildEveryCutOfASequence) {
  // A client that applies each delta (the ids to drop, the gathered triangles with their ids) to a
  // mesh keyed by id holds exactly the latest cut: its ids, each with its corners.
  SphereFocusJumps s(31);
  const cut::CutMesh& cut = s.cut;
  const std::size_t n = s.c->mt.triangle_count();
  cut::CutDelta delta;
  std::map<std::uint32_t, std::array<std::uint32_t, 3>> client;
  std::vector<std::uint32_t> added, removed, triangles, ids;
  std::size_t partial = 0;
  for (int step = 0; step < 30; ++step) {
    if (step == 20) delta.reset();  // the client starts over
    EXPECT_TRUE(s.jump(0.3f));
    const bool from_empty = delta.update(cut.ids, n, added, removed);
    EXPECT_EQ(from_empty, step == 0 || step == 20) << step;
    if (from_empty) client.clear();
    for (const std::uint32_t id : removed)
      ASSERT_EQ(client.erase(id), 1u) << "removed twice or never added: " << id;
    cut::gather_triangles(cut.triangles, cut.ids, added, triangles, ids);
    ASSERT_EQ(triangles.size(), 3 * added.size());
    ASSERT_EQ(ids.size(), added.size());
    for (std::size_t k = 0; k < ids.size(); ++k)
      ASSERT_TRUE(
          client.insert({ids[k], {triangles[3 * k], triangles[3 * k + 1], triangles[3 * k + 2]}}).second)
          << "added twice: " << ids[k];
    std::map<std::uint32_t, std::array<std::uint32_t, 3>> expected;
    for (std::size_t i = 0; i < cut.ids.size(); ++i)
      expected[cut.ids[i]] = {cut.triangles[3 * i], cut.triangles[3 * i + 1], cut.triangles[3 * i + 2]};
    ASSERT_EQ(client, expected) << step;
    partial += !from_empty && added.size() < cut.ids.size();
  }
  EXPECT_GT(partial, 0u);  // deltas were smaller than the cut
  // The same cut again changes nothing, in the same order or another; after a reset it goes whole.
  EXPECT_FALSE(delta.update(cut.ids, n, added, removed));
  EXPECT_TRUE(added.empty() && removed.empty());
  std::vector<std::uint32_t> shuffled = cut.ids;
  std::shuffle(shuffled.begin(), shuffled.end(), s.rng);
  EXPECT_FALSE(delta.update(shuffled, n, added, removed));
  EXPECT_TRUE(added.empty() && removed.empty());
  delta.reset();
  EXPECT_TRUE(delta.update(shuffled, n, added, removed));
  EXPECT_EQ(added.size(), shuffled.size());
  EXPECT_TRUE(removed.empty());
  // Another model (a different triangle count) starts from empty as well.
  EXPECT_TRUE(delta.update(std::vector<std::uint32_t>{0, 1}, 2, added, removed));
  EXPECT_EQ(added.size(), 2u);
  EXPECT_TRUE(removed.empty());
}

TEST(CutDelta, KeptOrderAppendedTailAndReorderedCutsGiveTheSameChanges) {
  // A moved cut (the triangles that stay in their order, new ones appended) and cuts in any other
  // order: the positions new to the client and the ids it drops, worked out by hand.
  cut::CutDelta delta;
  std::vector<std::uint32_t> added, removed;
  using Ids = std::vector<std::uint32_t>;
  EXPECT_TRUE(delta.update(Ids{1, 2, 3, 4}, 10, added, removed));
  EXPECT_EQ(added, (Ids{0, 1, 2, 3}));
  EXPECT_FALSE(delta.update(Ids{1, 3, 4, 7, 8}, 10, added, removed));  // 2 dropped, 7 and 8 appended
  EXPECT_EQ(added, (Ids{3, 4}));
  EXPECT_EQ(removed, (Ids{2}));
  EXPECT_FALSE(delta.update(Ids{3, 1, 4, 8, 9}, 10, added, removed));  // reordered, 7 dropped, 9 new
  EXPECT_EQ(added, (Ids{4}));
  EXPECT_EQ(removed, (Ids{7}));
  EXPECT_FALSE(delta.update(Ids{3, 5, 1, 4, 8, 9, 7}, 10, added, removed));  // inserted in the middle
  EXPECT_EQ(added, (Ids{1, 6}));
  EXPECT_TRUE(removed.empty());
  EXPECT_FALSE(delta.update(Ids{5, 4, 8, 9, 7, 3}, 10, added, removed));  // 1 dropped, 3 moved to the end
  EXPECT_TRUE(added.empty());
  EXPECT_EQ(removed, (Ids{1}));
  EXPECT_FALSE(delta.update(Ids{5, 4, 9, 3, 0}, 10, added, removed));  // 8 and 7 dropped, 0 appended
  EXPECT_EQ(added, (Ids{4}));
  EXPECT_EQ(removed, (Ids{8, 7}));
  // Most of a cut replaced, the rest in order (a saccade refined afresh), then again out of order.
  EXPECT_FALSE(delta.update(Ids{5, 9, 1, 2, 6, 7, 8}, 10, added, removed));  // 4, 3 and 0 dropped
  EXPECT_EQ(added, (Ids{2, 3, 4, 5, 6}));
  EXPECT_EQ(removed, (Ids{4, 3, 0}));
  EXPECT_FALSE(delta.update(Ids{8, 0, 3, 4}, 10, added, removed));
  EXPECT_EQ(added, (Ids{1, 2, 3}));
  EXPECT_EQ(removed, (Ids{5, 9, 1, 2, 6, 7}));
}

TEST(Refine, DynamicAfterSmallMovesOfTheFocusEqualsStatic) {
  // The expected use: a focus drifting a little between requests.
  const MtCase* c = test::scan_case("bunny-zipper-69k.ply");
  if (!c) GTEST_SKIP();
  const float top = max_node_error(c->mt);
  const float diagonal = bbox_diagonal(c->mesh);
  cut::Refiner dynamic(c->mt);
  cut::CutMesh moving, reference;
  std::vector<float> field(c->mesh.vertex_count());
  for (int step = 0; step < 12; ++step) {
    const float fx = -0.05f + 0.01f * step;  // the focus walks along x through the model
    for (std::size_t v = 0; v < field.size(); ++v) {
      const float* p = &c->mesh.positions[3 * v];
      const float d = std::sqrt((p[0] - fx) * (p[0] - fx) + (p[1] - 0.1f) * (p[1] - 0.1f) + p[2] * p[2]);
      field[v] = top * (1e-3f + 0.1f * std::min(1.0f, d / (0.2f * diagonal)));
    }
    EXPECT_TRUE(dynamic.refine(cut::Refinement::move(cut::AllowedError::from_vertices(field)), moving));
    cut::refine_static(c->mt, cut::AllowedError::from_vertices(field), reference);
    ASSERT_EQ(test::triangle_set(moving.triangles), test::triangle_set(reference.triangles))
        << "step " << step;
  }
  EXPECT_TRUE(test::validate_cut(c->reference, moving.triangles));
}

// The 871k dragon: one build, a few cuts (this test dominates the suite's time, keep it small).
TEST(Refine, FullResolutionDragonCutsAreConformingAndDynamicMatchesStatic) {
  const MtCase* c = test::scan_case("dragon-vrip-871k.ply");
  if (!c) GTEST_SKIP() << "dragon-vrip-871k.ply absent";
  cut::CutMesh out;
  cut::refine_static(c->mt, cut::AllowedError::everywhere(-1.0f), out);
  EXPECT_EQ(test::triangle_set(out.triangles), test::triangle_set(c->mesh.triangles));
  const float diagonal = bbox_diagonal(c->mesh);
  cut::Refiner dynamic(c->mt);
  cut::CutMesh moving;
  std::mt19937 rng(1);
  for (const float relative : {0.02f, 0.002f}) {
    cut::refine_static(c->mt, cut::AllowedError::everywhere(diagonal * relative), out);
    EXPECT_LE(out.max_error, diagonal * relative);
    EXPECT_TRUE(test::validate_cut(c->reference, out.triangles)) << relative;
    const std::vector<float> field =
        focus_field(c->mesh, rng, diagonal * relative * 0.1f, diagonal * relative);
    EXPECT_TRUE(dynamic.refine(cut::Refinement::move(cut::AllowedError::from_vertices(field)), moving));
    cut::refine_static(c->mt, cut::AllowedError::from_vertices(field), out);
    EXPECT_EQ(test::triangle_set(moving.triangles), test::triangle_set(out.triangles));
  }
}

}  // namespace
}  // namespace mtlod::core
