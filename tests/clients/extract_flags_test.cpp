// The viewing clients' default criteria (clients::apply_default_criteria): the image-space study's
// winner (foveal bound, hidden surfaces coarsened) when the user names no criterion, and nothing
// changed when they do. Checked on the request
// make_extract builds, which the server's own parser has accepted.
#include "clients/common/extract_flags.hpp"

#include <gtest/gtest.h>

namespace mtlod::clients {
namespace {

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
  EXPECT_FALSE(e.criteria.silhouette);
  ASSERT_EQ(e.criteria.focus.size(), 1u);
  EXPECT_EQ(e.criteria.focus[0].x, 0.5);
  EXPECT_EQ(e.criteria.focus[0].y, 0.5);
  EXPECT_EQ(e.criteria.focus[0].factor, 1.0);  // the bound itself holds at the focus
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
  silhouette.silhouette = "2,0.25";
  apply_default_criteria(silhouette);
  Extract e = request_for(silhouette);
  EXPECT_EQ(e.criteria.falloff, core::view::FalloffLaw::kStep);
  EXPECT_TRUE(e.criteria.focus.empty());
  EXPECT_EQ(e.criteria.hidden_factor, 1.0);
  ASSERT_TRUE(e.criteria.silhouette);
  EXPECT_EQ(e.criteria.silhouette->factor, 0.25);

  ExtractFlags falloff;
  falloff.falloff = "linear";
  apply_default_criteria(falloff);
  e = request_for(falloff);
  EXPECT_EQ(e.criteria.falloff, core::view::FalloffLaw::kLinear);
  EXPECT_TRUE(e.criteria.focus.empty());

  ExtractFlags focus;
  focus.focus.push_back("0.2,0.3,40,0.5");
  apply_default_criteria(focus);
  e = request_for(focus);
  EXPECT_EQ(e.criteria.falloff, core::view::FalloffLaw::kStep);
  ASSERT_EQ(e.criteria.focus.size(), 1u);
  EXPECT_EQ(e.criteria.focus[0].factor, 0.5);
}

TEST(DefaultCriteria, WithoutTheDefaultNoFalloffMeansStep) {
  ExtractFlags flags;
  flags.error = 0.01;
  EXPECT_EQ(request_for(flags).criteria.falloff, core::view::FalloffLaw::kStep);
}

}  // namespace
}  // namespace mtlod::clients
