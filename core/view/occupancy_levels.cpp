// Precomputed coarse cuts for the occupancy stage (see occupancy_levels.hpp).
#include "core/view/occupancy_levels.hpp"

#include <algorithm>
#include <limits>
#include <span>
#include <unordered_map>

#include "core/cut/refine.hpp"

namespace mtlod::core::view {
namespace {

// Directed edges by first vertex (CSR): the second vertices of vertex a's edges are
// to[offset[a] .. offset[a + 1]).
struct Outgoing {
  std::vector<std::uint32_t> offset, to;

  explicit Outgoing(std::span<const std::uint32_t> triangles) {
    const std::uint32_t vertices =
        triangles.empty() ? 0 : *std::max_element(triangles.begin(), triangles.end()) + 1;
    offset.assign(std::size_t{vertices} + 1, 0);
    for (const std::uint32_t v : triangles) ++offset[v + 1];
    for (std::size_t v = 0; v < vertices; ++v) offset[v + 1] += offset[v];
    to.resize(triangles.size());
    std::vector<std::uint32_t> fill(offset.begin(), offset.end() - 1);
    for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
      for (int k = 0; k < 3; ++k) to[fill[triangles[t + k]]++] = triangles[t + (k + 1) % 3];
  }
  std::uint32_t vertex_count() const { return static_cast<std::uint32_t>(offset.size() - 1); }
  // How often (from, to) appears; from must be a vertex of the surface.
  std::uint32_t count(std::uint32_t from, std::uint32_t target) const {
    if (from >= vertex_count()) return 0;
    return static_cast<std::uint32_t>(
        std::count(to.begin() + offset[from], to.begin() + offset[from + 1], target));
  }
};

}  // namespace

bool is_closed_surface(std::span<const std::uint32_t> triangles) {
  const Outgoing edges(triangles);
  for (std::uint32_t a = 0; a < edges.vertex_count(); ++a) {
    for (std::uint32_t i = edges.offset[a]; i < edges.offset[a + 1]; ++i) {
      const std::uint32_t b = edges.to[i];
      if (edges.count(a, b) != edges.count(b, a)) return false;
    }
  }
  return true;
}

std::size_t cap_holes(std::vector<std::uint32_t>& triangles) {
  const std::size_t before = triangles.size();
  // Boundary edges by first vertex, each list walked from its end: (a, b) as often as it is walked
  // more often than (b, a). This is the boundary of the triangles as an integer chain, so at every
  // vertex as many boundary edges leave as arrive and they split into loops, also where a cut
  // joins sheets (an edge walked twice one way and once the other has one boundary edge).
  std::vector<std::uint32_t> boundary_offset, boundary_to, remaining;
  {
    const Outgoing edges(triangles);
    const std::uint32_t vertices = edges.vertex_count();
    boundary_offset.assign(std::size_t{vertices} + 1, 0);
    std::vector<std::uint32_t> seen;
    for (std::uint32_t a = 0; a < vertices; ++a) {
      boundary_offset[a + 1] = boundary_offset[a];
      seen.assign(edges.to.begin() + edges.offset[a], edges.to.begin() + edges.offset[a + 1]);
      std::sort(seen.begin(), seen.end());
      for (std::size_t i = 0; i < seen.size();) {
        const std::uint32_t b = seen[i];
        std::size_t j = i;
        while (j < seen.size() && seen[j] == b) ++j;
        const std::uint32_t forward = static_cast<std::uint32_t>(j - i), backward = edges.count(b, a);
        for (std::uint32_t k = backward; k < forward; ++k) boundary_to.push_back(b);
        boundary_offset[a + 1] += forward > backward ? forward - backward : 0;
        i = j;
      }
    }
    remaining.resize(vertices);
    for (std::uint32_t a = 0; a < vertices; ++a) remaining[a] = boundary_offset[a + 1] - boundary_offset[a];
  }
  auto next = [&](std::uint32_t from, std::uint32_t& to) {
    if (remaining[from] == 0) return false;
    to = boundary_to[boundary_offset[from] + --remaining[from]];
    return true;
  };
  // A loop l0 → l1 → … → l(m−1) → l0 gets (l0, l(i+1), l(i)) for i = 1 … m − 2: each holds one
  // loop edge reversed, and consecutive ones share (l0, l(i+1)) in opposite directions.
  auto fan = [&](std::span<const std::uint32_t> loop) {
    for (std::size_t i = 1; i + 1 < loop.size(); ++i)
      triangles.insert(triangles.end(), {loop[0], loop[i + 1], loop[i]});
  };
  constexpr std::size_t kNotOnPath = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> position(remaining.size(), kNotOnPath);  // of each vertex on the path
  std::vector<std::uint32_t> path;
  for (std::uint32_t start = 0; start < remaining.size(); ++start) {
    std::uint32_t to = 0;
    while (next(start, to)) {
      path.assign(1, start);
      position[start] = 0;
      while (true) {
        if (position[to] != kNotOnPath) {
          // Back at a vertex of the path: the part after it is a loop.
          const std::size_t k = position[to];
          fan(std::span<const std::uint32_t>(path).subspan(k));
          for (std::size_t i = k + 1; i < path.size(); ++i) position[path[i]] = kNotOnPath;
          path.resize(k + 1);
        } else {
          position[to] = path.size();
          path.push_back(to);
        }
        if (!next(path.back(), to)) break;  // (a surface's boundary always closes: only at the start)
      }
      for (const std::uint32_t v : path) position[v] = kNotOnPath;
    }
  }
  return (triangles.size() - before) / 3;
}

Result<std::unique_ptr<OccupancyLevels>> OccupancyLevels::make(const model::Mt& mt) {
  std::unique_ptr<OccupancyLevels> made(new OccupancyLevels);
  std::vector<OccupancyLevel>& levels = made->levels_;
  cut::Refiner refiner(mt);
  cut::CutMesh cut;
  // Uniform allowed error 0 ranks triangles by error alone: each budget gives the cut with the
  // smallest maximum error at that size.
  const cut::AllowedError everywhere_exact = cut::AllowedError::everywhere(0.0f);
  for (std::size_t budget = 512; budget <= (std::size_t{1} << 18); budget *= 2) {
    MTLOD_RETURN_IF_ERROR(refiner.refine(cut::Refinement::from_root(everywhere_exact).within(budget), cut));
    if (!levels.empty() && cut.triangle_count() == levels.back().triangle_count()) break;  // nothing finer
    OccupancyLevel level;
    std::unordered_map<std::uint32_t, std::uint32_t> local;
    level.triangles.reserve(cut.triangles.size());
    for (const std::uint32_t v : cut.triangles) {
      const auto [it, added] = local.try_emplace(v, static_cast<std::uint32_t>(level.model_ids.size()));
      if (added) {
        level.model_ids.push_back(v);
        level.positions.insert(level.positions.end(), &mt.positions[3 * std::size_t{v}],
                               &mt.positions[3 * std::size_t{v} + 3]);
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
    levels.push_back(std::move(level));
  }
  return made;
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

}  // namespace mtlod::core::view
