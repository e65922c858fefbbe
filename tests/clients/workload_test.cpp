// mtlod-load's request sequence: an extract before any gaze, the mix's kinds, scripted cameras
// cycled from the connection's own line, and the same requests for the same seed.
#include "clients/load/workload.hpp"

#include <gtest/gtest.h>

#include <string>
#include <variant>
#include <vector>

#include "protocol/parse.hpp"

namespace mtlod::clients {
namespace {

ModelView unit_box() {
  ModelView model;
  model.name = "box";
  model.bounds_min = {-1, -1, -1};
  model.bounds_max = {1, 1, 1};
  model.base.model = "box";
  return model;
}

TEST(RequestSequence, OpensWithAnExtractThenFollowsTheMix) {
  // gaze=1 alone: every request after the first is a gaze, which needs the first's view.
  const ModelView model = unit_box();
  RequestSettings settings;
  settings.mix = Mix{0, 1};
  RequestSequence requests(model, settings, 7, 0);
  EXPECT_TRUE(std::holds_alternative<protocol::Extract>(requests.next()));
  for (int i = 0; i < 50; ++i) ASSERT_TRUE(std::holds_alternative<protocol::Gaze>(requests.next())) << i;
}

TEST(RequestSequence, ExtractsOnlyWhenTheMixHasNoGazes) {
  const ModelView model = unit_box();
  RequestSettings settings;  // extract=1
  RequestSequence requests(model, settings, 7, 0);
  for (int i = 0; i < 50; ++i) {
    const protocol::Request r = requests.next();
    const auto* e = std::get_if<protocol::Extract>(&r);
    ASSERT_NE(e, nullptr) << i;
    // --random-focus: one focus point inside [0.1, 0.9]².
    ASSERT_TRUE(e->criteria.regions[core::view::Criterion::kFocus]);
    ASSERT_EQ(e->criteria.regions[core::view::Criterion::kFocus]->points.size(), 1u);
    EXPECT_GE(e->criteria.regions[core::view::Criterion::kFocus]->points.front().x, 0.1);
    EXPECT_LT(e->criteria.regions[core::view::Criterion::kFocus]->points.front().x, 0.9);
    EXPECT_GE(e->criteria.regions[core::view::Criterion::kFocus]->points.front().y, 0.1);
    EXPECT_LT(e->criteria.regions[core::view::Criterion::kFocus]->points.front().y, 0.9);
  }
}

TEST(RequestSequence, TheSameSeedGivesTheSameRequests) {
  const ModelView model = unit_box();
  RequestSettings settings;
  settings.mix = Mix{1, 3};
  RequestSequence a(model, settings, 42, 0), b(model, settings, 42, 0), c(model, settings, 43, 0);
  bool differs = false;
  for (std::uint64_t id = 1; id <= 100; ++id) {
    const std::string from_a = protocol::to_json(a.next(), id);
    ASSERT_EQ(from_a, protocol::to_json(b.next(), id)) << id;
    differs |= from_a != protocol::to_json(c.next(), id);
  }
  EXPECT_TRUE(differs) << "another seed, other cameras and foci";
}

TEST(RequestSequence, ScriptedCamerasCycleFromTheConnectionsFirstLine) {
  // Connection 1 of a two-line script starts on line 1 and then wraps to line 0; the script's foci
  // replace random ones.
  const ModelView model = unit_box();
  RequestSettings settings;
  settings.random_cameras = false;
  settings.script = {ScriptedCamera{{0, 0, 3}, {0, 0, 0}, true, {0.25, 0.75}},
                     ScriptedCamera{{3, 0, 0}, {0, 0, 0}, true, {0.5, 0.125}}};
  RequestSequence requests(model, settings, 1, 1);
  const std::vector<std::size_t> lines{1, 0, 1, 0};
  for (std::size_t line : lines) {
    const protocol::Request r = requests.next();
    const auto& e = std::get<protocol::Extract>(r);
    ASSERT_TRUE(e.criteria.regions[core::view::Criterion::kFocus]);
    ASSERT_EQ(e.criteria.regions[core::view::Criterion::kFocus]->points.size(), 1u);
    EXPECT_EQ(e.criteria.regions[core::view::Criterion::kFocus]->points.front().x,
              settings.script[line].focus[0])
        << line;
    EXPECT_EQ(e.criteria.regions[core::view::Criterion::kFocus]->points.front().y,
              settings.script[line].focus[1])
        << line;
  }
}

}  // namespace
}  // namespace mtlod::clients
