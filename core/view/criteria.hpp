// The vocabulary of the allowed-error functions (allowed_error.hpp) that requests choose from: the
// criteria that scale the allowed error with a distance on the image, how the error falls off with
// that distance, and the units of the bound. Kept apart from allowed_error.hpp so that protocol
// messages can name them without the refinement's headers.
//
// A criterion is one entry of kCriteria: what seeds its distance transform and how its multiplier
// combines with the others. The allowed-error field, the extractor's transforms, the protocol's
// reader and writer, PROTOCOL.md's table and the viewer's panel all iterate the criteria, so a new
// one is an enumerator here, its traits, and its wire name (protocol/messages.hpp, kCriterionWire).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace mtlod::core::view {

enum class FalloffLaw : std::uint8_t {
  kStep,        // the papers' two levels: factor inside the region, 1 outside
  kLinear,      // factor up to distance_px, rising linearly to 1 over falloff_px
  kSmoothstep,  // same ramp through smoothstep (C¹ at both ends)
  kFoveal,  // factor·(1 + eccentricity/foveal_e2_deg), capped at 1 when factor < 1: acuity falls linearly
            // with eccentricity
};
inline constexpr std::size_t kFalloffLawCount = 4;  // tables indexed by a law are sized by it

enum class ErrorUnits : std::uint8_t {
  kModel,         // `error` is a distance in model units
  kScreenPixels,  // `error` is in screen pixels, converted per vertex with its depth
};
inline constexpr std::size_t kErrorUnitsCount = 2;

enum class Criterion : std::uint8_t {
  kSilhouette,  // distance to the model's outline (JVRB 2006)
  kFocus,       // distance to the focus points (DGCI 2006): the gaze
  kNeglect,     // distance to regions of neglect, coarsened (factor ≥ 1)
  kScreenEdge,  // distance to the screen's edge, coarsened (factor ≥ 1): the periphery of the view
};

// What a criterion's distance transform measures the distance to.
enum class Seeds : std::uint8_t {
  kBackground,  // the empty cells of the occupancy grid (and depth jumps with internal silhouettes)
  kPoints,      // points the request names, in normalised viewport coordinates
  kBorder,      // the cells on the grid's border
};

// How a criterion's multiplier joins the others'.
enum class Combine : std::uint8_t {
  kStricter,  // the smallest of the kStricter criteria in use wins (1 when none is in use)
  kScales,    // multiplies the result (regions that coarsen)
};

struct CriterionTraits {
  Seeds seeds;
  Combine combine;
  bool foveal;  // takes the request's foveal law; false: the step law stands in for it
};

inline constexpr std::array<CriterionTraits, 4> kCriteria{{
    {Seeds::kBackground, Combine::kStricter, true},  // kSilhouette
    {Seeds::kPoints, Combine::kStricter, true},      // kFocus
    {Seeds::kPoints, Combine::kScales, false},       // kNeglect
    {Seeds::kBorder, Combine::kScales, false},       // kScreenEdge
}};
inline constexpr std::size_t kCriterionCount = kCriteria.size();

constexpr const CriterionTraits& traits(Criterion c) {
  return kCriteria[static_cast<std::size_t>(c)];
}

// Every criterion, in table order: what the layers iterate.
inline constexpr std::array<Criterion, kCriterionCount> kAllCriteria = [] {
  std::array<Criterion, kCriterionCount> all{};
  for (std::size_t i = 0; i < kCriterionCount; ++i) all[i] = static_cast<Criterion>(i);
  return all;
}();

// The criterion a gaze moves: a session's incremental path recomputes only what its transform
// changes.
inline constexpr Criterion kGazeCriterion = Criterion::kFocus;
static_assert(kCriteria[static_cast<std::size_t>(kGazeCriterion)].seeds == Seeds::kPoints);

// One value per criterion, indexed by the criterion.
template <class T>
struct PerCriterion {
  std::array<T, kCriterionCount> entries{};

  T& operator[](Criterion c) { return entries[static_cast<std::size_t>(c)]; }
  const T& operator[](Criterion c) const { return entries[static_cast<std::size_t>(c)]; }
  bool operator==(const PerCriterion&) const = default;
};

}  // namespace mtlod::core::view
