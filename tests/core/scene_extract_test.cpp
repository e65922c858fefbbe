// Scenes in core (scene_extract): one instance is the single-model pipeline's cut, a placed
// instance keeps the bound in the world, an instance hidden behind another stays at its root, two
// instances meeting in the picture seed its silhouette, and one budget is spent across instances.
#include "core/view/scene_extract.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <set>
#include <vector>

#include "core/eval/mesh_gen.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/view_extract.hpp"
#include "tests/core/mt_fixtures.hpp"

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/mat4x4.hpp>

namespace mtlod::core {
namespace {

struct Model {
  const test::MtCase* built = nullptr;
  std::unique_ptr<view::OccupancyLevels> levels;
};

// A noisy sphere of about 20k triangles, radius about 1 around the origin: closed, so a single
// model's occupancy (which may skip back faces) and a scene's (which never does) mark the same cells.
const Model& sphere() {
  static const Model model = [] {
    Model m;
    m.built = test::shape_case(eval::Shape::kSphere, 20'000);
    m.levels = view::OccupancyLevels::make(m.built->mt).value();
    return m;
  }();
  return model;
}

// From (0, 0, 6) towards the origin, 45° vertical field of view, a 256² grid; a pixel bound with the
// silhouette criterion (2 px, factor 0.25).
view::ViewRequest pixel_request(float error_px = 1.0f) {
  view::ViewRequest r;
  r.camera.view = glm::lookAt(glm::vec3(0, 0, 6), glm::vec3(0), glm::vec3(0, 1, 0));
  r.camera.projection = glm::perspective(glm::radians(45.0f), 1.0f, 0.1f, 100.0f);
  r.grid = {256, 256};
  r.allowed.error = error_px;
  r.allowed.units = view::ErrorUnits::kScreenPixels;
  r.allowed.criteria[view::Criterion::kSilhouette] = view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 0.25f};
  r.dynamic = false;
  return r;
}

view::SceneInstance instance(const Model& m, const glm::mat4& matrix) {
  return {&m.built->mt, m.levels.get(), matrix};
}

std::multiset<std::uint32_t> ids_of(const cut::CutMesh& cut) {
  return {cut.ids.begin(), cut.ids.end()};
}

std::vector<cut::CutMesh> extract(view::SceneExtractor& x, const view::ViewRequest& r,
                                  const std::vector<view::SceneInstance>& instances,
                                  view::SceneStats* stats = nullptr) {
  std::vector<cut::CutMesh> cuts;
  auto result = x.extract({r, instances}, cuts);
  EXPECT_TRUE(result.ok()) << result.error().message;
  if (stats && result.ok()) *stats = *result;
  return cuts;
}

TEST(SceneExtract, OneInstanceIsTheSingleModelCut) {
  const Model& m = sphere();
  for (const bool internal : {false, true}) {
    view::ViewRequest r = pixel_request();
    r.internal_silhouettes = internal;
    r.camera.model = glm::rotate(glm::translate(glm::mat4(1), glm::vec3(0.3f, -0.2f, 0.5f)), 0.7f,
                                 glm::vec3(0.2f, 1, 0.1f));
    view::ViewExtractor single(m.built->mt, *m.levels);
    cut::Refiner refiner(m.built->mt);
    cut::CutMesh scratch, expected;
    const auto extracted = single.extract(r, refiner, scratch);
    ASSERT_TRUE(extracted.ok());
    expected.assign(*extracted);

    view::SceneExtractor x;
    view::SceneStats stats;
    const auto cuts = extract(x, r, {instance(m, r.camera.model)}, &stats);
    ASSERT_EQ(cuts.size(), 1u);
    EXPECT_EQ(ids_of(cuts[0]), ids_of(expected)) << "internal silhouettes " << internal;
    EXPECT_EQ(stats.triangles, expected.triangle_count());
    EXPECT_EQ(stats.passes, 1u);
    EXPECT_EQ(stats.instances_in_view, 1u);
    EXPECT_GT(expected.triangle_count(), m.built->mt.root_triangle_count());
  }
}

TEST(SceneExtract, AScaledInstanceKeepsAModelUnitBoundInTheWorld) {
  // No criteria and nothing outside the view: every vertex is allowed e / s, so the cut is the
  // MT's uniform cut at e / s.
  const Model& m = sphere();
  const model::Mt& mt = m.built->mt;
  view::ViewRequest r = pixel_request();
  r.allowed.units = view::ErrorUnits::kModel;
  r.allowed.criteria[view::Criterion::kSilhouette].reset();
  r.allowed.outside_view_factor = 1.0f;
  r.allowed.error = 0.004f;
  for (const float scale : {0.5f, 1.0f, 2.0f}) {
    const glm::mat4 matrix =
        glm::scale(glm::rotate(glm::mat4(1), 0.5f, glm::vec3(0, 1, 0)), glm::vec3(scale));
    view::SceneExtractor x;
    const auto cuts = extract(x, r, {instance(m, matrix)});
    cut::Refiner refiner(mt);
    cut::CutMesh uniform;
    ASSERT_TRUE(refiner.refine(
        cut::Refinement::from_root(cut::AllowedError::everywhere(r.allowed.error / scale)), uniform));
    EXPECT_EQ(ids_of(cuts[0]), ids_of(uniform)) << "scale " << scale;
    EXPECT_LE(cuts[0].max_error * scale, r.allowed.error * (1 + 1e-6f));
  }
}

TEST(SceneExtract, AnInstanceHiddenBehindAnotherStaysAtItsRoot) {
  const Model& m = sphere();
  const std::size_t root = m.built->mt.root_triangle_count();
  // A sphere of radius about 2.5 at the origin hides one of radius 0.5 four units behind it.
  const glm::mat4 front = glm::scale(glm::mat4(1), glm::vec3(2.5f));
  const glm::mat4 back = glm::scale(glm::translate(glm::mat4(1), glm::vec3(0, 0, -4)), glm::vec3(0.5f));
  view::ViewRequest r = pixel_request(0.5f);
  r.allowed.hidden_factor = 1e6f;
  view::SceneExtractor x;
  view::SceneStats stats;
  auto cuts = extract(x, r, {instance(m, front), instance(m, back)}, &stats);
  EXPECT_EQ(stats.instances_in_view, 2u);
  EXPECT_GT(cuts[0].triangle_count(), 10 * root);
  EXPECT_EQ(cuts[1].triangle_count(), root);
  // The picture shows the front instance only.
  for (const std::uint32_t owner : x.instance_grid()) EXPECT_NE(owner, 1u);

  // Without hidden-surface coarsening the same instance is refined: it is the occlusion that costs nothing.
  r.allowed.hidden_factor = 1.0f;
  cuts = extract(x, r, {instance(m, front), instance(m, back)});
  EXPECT_GT(cuts[1].triangle_count(), 2 * root);
}

TEST(SceneExtract, AnInstanceHiddenJustInsideAnOutlineCostsItsRoot) {
  // A unit sphere at the origin hides a sphere four units behind it whose outline falls a few cells
  // inside its own (95 % of its apparent radius, about 50 cells on this grid): cells there are next
  // to none of the background, and still the hidden instance is at its coarsest cut.
  const Model& m = sphere();
  const std::size_t root = m.built->mt.root_triangle_count();
  const float tan_front = 1.0f / std::sqrt(35.0f);  // the front sphere's apparent radius from z = 6
  const float t = 0.95f * tan_front, back_radius = 10.0f * t / std::sqrt(1.0f + t * t);
  const glm::mat4 back =
      glm::scale(glm::translate(glm::mat4(1), glm::vec3(0, 0, -4)), glm::vec3(back_radius));
  view::ViewRequest r = pixel_request(0.5f);
  r.allowed.hidden_factor = 16.0f;
  view::SceneExtractor x;
  auto cuts = extract(x, r, {instance(m, glm::mat4(1)), instance(m, back)});
  for (const std::uint32_t owner : x.instance_grid()) ASSERT_NE(owner, 1u);
  EXPECT_GT(cuts[0].triangle_count(), 10 * root);
  EXPECT_EQ(cuts[1].triangle_count(), root);
}

TEST(SceneExtract, AnInstanceOutsideTheViewIsNotRasterisedAndStaysAtItsRoot) {
  const Model& m = sphere();
  view::ViewRequest r = pixel_request();
  const glm::mat4 behind = glm::translate(glm::mat4(1), glm::vec3(0, 0, 12));  // behind the camera
  view::SceneExtractor x;
  view::SceneStats stats;
  const auto cuts = extract(x, r, {instance(m, glm::mat4(1)), instance(m, behind)}, &stats);
  EXPECT_EQ(stats.instances_in_view, 1u);
  EXPECT_EQ(cuts[1].triangle_count(), m.built->mt.root_triangle_count());
}

TEST(SceneExtract, WhereTwoInstancesMeetInThePictureIsASilhouette) {
  const Model& m = sphere();
  // Two spheres side by side, the right one nearer and overlapping the left one in the picture.
  const glm::mat4 left = glm::translate(glm::mat4(1), glm::vec3(-0.8f, 0, 0));
  const glm::mat4 right = glm::translate(glm::mat4(1), glm::vec3(0.8f, 0, 1));
  view::ViewRequest r = pixel_request();
  view::SceneExtractor x;
  extract(x, r, {instance(m, left), instance(m, right)});
  const auto owner = x.instance_grid();
  const auto dt = x.distance_transform(view::Criterion::kSilhouette);
  ASSERT_EQ(dt.size(), r.grid.cell_count());
  std::size_t meetings = 0;
  for (std::uint32_t y = 0; y < r.grid.height; ++y) {
    for (std::uint32_t c = r.grid.cell(0, y); c + 1 < r.grid.cell(r.grid.width, y); ++c) {
      const std::uint32_t a = owner[c], b = owner[c + 1];
      if (a == view::SceneExtractor::kNoInstance || b == view::SceneExtractor::kNoInstance || a == b)
        continue;
      ++meetings;
      EXPECT_EQ(std::min(dt[c], dt[c + 1]), 0) << "cells " << c << ", " << c + 1;
    }
  }
  EXPECT_GT(meetings, 20u);  // the overlap runs down a good part of the picture
}

TEST(SceneExtract, OneBudgetIsSpentAcrossInstancesNearestFirst) {
  const Model& m = sphere();
  view::ViewRequest r = pixel_request(0.25f);
  const std::vector<view::SceneInstance> instances{
      instance(m, glm::translate(glm::mat4(1), glm::vec3(-1.2f, 0, 0))),
      instance(m, glm::translate(glm::mat4(1), glm::vec3(1.5f, 0, -4))),
      instance(m, glm::translate(glm::mat4(1), glm::vec3(0, 3, -12))),
  };
  view::SceneExtractor x;
  view::SceneStats unbounded;
  extract(x, r, instances, &unbounded);
  const std::size_t budget = unbounded.triangles / 3;
  r.budget = budget;
  view::SceneStats stats;
  const auto cuts = extract(x, r, instances, &stats);
  std::size_t total = 0;
  for (const cut::CutMesh& c : cuts) total += c.triangle_count();
  EXPECT_EQ(total, stats.triangles);
  EXPECT_LE(total, budget);
  EXPECT_GE(total, 0.9 * static_cast<double>(budget));
  EXPECT_TRUE(stats.within_budget);
  EXPECT_GT(stats.threshold.key, 1.0f);
  // Nearer instances of the same model, at the same threshold, keep more.
  EXPECT_GT(cuts[0].triangle_count(), cuts[1].triangle_count());
  EXPECT_GT(cuts[1].triangle_count(), cuts[2].triangle_count());

  // Each instance's cut is its minimal cut at that one threshold, as a single-model refinement
  // would make it with the same allowed errors: alone in the picture, no instance shares an edge
  // with another here, so the single model's field is the scene's.
  for (std::size_t i = 0; i < instances.size(); ++i) {
    view::ViewRequest alone = r;
    alone.budget.reset();
    alone.camera.model = instances[i].model;
    view::ViewExtractor single(m.built->mt, *m.levels);
    const auto field = single.allowed_error_field(alone);
    cut::Refiner refiner(m.built->mt);
    cut::Refinement what = cut::Refinement::from_root(cut::AllowedError::from_vertices(field));
    what.allowed.threshold = stats.threshold;
    cut::CutMesh expected;
    ASSERT_TRUE(refiner.refine(what, expected));
    EXPECT_EQ(ids_of(cuts[i]), ids_of(expected)) << "instance " << i;
  }
}

TEST(SceneExtract, AGazeInASessionGivesTheCutsOfAFreshExtraction) {
  // A session's gazes skip the occupancy and the other transforms; their cuts are those every stage
  // gives. The view then changes and the session computes it afresh.
  const Model& m = sphere();
  const std::vector<view::SceneInstance> instances{
      instance(m, glm::translate(glm::mat4(1), glm::vec3(-1.2f, 0, 0))),
      instance(m, glm::translate(glm::mat4(1), glm::vec3(0.9f, 0.2f, -2))),
  };
  view::ViewRequest r = pixel_request(2.0f);
  r.allowed.criteria[view::kGazeCriterion] = view::RegionLaw{view::FalloffLaw::kStep, 12.0f, 0.1f};
  r.allowed.hidden_factor = 16.0f;
  view::SceneExtractor in_session, fresh;
  view::SceneCache session;
  const std::array<std::array<float, 2>, 4> gazes{
      {{0.3f, 0.5f}, {0.35f, 0.52f}, {0.7f, 0.45f}, {0.7f, 0.45f}}};
  for (std::size_t k = 0; k < gazes.size(); ++k) {
    r.points[view::kGazeCriterion] = {gazes[k]};
    std::vector<cut::CutMesh> kept, expected;
    ASSERT_TRUE(in_session.extract({r, instances}, kept, nullptr, &session).ok());
    EXPECT_EQ(session.reused(), k > 0) << "gaze " << k;
    ASSERT_TRUE(fresh.extract({r, instances}, expected).ok());
    for (std::size_t i = 0; i < instances.size(); ++i)
      EXPECT_EQ(ids_of(kept[i]), ids_of(expected[i])) << "gaze " << k << ", instance " << i;
  }
  EXPECT_GT(session.memory_bytes(), r.grid.cell_count() * 2);
  r.camera.view = glm::lookAt(glm::vec3(1, 0, 6), glm::vec3(0), glm::vec3(0, 1, 0));
  std::vector<cut::CutMesh> moved, expected;
  ASSERT_TRUE(in_session.extract({r, instances}, moved, nullptr, &session).ok());
  EXPECT_FALSE(session.reused());
  ASSERT_TRUE(fresh.extract({r, instances}, expected).ok());
  for (std::size_t i = 0; i < instances.size(); ++i) EXPECT_EQ(ids_of(moved[i]), ids_of(expected[i]));
}

TEST(SceneExtract, ASessionsGazesWithABudgetFillItAsAFreshSearchDoes) {
  // A gaze starts the budget's search at the session's last threshold: its cuts still fit the
  // budget, fill it as a fresh search's do, and take fewer passes.
  const Model& m = sphere();
  const std::vector<view::SceneInstance> instances{
      instance(m, glm::translate(glm::mat4(1), glm::vec3(-1.2f, 0, 0))),
      instance(m, glm::translate(glm::mat4(1), glm::vec3(1.5f, 0, -4))),
  };
  view::ViewRequest r = pixel_request(0.25f);
  r.allowed.criteria[view::kGazeCriterion] = view::RegionLaw{view::FalloffLaw::kStep, 12.0f, 0.1f};
  r.points[view::kGazeCriterion] = {{0.3f, 0.5f}};
  view::SceneExtractor x, fresh;
  view::SceneStats unbounded;
  extract(fresh, r, instances, &unbounded);
  r.budget = unbounded.triangles / 3;
  view::SceneCache session;
  std::size_t session_passes = 0, fresh_passes = 0;
  for (int k = 0; k < 6; ++k) {
    r.points[view::kGazeCriterion] = {{0.3f + 0.03f * static_cast<float>(k), 0.5f}};
    std::vector<cut::CutMesh> cuts;
    auto stats = x.extract({r, instances}, cuts, nullptr, &session);
    ASSERT_TRUE(stats.ok());
    view::SceneStats alone;
    extract(fresh, r, instances, &alone);
    EXPECT_LE(stats->triangles, *r.budget) << "gaze " << k;
    EXPECT_GE(static_cast<double>(stats->triangles), 0.9 * static_cast<double>(*r.budget)) << "gaze " << k;
    if (k > 0) session_passes += stats->passes, fresh_passes += alone.passes;
  }
  EXPECT_LT(session_passes, fresh_passes);
}

TEST(SceneExtract, ABudgetBelowTheRootsGetsTheRoots) {
  const Model& m = sphere();
  view::ViewRequest r = pixel_request();
  r.budget = m.built->mt.root_triangle_count();  // two instances: twice that at least
  view::SceneExtractor x;
  view::SceneStats stats;
  const auto cuts = extract(x, r, {instance(m, glm::mat4(1)), instance(m, glm::mat4(1))}, &stats);
  EXPECT_FALSE(stats.within_budget);
  for (const cut::CutMesh& c : cuts) EXPECT_EQ(c.triangle_count(), m.built->mt.root_triangle_count());
}

}  // namespace
}  // namespace mtlod::core
