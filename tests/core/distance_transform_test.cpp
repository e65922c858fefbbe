// Distance transforms (core/ARCHITECTURE.md §1.3; papers/000 Alg. 1): every chamfer against a
// Dijkstra shortest path over the same mask moves, the exact Euclidean transform against brute force,
// and small cases whose answer is worked out by hand.
#include "core/view/distance_transform.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <queue>
#include <random>
#include <vector>

namespace mtlod::core {
namespace {

// Reference: Dijkstra from all zero cells over the full (forward and backward) mask, moves staying
// inside the grid. Returns kChamferUnreached where no seed exists.
template <std::size_t N>
std::vector<std::uint16_t> dijkstra(const std::vector<std::uint8_t>& image, view::GridSize grid,
                                    const std::array<view::ChamferStep, N>& forward) {
  const std::uint32_t inf = 0xFFFFFFFFu;
  std::vector<std::uint32_t> dist(grid.cell_count(), inf);
  using Entry = std::pair<std::uint32_t, std::uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
  for (std::uint32_t c = 0; c < image.size(); ++c) {
    if (image[c] == 0) {
      dist[c] = 0;
      queue.push({0, c});
    }
  }
  while (!queue.empty()) {
    const auto [d, c] = queue.top();
    queue.pop();
    if (d != dist[c]) continue;
    const int x = static_cast<int>(c % grid.width), y = static_cast<int>(c / grid.width);
    for (const view::ChamferStep& s : forward) {
      for (const int sign : {1, -1}) {
        const int nx = x + sign * s.dx, ny = y + sign * s.dy;
        if (nx < 0 || ny < 0 || nx >= static_cast<int>(grid.width) || ny >= static_cast<int>(grid.height))
          continue;
        const std::uint32_t n = grid.cell(static_cast<std::uint32_t>(nx), static_cast<std::uint32_t>(ny));
        if (d + s.weight < dist[n]) {
          dist[n] = d + s.weight;
          queue.push({dist[n], n});
        }
      }
    }
  }
  std::vector<std::uint16_t> out(dist.size());
  for (std::size_t c = 0; c < dist.size(); ++c) {
    out[c] = dist[c] == inf ? view::kChamferUnreached : static_cast<std::uint16_t>(dist[c]);
  }
  return out;
}

// Random object/background images; background_percent of the cells are seeds. Blobs would give
// longer distances, so every third image is a few background dots in a full object.
std::vector<std::uint8_t> random_image(view::GridSize grid, std::mt19937& rng, int background_percent) {
  std::uniform_int_distribution<int> percent(0, 99);
  std::vector<std::uint8_t> image(grid.cell_count());
  for (auto& cell : image) cell = percent(rng) < background_percent ? 0 : 1;
  return image;
}

// The shapes the issue asks for (1×N, N×1) and widths around the 8-cell register (tails of 1..7).
std::vector<view::GridSize> test_sizes() {
  std::vector<view::GridSize> sizes = {{1, 1}, {1, 37},  {37, 1},  {2, 2},
                                       {3, 5}, {64, 64}, {100, 3}, {3, 100}};
  for (std::uint32_t w = 4; w <= 19; ++w) sizes.push_back({w, 11});
  sizes.push_back({67, 45});
  sizes.push_back({129, 70});
  return sizes;
}

using ChamferFn = void (*)(std::span<const std::uint8_t>, view::GridSize, std::span<std::uint16_t>);

template <std::size_t N>
void expect_matches_dijkstra(ChamferFn transform, const std::array<view::ChamferStep, N>& mask) {
  std::mt19937 rng(20061123);
  for (const view::GridSize grid : test_sizes()) {
    for (const int background_percent : {0, 1, 5, 30, 100}) {
      const auto image = random_image(grid, rng, background_percent);
      std::vector<std::uint16_t> out(grid.cell_count(), 0xABCD);
      transform(image, grid, out);
      const auto expected = dijkstra(image, grid, mask);
      ASSERT_EQ(out, expected) << grid.width << "x" << grid.height << " background " << background_percent
                               << "%";
    }
  }
}

TEST(Chamfer5711, MatchesDijkstraOnRandomGrids) {
  expect_matches_dijkstra(view::chamfer_5_7_11, view::kChamfer5711Forward);
}
TEST(Chamfer34, MatchesDijkstraOnRandomGrids) {
  expect_matches_dijkstra(view::chamfer_3_4, view::kChamfer34Forward);
}
TEST(CityBlock, MatchesDijkstraOnRandomGrids) {
  expect_matches_dijkstra(view::city_block, view::kCityBlockForward);
}
TEST(Chessboard, MatchesDijkstraOnRandomGrids) {
  expect_matches_dijkstra(view::chessboard, view::kChessboardForward);
}

// The cell-by-cell scalar passes (the non-SSE2 build) against the same reference.
void chamfer_scalar(view::DistanceMetric metric, std::span<const std::uint8_t> image, view::GridSize grid,
                    std::span<std::uint16_t> out) {
  view::DistanceTransformer transformer;
  transformer.set_scalar(true);
  transformer.chamfer(metric, image, grid, out);
}
void chamfer_5_7_11_scalar(std::span<const std::uint8_t> image, view::GridSize grid,
                           std::span<std::uint16_t> out) {
  chamfer_scalar(view::DistanceMetric::kChamfer5711, image, grid, out);
}
void chessboard_scalar(std::span<const std::uint8_t> image, view::GridSize grid,
                       std::span<std::uint16_t> out) {
  chamfer_scalar(view::DistanceMetric::kChessboard, image, grid, out);
}
TEST(Chamfer5711, ScalarPassesMatchDijkstraOnRandomGrids) {
  expect_matches_dijkstra(chamfer_5_7_11_scalar, view::kChamfer5711Forward);
}
TEST(Chessboard, ScalarPassesMatchDijkstraOnRandomGrids) {
  expect_matches_dijkstra(chessboard_scalar, view::kChessboardForward);
}

TEST(Chamfer5711, SingleSeedGivesMaskDistancesByHand) {
  // One seed at (2, 2) of a 5×5 grid. Two cells away: 10 along an axis, 14 diagonally, 11 for the
  // knight move; the corner (0, 0) is two diagonal steps (14), (0, 1) a knight move (11).
  const view::GridSize grid{5, 5};
  std::vector<std::uint8_t> image(grid.cell_count(), 1);
  image[grid.cell(2, 2)] = 0;
  std::vector<std::uint16_t> out(grid.cell_count());
  view::chamfer_5_7_11(image, grid, out);
  const std::vector<std::uint16_t> expected = {
      14, 11, 10, 11, 14,  //
      11, 7,  5,  7,  11,  //
      10, 5,  0,  5,  10,  //
      11, 7,  5,  7,  11,  //
      14, 11, 10, 11, 14,
  };
  EXPECT_EQ(out, expected);
}

TEST(Chamfer5711, ContourCellOfObjectHasLabelFive) {
  // A 3×3 object square in a 7×7 background: its ring of 8 cells touches the background by an edge
  // (label 5), and the centre is two edge steps from the background (10).
  const view::GridSize grid{7, 7};
  std::vector<std::uint8_t> image(grid.cell_count(), 0);
  for (std::uint32_t j = 2; j <= 4; ++j)
    for (std::uint32_t i = 2; i <= 4; ++i) image[grid.cell(i, j)] = 1;
  std::vector<std::uint16_t> out(grid.cell_count());
  view::chamfer_5_7_11(image, grid, out);
  for (std::uint32_t j = 0; j < 7; ++j) {
    for (std::uint32_t i = 0; i < 7; ++i) {
      const bool object = i >= 2 && i <= 4 && j >= 2 && j <= 4;
      const bool centre = i == 3 && j == 3;
      EXPECT_EQ(out[grid.cell(i, j)], centre ? 10 : object ? 5 : 0) << i << "," << j;
    }
  }
}

TEST(Chamfer5711, AllObjectImageIsUnreachedAndAllBackgroundIsZero) {
  const view::GridSize grid{13, 9};
  std::vector<std::uint16_t> out(grid.cell_count());
  view::chamfer_5_7_11(std::vector<std::uint8_t>(grid.cell_count(), 1), grid, out);
  EXPECT_TRUE(
      std::all_of(out.begin(), out.end(), [](std::uint16_t v) { return v == view::kChamferUnreached; }));
  view::chamfer_5_7_11(std::vector<std::uint8_t>(grid.cell_count(), 0), grid, out);
  EXPECT_TRUE(std::all_of(out.begin(), out.end(), [](std::uint16_t v) { return v == 0; }));
}

TEST(Chamfer5711, LargestGridFarCornerDoesNotOverflow) {
  // A single seed in one corner of the largest grid: the far corner is 4095 diagonal steps away.
  const view::GridSize grid{view::kMaxGridSide, view::kMaxGridSide};
  std::vector<std::uint8_t> image(grid.cell_count(), 1);
  image[0] = 0;
  std::vector<std::uint16_t> out(grid.cell_count());
  view::chamfer_5_7_11(image, grid, out);
  EXPECT_EQ(out[grid.cell(view::kMaxGridSide - 1, view::kMaxGridSide - 1)], 4095 * 7);
  EXPECT_EQ(out[grid.cell(view::kMaxGridSide - 1, 0)], 4095 * 5);
  // (4095, 2047): 2047 knight moves (2, 1) give (4094, 2047), one more edge step: 2047·11 + 5.
  EXPECT_EQ(out[grid.cell(view::kMaxGridSide - 1, 2047)], 2047 * 11 + 5);
}

TEST(ChamferFocus, SeveralFociGiveDistanceToNearestFocus) {
  // Focus mode: seeds are the focus cells. Compare with the Dijkstra reference seeded the same way,
  // which is the chamfer distance to the nearest focus by definition.
  const view::GridSize grid{61, 47};
  const std::vector<std::uint32_t> foci = {grid.cell(3, 4), grid.cell(50, 40), grid.cell(30, 10),
                                           view::kNoCell};
  std::vector<std::uint8_t> image(grid.cell_count(), 1);
  for (const std::uint32_t c : foci)
    if (c != view::kNoCell) image[c] = 0;
  view::DistanceTransformer transformer;
  std::vector<std::uint16_t> out(grid.cell_count());
  transformer.chamfer_from_cells(view::DistanceMetric::kChamfer5711, foci, grid, out);
  EXPECT_EQ(out, dijkstra(image, grid, view::kChamfer5711Forward));
  // And by hand: (3, 4) is the focus (0); (5, 5) is one knight move from it (11).
  EXPECT_EQ(out[grid.cell(3, 4)], 0);
  EXPECT_EQ(out[grid.cell(5, 5)], 11);
}

TEST(ChamferFocus, NoFocusLeavesEveryCellUnreached) {
  const view::GridSize grid{9, 9};
  std::vector<std::uint16_t> out(grid.cell_count());
  view::DistanceTransformer().chamfer_from_cells(view::DistanceMetric::kChamfer5711, {}, grid, out);
  EXPECT_TRUE(
      std::all_of(out.begin(), out.end(), [](std::uint16_t v) { return v == view::kChamferUnreached; }));
}

TEST(ChamferFocus, ARectangleHoldingTheFociGivesTheWholeGridsLabelsInside) {
  // Every metric's labels over random rectangles holding random foci: inside, the whole grid's
  // transform; outside, unreached.
  const view::GridSize grid{70, 53};
  std::mt19937 rng(11);
  view::DistanceTransformer within, whole;
  for (const view::DistanceMetric metric :
       {view::DistanceMetric::kChamfer5711, view::DistanceMetric::kChamfer34,
        view::DistanceMetric::kCityBlock, view::DistanceMetric::kChessboard,
        view::DistanceMetric::kEuclidean}) {
    for (int round = 0; round < 20; ++round) {
      auto coordinate = [&](std::uint32_t n) {
        return std::uniform_int_distribution<std::uint32_t>(0, n - 1)(rng);
      };
      view::CellRect rect{coordinate(grid.width), coordinate(grid.height), 0, 0};
      rect.x1 = rect.x0 + 1 + coordinate(grid.width - rect.x0);
      rect.y1 = rect.y0 + 1 + coordinate(grid.height - rect.y0);
      std::vector<std::uint32_t> foci{view::kNoCell};
      for (std::uint32_t k = 0, n = 1 + coordinate(3); k < n; ++k)
        foci.push_back(grid.cell(rect.x0 + coordinate(rect.width()), rect.y0 + coordinate(rect.height())));
      std::vector<std::uint16_t> inside(grid.cell_count()), expected(grid.cell_count());
      within.labels_from_cells_within(metric, foci, grid, rect, inside);
      whole.labels_from_cells(metric, foci, grid, expected);
      for (std::uint32_t y = 0; y < grid.height; ++y) {
        for (std::uint32_t x = 0; x < grid.width; ++x) {
          const bool in = x >= rect.x0 && x < rect.x1 && y >= rect.y0 && y < rect.y1;
          ASSERT_EQ(inside[grid.cell(x, y)], in ? expected[grid.cell(x, y)] : view::kChamferUnreached)
              << int(metric) << " round " << round << " cell " << x << "," << y;
        }
      }
    }
  }
}

TEST(DistanceTransformer, ReusedObjectGivesSameResultsAcrossGridSizes) {
  // Scratch reuse must not leak values from a previous, larger or smaller request.
  std::mt19937 rng(7);
  view::DistanceTransformer transformer;
  for (const view::GridSize grid :
       {view::GridSize{40, 30}, view::GridSize{9, 70}, view::GridSize{40, 30}, view::GridSize{5, 5}}) {
    const auto image = random_image(grid, rng, 3);
    std::vector<std::uint16_t> reused(grid.cell_count()), fresh(grid.cell_count());
    transformer.chamfer(view::DistanceMetric::kChamfer5711, image, grid, reused);
    view::chamfer_5_7_11(image, grid, fresh);
    EXPECT_EQ(reused, fresh);
    std::vector<std::uint32_t> e_reused(grid.cell_count()), e_fresh(grid.cell_count());
    transformer.euclidean_squared(image, grid, e_reused);
    view::euclidean_squared(image, grid, e_fresh);
    EXPECT_EQ(e_reused, e_fresh);
  }
}

// Reference for the constrained transform: Dijkstra from the seeds over mask moves whose two ends are
// passable (seeds count as passable).
std::vector<std::uint16_t> constrained_dijkstra(const std::vector<std::uint32_t>& seeds,
                                                std::vector<std::uint8_t> passable, view::GridSize grid) {
  for (const std::uint32_t c : seeds) passable[c] = 1;
  std::vector<std::uint32_t> dist(grid.cell_count(), 0xFFFFFFFFu);
  using Entry = std::pair<std::uint32_t, std::uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
  for (const std::uint32_t c : seeds) {
    dist[c] = 0;
    queue.push({0, c});
  }
  while (!queue.empty()) {
    const auto [d, c] = queue.top();
    queue.pop();
    if (d != dist[c]) continue;
    const int x = static_cast<int>(c % grid.width), y = static_cast<int>(c / grid.width);
    for (const view::ChamferStep& s : view::kChamfer5711Forward) {
      for (const int sign : {1, -1}) {
        const int nx = x + sign * s.dx, ny = y + sign * s.dy;
        if (nx < 0 || ny < 0 || nx >= static_cast<int>(grid.width) || ny >= static_cast<int>(grid.height))
          continue;
        const std::uint32_t n = grid.cell(static_cast<std::uint32_t>(nx), static_cast<std::uint32_t>(ny));
        if (!passable[n]) continue;
        if (d + s.weight < dist[n]) {
          dist[n] = d + s.weight;
          queue.push({dist[n], n});
        }
      }
    }
  }
  std::vector<std::uint16_t> out(dist.size());
  for (std::size_t c = 0; c < dist.size(); ++c) {
    out[c] = dist[c] == 0xFFFFFFFFu ? view::kChamferUnreached : static_cast<std::uint16_t>(dist[c]);
  }
  return out;
}

TEST(ChamferConstrained, MatchesDijkstraThroughPassableCellsOnly) {
  std::mt19937 rng(2006);
  view::DistanceTransformer transformer;
  for (const view::GridSize grid :
       {view::GridSize{1, 30}, view::GridSize{30, 1}, view::GridSize{17, 13}, view::GridSize{64, 48}}) {
    for (const int blocked_percent : {0, 20, 45}) {
      std::vector<std::uint8_t> passable = random_image(grid, rng, blocked_percent);  // 0 = blocked
      std::uniform_int_distribution<std::uint32_t> cell(0, static_cast<std::uint32_t>(grid.cell_count() - 1));
      const std::vector<std::uint32_t> seeds = {cell(rng), cell(rng), view::kNoCell};
      std::vector<std::uint16_t> out(grid.cell_count());
      const std::size_t rounds =
          transformer.chamfer_constrained(view::DistanceMetric::kChamfer5711, seeds, passable, grid, out);
      EXPECT_LT(rounds, 256u) << "did not converge";
      const std::vector<std::uint32_t> real_seeds(seeds.begin(), seeds.end() - 1);
      ASSERT_EQ(out, constrained_dijkstra(real_seeds, passable, grid))
          << grid.width << "x" << grid.height << " blocked " << blocked_percent << "%";
    }
  }
}

TEST(ChamferConstrained, WallIsCrossedOnlyByAKnightMove) {
  // 7×5 grid, seed at (0, 0), column 3 blocked except its bottom cell. The straight path to (6, 0)
  // (30) is cut. Edge and diagonal moves cannot skip column 3, but a knight move (2, ±1) has both ends
  // passable and jumps it (the constraint applies to the ends of each move): (0,0) → (2,0) costs 10,
  // the knight to (4,1) 11, the knight back to (6,0) 11, so 32, less than the way round the gap.
  const view::GridSize grid{7, 5};
  std::vector<std::uint8_t> passable(grid.cell_count(), 1);
  for (std::uint32_t j = 0; j < 4; ++j) passable[grid.cell(3, j)] = 0;
  std::vector<std::uint16_t> out(grid.cell_count());
  view::DistanceTransformer transformer;
  const std::vector<std::uint32_t> seeds = {0};
  transformer.chamfer_constrained(view::DistanceMetric::kChamfer5711, seeds, passable, grid, out);
  EXPECT_EQ(out[grid.cell(3, 1)], view::kChamferUnreached);  // inside the wall
  EXPECT_EQ(out[grid.cell(6, 0)], 32);
  EXPECT_EQ(out, constrained_dijkstra(seeds, passable, grid));
}

std::vector<std::uint32_t> brute_force_edt(const std::vector<std::uint8_t>& image, view::GridSize grid) {
  std::vector<std::uint32_t> out(grid.cell_count(), view::kEuclideanUnreached);
  for (std::uint32_t c = 0; c < image.size(); ++c) {
    for (std::uint32_t s = 0; s < image.size(); ++s) {
      if (image[s] != 0) continue;
      const std::int64_t dx = static_cast<std::int64_t>(c % grid.width) - s % grid.width;
      const std::int64_t dy = static_cast<std::int64_t>(c / grid.width) - s / grid.width;
      out[c] = std::min<std::uint32_t>(out[c], static_cast<std::uint32_t>(dx * dx + dy * dy));
    }
  }
  return out;
}

TEST(EuclideanSquared, MatchesBruteForceOnRandomGrids) {
  std::mt19937 rng(1966);
  for (const view::GridSize grid : test_sizes()) {
    for (const int background_percent : {0, 1, 5, 30, 100}) {
      const auto image = random_image(grid, rng, background_percent);
      std::vector<std::uint32_t> out(grid.cell_count(), 0xABCD);
      view::euclidean_squared(image, grid, out);
      ASSERT_EQ(out, brute_force_edt(image, grid))
          << grid.width << "x" << grid.height << " " << background_percent;
    }
  }
}

TEST(EuclideanSquared, FromCellsMatchesImageSeeds) {
  const view::GridSize grid{33, 21};
  const std::vector<std::uint32_t> foci = {grid.cell(0, 0), grid.cell(32, 20), grid.cell(16, 3)};
  std::vector<std::uint8_t> image(grid.cell_count(), 1);
  for (const std::uint32_t c : foci) image[c] = 0;
  std::vector<std::uint32_t> out(grid.cell_count());
  view::DistanceTransformer().euclidean_squared_from_cells(foci, grid, out);
  EXPECT_EQ(out, brute_force_edt(image, grid));
  // (3, 4) from (0, 0): 3² + 4² = 25.
  EXPECT_EQ(out[grid.cell(3, 4)], 25u);
}

TEST(DistanceUnits, PixelsAndThresholdsFollowEachMetric) {
  EXPECT_EQ(view::distance_px(10, view::DistanceMetric::kChamfer5711), 2.0f);
  EXPECT_EQ(view::distance_px(9, view::DistanceMetric::kChamfer34), 3.0f);
  EXPECT_EQ(view::distance_px(25, view::DistanceMetric::kEuclidean), 5.0f);
  EXPECT_EQ(view::raw_threshold(2.0f, view::DistanceMetric::kChamfer5711), 10u);
  EXPECT_EQ(view::raw_threshold(2.5f, view::DistanceMetric::kChamfer34), 7u);  // floor(7.5)
  EXPECT_EQ(view::raw_threshold(3.0f, view::DistanceMetric::kEuclidean), 9u);
  EXPECT_EQ(view::raw_threshold(1.5f, view::DistanceMetric::kChessboard), 1u);
}

}  // namespace
}  // namespace mtlod::core
