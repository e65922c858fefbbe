// The viewing clients' default criteria (clients::apply_default_criteria): the image-space study's
// winner (foveal bound, hidden surfaces coarsened) when the user names no criterion, and nothing
// changed when they do. Checked on the request
// make_extract builds, which the server's own parser has accepted.
#include "clients/common/extract_flags.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "fmt/format.h"

namespace mtlod::clients {
namespace {

using core::view::Criterion;
using protocol::Extract;

Extract request_for(const ExtractFlags& flags) {
  auto e = make_extract(flags, "box", {-1, -1, -1}, {1, 1, 1});
  EXPECT_TRUE(e) << (e ? "" : e.error().message);
  return e ? *e : Extract{};
}

TEST(DefaultCriteria, FovealBoundAtTheFocusWhenNoCriterionIsGiven) {
  ExtractFlags flags;
  apply_default_criteria(flags);
  const Extract e = request_for(flags);
  EXPECT_EQ(e.error_unit, core::view::ErrorUnits::kScreenPixels);
  EXPECT_EQ(e.error, 1.0);
  EXPECT_EQ(e.criteria.falloff, core::view::FalloffLaw::kFoveal);
  EXPECT_FALSE(e.criteria.regions[Criterion::kSilhouette]);
  ASSERT_TRUE(e.criteria.regions[Criterion::kFocus]);
  ASSERT_EQ(e.criteria.regions[Criterion::kFocus]->points.size(), 1u);
  EXPECT_EQ(e.criteria.regions[Criterion::kFocus]->points[0].x, 0.5);
  EXPECT_EQ(e.criteria.regions[Criterion::kFocus]->points[0].y, 0.5);
  EXPECT_EQ(e.criteria.regions[Criterion::kFocus]->factor, 1.0);  // the bound itself holds at the focus
  EXPECT_EQ(e.criteria.hidden_factor, kDefaultHiddenFactor);
}

TEST(DefaultCriteria, AGivenHiddenFactorIsKept) {
  ExtractFlags flags;
  flags.hidden_factor = 1;
  apply_default_criteria(flags);
  EXPECT_EQ(request_for(flags).criteria.hidden_factor, 1.0);
}

TEST(DefaultCriteria, AGivenBoundIsKept) {
  ExtractFlags flags;
  flags.error_px = 0.25;
  apply_default_criteria(flags);
  const Extract e = request_for(flags);
  EXPECT_EQ(e.error, 0.25);
  EXPECT_EQ(e.criteria.falloff, core::view::FalloffLaw::kFoveal);
}

TEST(DefaultCriteria, AnyGivenCriterionTurnsTheDefaultOff) {
  ExtractFlags silhouette;
  silhouette.criteria[Criterion::kSilhouette] = {"2,0.25"};
  apply_default_criteria(silhouette);
  Extract e = request_for(silhouette);
  EXPECT_EQ(e.criteria.falloff, core::view::FalloffLaw::kStep);
  EXPECT_FALSE(e.criteria.regions[Criterion::kFocus]);
  EXPECT_EQ(e.criteria.hidden_factor, 1.0);
  ASSERT_TRUE(e.criteria.regions[Criterion::kSilhouette]);
  EXPECT_EQ(e.criteria.regions[Criterion::kSilhouette]->factor, 0.25);

  ExtractFlags falloff;
  falloff.falloff = "linear";
  apply_default_criteria(falloff);
  e = request_for(falloff);
  EXPECT_EQ(e.criteria.falloff, core::view::FalloffLaw::kLinear);
  EXPECT_FALSE(e.criteria.regions[Criterion::kFocus]);

  ExtractFlags focus;
  focus.criteria[Criterion::kFocus].push_back("0.2,0.3,40,0.5");
  apply_default_criteria(focus);
  e = request_for(focus);
  EXPECT_EQ(e.criteria.falloff, core::view::FalloffLaw::kStep);
  ASSERT_TRUE(e.criteria.regions[Criterion::kFocus]);
  ASSERT_EQ(e.criteria.regions[Criterion::kFocus]->points.size(), 1u);
  EXPECT_EQ(e.criteria.regions[Criterion::kFocus]->factor, 0.5);
}

TEST(DefaultCriteria, ACriterionThatCoarsensKeepsTheDefault) {
  ExtractFlags flags;
  flags.criteria[Criterion::kNeglect].push_back("0.9,0.9,30,4");
  apply_default_criteria(flags);
  const Extract e = request_for(flags);
  EXPECT_EQ(e.criteria.falloff, core::view::FalloffLaw::kFoveal);
  ASSERT_TRUE(e.criteria.regions[Criterion::kFocus]);
  ASSERT_TRUE(e.criteria.regions[Criterion::kNeglect]);
  EXPECT_EQ(e.criteria.regions[Criterion::kNeglect]->factor, 4);
}

// Every criterion of the protocol's table has its flag, read into the request the server parses.
TEST(CriterionFlags, EveryCriterionHasAFlag) {
  for (const Criterion c : core::view::kAllCriteria) {
    const protocol::CriterionWire& w = protocol::wire(c);
    const bool points = core::view::traits(c).seeds == core::view::Seeds::kPoints;
    const double factor = (w.factor_min + w.factor_max) / 2;
    CLI::App app;
    ExtractFlags flags;
    add_extract_flags(app, flags);
    std::vector<std::string> args{
        "--error", "0.01", criterion_flag(c),
        points ? fmt::format("0.25,0.75,12,{}", factor) : fmt::format("12,{}", factor)};
    if (points) args.insert(args.end(), {criterion_flag(c), "0.5,0.5,1,1"});
    std::reverse(args.begin(), args.end());  // CLI11 takes the arguments last first
    ASSERT_NO_THROW(app.parse(args)) << criterion_flag(c);
    const Extract e = request_for(flags);
    const std::optional<protocol::Region>& region = e.criteria.regions[c];
    ASSERT_TRUE(region) << criterion_flag(c);
    EXPECT_EQ(region->distance, 12) << criterion_flag(c);
    EXPECT_EQ(region->factor, factor) << criterion_flag(c);  // the first point's, shared
    if (points) {
      EXPECT_EQ(region->points, (std::vector<protocol::Point>{{0.25, 0.75}, {0.5, 0.5}}))
          << criterion_flag(c);
    }
  }
}

TEST(DefaultCriteria, WithoutTheDefaultNoFalloffMeansStep) {
  ExtractFlags flags;
  flags.error = 0.01;
  EXPECT_EQ(request_for(flags).criteria.falloff, core::view::FalloffLaw::kStep);
}

}  // namespace
}  // namespace mtlod::clients
