// Precomputed coarse cuts for the occupancy stage (see occupancy_levels.hpp).
#include "core/occupancy_levels.hpp"

#include <algorithm>
#include <functional>
#include <span>
#include <unordered_map>

#include "core/refine.hpp"

namespace mtlod::core {
namespace {

std::uint64_t edge_key(std::uint32_t from, std::uint32_t to) { return std::uint64_t{from} << 32 | to; }

// Directed edges of `triangles` with how often each appears.
std::unordered_map<std::uint64_t, std::uint32_t> directed_edges(std::span<const std::uint32_t> triangles) {
  std::unordered_map<std::uint64_t, std::uint32_t> edges;
  edges.reserve(triangles.size());
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
    for (int k = 0; k < 3; ++k) ++edges[edge_key(triangles[t + k], triangles[t + (k + 1) % 3])];
  return edges;
}

}  // namespace

bool is_closed_surface(std::span<const std::uint32_t> triangles) {
  const auto edges = directed_edges(triangles);
  for (const auto& [key, count] : edges) {
    const auto reverse = edges.find(key << 32 | key >> 32);
    if (reverse == edges.end() || reverse->second != count) return false;
  }
  return true;
}

std::size_t cap_holes(std::vector<std::uint32_t>& triangles) {
  const std::size_t before = triangles.size();
  // Boundary edges, by their first vertex.
  std::unordered_map<std::uint32_t, std::vector<std::uint32_t>> boundary;
  std::vector<std::uint32_t> starts;
  {
    const auto edges = directed_edges(triangles);
    for (const auto& [key, count] : edges) {
      if (edges.contains(key << 32 | key >> 32)) continue;
      const auto from = static_cast<std::uint32_t>(key >> 32);
      boundary[from].push_back(static_cast<std::uint32_t>(key));
      starts.push_back(from);
    }
  }
  std::sort(starts.begin(), starts.end());  // the same caps whatever the hash order
  for (auto& [from, targets] : boundary) std::sort(targets.begin(), targets.end(), std::greater<>());
  // A loop l0 → l1 → … → l(m−1) → l0 gets (l0, l(i+1), l(i)) for i = 1 … m − 2: each holds one
  // loop edge reversed, and consecutive ones share (l0, l(i+1)) in opposite directions.
  auto fan = [&](std::span<const std::uint32_t> loop) {
    for (std::size_t i = 1; i + 1 < loop.size(); ++i) triangles.insert(triangles.end(), {loop[0], loop[i + 1], loop[i]});
  };
  auto next = [&](std::uint32_t from, std::uint32_t& to) {
    auto it = boundary.find(from);
    if (it == boundary.end() || it->second.empty()) return false;
    to = it->second.back();
    it->second.pop_back();
    return true;
  };
  std::vector<std::uint32_t> path;
  std::unordered_map<std::uint32_t, std::size_t> position;  // of each vertex on the path
  for (const std::uint32_t start : starts) {
    std::uint32_t to = 0;
    if (!next(start, to)) continue;  // its edges were walked from another start
    path.assign(1, start);
    position.clear();
    position[start] = 0;
    while (true) {
      if (const auto seen = position.find(to); seen != position.end()) {
        // Back at a vertex of the path: the part after it is a loop.
        const std::size_t k = seen->second;
        fan(std::span<const std::uint32_t>(path).subspan(k));
        for (std::size_t i = k + 1; i < path.size(); ++i) position.erase(path[i]);
        path.resize(k + 1);
      } else {
        position[to] = path.size();
        path.push_back(to);
      }
      if (!next(path.back(), to)) break;  // (a surface's boundary always closes: only at the start)
    }
  }
  return (triangles.size() - before) / 3;
}

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
    // Closed, a request rasterises about half of it; if capping does not close it (edges shared
    // by more than two triangles), it stays as it was and is rasterised whole.
    const std::size_t cut_size = level.triangles.size();
    level.cap_triangles = cap_holes(level.triangles);
    level.closed = is_closed_surface(level.triangles);
    if (!level.closed) {
      level.triangles.resize(cut_size);
      level.cap_triangles = 0;
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
