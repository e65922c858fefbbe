// Precomputed coarse cuts for the occupancy stage (see occupancy_levels.hpp).
#include "core/occupancy_levels.hpp"

#include <unordered_map>

#include "core/refine.hpp"

namespace mtlod::core {

OccupancyLevels::OccupancyLevels(const Mt& mt) {
  Refiner refiner(mt);
  CutMesh cut;
  // Uniform allowed error 0 ranks triangles by error alone: each budget gives the cut with the
  // smallest maximum error at that size.
  const AllowedError everywhere_exact = AllowedError::everywhere(0.0f);
  for (std::size_t budget = 2048; budget <= (std::size_t{1} << 18); budget *= 2) {
    refiner.refine_budget(everywhere_exact, budget, cut);
    if (!levels_.empty() && cut.triangle_count() == levels_.back().triangle_count()) break;  // nothing finer
    OccupancyLevel level;
    std::unordered_map<std::uint32_t, std::uint32_t> local;
    level.triangles.reserve(cut.triangles.size());
    for (const std::uint32_t v : cut.triangles) {
      const auto [it, added] = local.try_emplace(v, static_cast<std::uint32_t>(level.model_ids.size()));
      if (added) {
        level.model_ids.push_back(v);
        level.positions.insert(level.positions.end(), &mt.positions[3 * std::size_t{v}], &mt.positions[3 * std::size_t{v} + 3]);
      }
      level.triangles.push_back(it->second);
    }
    levels_.push_back(std::move(level));
  }
}

const OccupancyLevel& OccupancyLevels::for_covered_cells(double covered_cells) const {
  for (const OccupancyLevel& level : levels_) {
    if (static_cast<double>(level.triangle_count()) >= 0.25 * covered_cells) return level;
  }
  return levels_.back();
}

std::size_t OccupancyLevels::memory_bytes() const {
  std::size_t bytes = 0;
  for (const OccupancyLevel& level : levels_) {
    bytes += (level.triangles.size() + level.model_ids.size()) * sizeof(std::uint32_t) +
             level.positions.size() * sizeof(float);
  }
  return bytes;
}

}  // namespace mtlod::core
