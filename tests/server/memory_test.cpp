// The engine's memory estimate, which the server's ceiling (--max-memory) reserves before an
// extraction runs, must bound what the extraction really holds afterwards: the session's bytes
// and the worker's scratch, as the engine itself measures them.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "core/build/mt_builder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mt_file.hpp"
#include "protocol/camera.hpp"
#include "server/engine.hpp"
#include "server/model_registry.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::server {
namespace {

// A generated shell of about `triangles` triangles written as NAME.mt and served from a registry,
// with a request for it framed from the front.
struct ShellModel {
  ModelRegistry models;
  protocol::Extract front;
};
void serve_shell(const std::string& name, std::uint32_t triangles, ShellModel& out) {
  const auto dir = test::scratch_dir("memory-estimate-" + name);
  core::eval::GenerateOptions shape;
  shape.shape = core::eval::Shape::kShell;
  shape.target_triangles = triangles;
  auto mt = core::build::build_mt(core::eval::generate_mesh(shape));
  ASSERT_TRUE(mt.ok()) << mt.error().message;
  ASSERT_TRUE(core::io::write_mt_file(dir / (name + ".mt"), *mt).ok());
  ASSERT_TRUE(out.models.add_file(dir / (name + ".mt")).ok());
  const Model& model = *out.models.find(name);
  out.front.model = name;
  protocol::look_at_camera(
      protocol::frame_bounds({model.bounds_min[0], model.bounds_min[1], model.bounds_min[2]},
                             {model.bounds_max[0], model.bounds_max[1], model.bounds_max[2]}),
      1.0, out.front.view, out.front.projection);
}

TEST(MemoryEstimate, BoundsSessionAndScratchOfExtremeRequests) {
  ShellModel shell;
  ASSERT_NO_FATAL_FAILURE(serve_shell("shell", 20000, shell));
  Engine engine(shell.models);
  const protocol::Extract& base = shell.front;
  std::vector<protocol::Extract> requests;
  for (const std::uint32_t side : {16u, 256u, 1024u, 2048u}) {
    for (const bool delta : {false, true}) {
      protocol::Extract e = base;
      e.grid = {side, side};
      e.error = 0;  // every triangle: the largest cut
      e.error_unit = core::view::ErrorUnits::kModel;
      e.delta = delta;
      requests.push_back(e);
      e.error = 1;
      e.error_unit = core::view::ErrorUnits::kScreenPixels;
      e.criteria.regions[core::view::Criterion::kSilhouette] = protocol::Region{2, 0, {}};
      e.criteria.regions[core::view::Criterion::kFocus] = protocol::Region{20, 0.1, {{0.5, 0.5}}};
      requests.push_back(e);
    }
  }
  ExtractionState session;  // one session through all of them, as a connection would keep it
  for (const auto& request : requests) {
    auto outcome = engine.extract(request, false, session);
    ASSERT_TRUE(outcome) << outcome.error().message;
    const auto& reply = outcome->reply;
    const std::uint64_t estimate = engine.estimate_bytes(request);
    EXPECT_LE(reply.session_bytes + reply.scratch_bytes, estimate)
        << "grid " << request.grid[0] << " error " << request.error << " delta " << request.delta
        << ": session " << reply.session_bytes << " scratch " << reply.scratch_bytes;
    EXPECT_EQ(reply.session_bytes, session.memory_bytes());
    // Not wildly above either: the ceiling would refuse work it has room for.
    EXPECT_LT(estimate, 8 * (reply.session_bytes + reply.scratch_bytes) + (std::uint64_t{4} << 20));
  }
  // A worker keeps modest scratch for its next request and frees a huge grid's.
  Engine::settle_worker_scratch();
  protocol::Extract huge = requests.back();  // silhouette and focus transforms
  huge.grid = {4096, 4096};
  auto outcome = engine.extract(huge, false, session);
  ASSERT_TRUE(outcome) << outcome.error().message;
  const std::uint64_t used = outcome->reply.scratch_bytes;
  ASSERT_GT(used, Engine::kRetainedScratchBytes) << "the request does not exercise the release";
  EXPECT_LT(Engine::settle_worker_scratch(), 0)
      << "the 4096² grid's " << used << " bytes of scratch were kept";
}

// A budgeted session on a model many times its cut: the estimate follows the budget, not the
// model, and still bounds what a new view and the gazes that follow really hold.
TEST(MemoryEstimate, FollowsTheBudgetOnAModelManyTimesTheCut) {
  ShellModel big;
  ASSERT_NO_FATAL_FAILURE(serve_shell("big", 200000, big));
  Engine engine(big.models);
  protocol::Extract e = big.front;
  e.grid = {256, 256};
  e.error = 0.25;
  e.error_unit = core::view::ErrorUnits::kScreenPixels;
  e.criteria.regions[core::view::Criterion::kSilhouette] = protocol::Region{2, 0.25, {}};
  e.budget = 4000;
  e.delta = true;
  ExtractionState session;
  std::uint64_t most = 0;
  for (int gaze = 0; gaze < 20; ++gaze) {
    // Sweeps of the focus across the screen: the cut moves to new vertices at every gaze.
    e.criteria.regions[core::view::Criterion::kFocus] =
        protocol::Region{20, 0.1, {{0.1 + 0.04 * gaze, 0.3 + 0.02 * gaze}}};
    auto outcome = engine.extract(e, gaze > 0, session);
    ASSERT_TRUE(outcome) << outcome.error().message;
    const std::uint64_t held = outcome->reply.session_bytes + outcome->reply.scratch_bytes;
    EXPECT_LE(held, engine.estimate_bytes(e)) << "gaze " << gaze;
    most = std::max(most, held);
  }
  // A fraction of the same request's estimate without the budget (a cut of the whole model).
  protocol::Extract unbounded = e;
  unbounded.budget.reset();
  EXPECT_LT(4 * engine.estimate_bytes(e), engine.estimate_bytes(unbounded));
  EXPECT_LT(engine.estimate_bytes(e), 8 * most + (std::uint64_t{4} << 20)) << "held at most " << most;
  // Error-bound gazes: the session's estimate follows its last cut (the server estimates before
  // each run, with the session it will run in).
  for (int gaze = 0; gaze < 10; ++gaze) {
    unbounded.criteria.regions[core::view::Criterion::kFocus] =
        protocol::Region{20, 0.1, {{0.8 - 0.05 * gaze, 0.5}}};
    const std::uint64_t estimate = engine.estimate_bytes(unbounded, &session);
    auto outcome = engine.extract(unbounded, gaze > 0, session);
    ASSERT_TRUE(outcome) << outcome.error().message;
    EXPECT_LE(outcome->reply.session_bytes + outcome->reply.scratch_bytes, estimate) << "gaze " << gaze;
    if (gaze > 0) EXPECT_LT(estimate, engine.estimate_bytes(unbounded));
  }
}

}  // namespace
}  // namespace mtlod::server
