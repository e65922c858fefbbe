// The vocabulary of the allowed-error functions (allowed_error.hpp) that requests choose from: how
// the allowed error falls off with a label's distance, and the units of the bound. Kept apart from
// allowed_error.hpp so that protocol messages can name them without the refinement's headers.
#pragma once

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

}  // namespace mtlod::core::view
