// MT benchmarks (core/ARCHITECTURE.md §2), peers in the same run: building the MT of the 871k
// dragon against meshoptimizer's meshopt_simplify and OpenMesh's Decimater (ModQuadric) to the same
// triangle count; static, budgeted and dynamic refinement output rates; bytes per input triangle.
//   build/tests/mtlod_bench_mt --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>
#include <meshoptimizer.h>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "core/build/mt_builder.hpp"
#include "core/cut/refine.hpp"
#include "core/io/mesh_io.hpp"
#include "core/threads/thread_pool.hpp"
#include "tests/bench/bench_support.hpp"

namespace {

using mtlod::bench::refined;

using namespace mtlod::core;

const model::Mesh* dragon() {
  static const model::Mesh* mesh = []() -> const model::Mesh* {
    const auto path = std::filesystem::path(MTLOD_SHARED_MESHES_DIR) / "dragon-vrip-871k.ply";
    auto loaded = io::load_mesh(path);
    if (!loaded) {
      std::fprintf(stderr, "cannot load %s: %s\n", path.c_str(), loaded.error().message.c_str());
      return nullptr;
    }
    return new model::Mesh(std::move(loaded->mesh));
  }();
  return mesh;
}

const model::Mt* dragon_mt() {
  static const model::Mt* mt = []() -> const model::Mt* {
    if (!dragon()) return nullptr;
    auto built = build::build_mt(*dragon());
    return built ? new model::Mt(std::move(built).value()) : nullptr;
  }();
  return mt;
}

void BM_BuildMt(benchmark::State& state) {
  const model::Mesh* mesh = dragon();
  if (!mesh) return state.SkipWithError("dragon-vrip-871k.ply not found");
  build::BuildStats stats;
  build::BuildOptions options;
  // range(0) = 1: the pass's independent work on every core (2 here); the MT is the same as serial.
  mtlod::core::threads::ThreadPool pool;
  if (state.range(0) == 1) pool.attach(options);
  for (auto _ : state) {
    auto mt = build::build_mt(*mesh, options, &stats);
    benchmark::DoNotOptimize(mt);
    if (!mt) return state.SkipWithError("build failed");
    state.counters["bytes_per_input_triangle"] = double(mt->memory_bytes()) / double(mesh->triangle_count());
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(mesh->triangle_count()));
  state.counters["root_triangles"] = double(stats.root_triangles);
  state.counters["nodes"] = double(stats.nodes);
}
// Wall time: the threaded build spends CPU time on threads the main thread does not count.
BENCHMARK(BM_BuildMt)
    ->ArgName("threaded")
    ->Arg(0)
    ->Arg(1)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

// meshopt_simplify to a fraction of the input (range(0) percent), no error limit.
void BM_MeshoptSimplify(benchmark::State& state) {
  const model::Mesh* mesh = dragon();
  if (!mesh) return state.SkipWithError("dragon-vrip-871k.ply not found");
  const std::size_t target = mesh->triangles.size() * std::size_t(state.range(0)) / 100 / 3 * 3;
  std::vector<std::uint32_t> out(mesh->triangles.size());
  std::size_t result = 0;
  for (auto _ : state) {
    result = meshopt_simplify(out.data(), mesh->triangles.data(), mesh->triangles.size(),
                              mesh->positions.data(), mesh->vertex_count(), 12, target, 1.0f, 0, nullptr);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(mesh->triangle_count()));
  state.counters["output_triangles"] = double(result / 3);
}
BENCHMARK(BM_MeshoptSimplify)->Arg(10)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(3);

// OpenMesh Decimater with ModQuadric, to 10% of the input. About 16 s: one iteration.
void BM_OpenMeshDecimater(benchmark::State& state) {
  using OmMesh = OpenMesh::TriMesh_ArrayKernelT<>;
  const model::Mesh* mesh = dragon();
  if (!mesh) return state.SkipWithError("dragon-vrip-871k.ply not found");
  const std::size_t target = mesh->triangle_count() * std::size_t(state.range(0)) / 100;
  std::size_t result = 0;
  for (auto _ : state) {
    state.PauseTiming();
    OmMesh om;
    std::vector<OmMesh::VertexHandle> handles(mesh->vertex_count());
    for (std::size_t v = 0; v < mesh->vertex_count(); ++v)
      handles[v] = om.add_vertex(
          OmMesh::Point(mesh->positions[3 * v], mesh->positions[3 * v + 1], mesh->positions[3 * v + 2]));
    for (std::size_t t = 0; t < mesh->triangle_count(); ++t)
      om.add_face(handles[mesh->triangles[3 * t]], handles[mesh->triangles[3 * t + 1]],
                  handles[mesh->triangles[3 * t + 2]]);
    state.ResumeTiming();
    OpenMesh::Decimater::DecimaterT<OmMesh> decimater(om);
    OpenMesh::Decimater::ModQuadricT<OmMesh>::Handle quadric;
    decimater.add(quadric);
    decimater.initialize();
    decimater.decimate_to_faces(0, target);
    om.garbage_collection();
    result = om.n_faces();
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(mesh->triangle_count()));
  state.counters["output_triangles"] = double(result);
}
BENCHMARK(BM_OpenMeshDecimater)->Arg(10)->Unit(benchmark::kMillisecond)->Iterations(1);

// The uniform error whose static cut has about `triangles` triangles (bisection on a log scale).
float error_for_size(const model::Mt& mt, std::size_t triangles) {
  cut::Refiner refiner(mt);
  cut::CutMesh cut;
  float lo = 1e-7f, hi = *std::max_element(mt.node_error.begin(), mt.node_error.end());
  for (int i = 0; i < 40; ++i) {
    const float mid = std::sqrt(lo * hi);
    refined(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(mid)), cut));
    (cut.triangle_count() > triangles ? lo : hi) = mid;
  }
  return hi;
}

// A per-vertex field fine near a focus vertex and coarse away from it (what labels will give).
std::vector<float> focus_field(const model::Mesh& mesh, std::size_t focus_vertex, float fine, float coarse,
                               float radius) {
  std::vector<float> field(mesh.vertex_count());
  const float* f = &mesh.positions[3 * focus_vertex];
  for (std::size_t v = 0; v < field.size(); ++v) {
    const float* p = &mesh.positions[3 * v];
    const float d = std::sqrt((p[0] - f[0]) * (p[0] - f[0]) + (p[1] - f[1]) * (p[1] - f[1]) +
                              (p[2] - f[2]) * (p[2] - f[2]));
    field[v] = fine + (coarse - fine) * std::min(1.0f, d / radius);
  }
  return field;
}

void BM_RefineStatic(benchmark::State& state) {
  const model::Mt* mt = dragon_mt();
  if (!mt) return state.SkipWithError("dragon-vrip-871k.ply not found");
  const float e = error_for_size(*mt, std::size_t(state.range(0)));
  cut::Refiner refiner(*mt);
  cut::CutMesh cut;
  for (auto _ : state) {
    refined(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(e)), cut));
    benchmark::DoNotOptimize(cut.triangles.data());
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(cut.triangle_count()));
  state.counters["triangles"] = double(cut.triangle_count());
  state.counters["bytes_per_input_triangle"] =
      double(mt->memory_bytes()) / double(dragon()->triangle_count());
}
BENCHMARK(BM_RefineStatic)->Arg(50'000)->Arg(500'000)->Unit(benchmark::kMicrosecond);

void BM_RefineBudget(benchmark::State& state) {
  const model::Mt* mt = dragon_mt();
  if (!mt) return state.SkipWithError("dragon-vrip-871k.ply not found");
  cut::Refiner refiner(*mt);
  cut::CutMesh cut;
  for (auto _ : state) {
    refined(refiner.refine(
        cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(std::size_t(state.range(0))),
        cut));
    benchmark::DoNotOptimize(cut.triangles.data());
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(cut.triangle_count()));
  state.counters["triangles"] = double(cut.triangle_count());
}
BENCHMARK(BM_RefineBudget)->Arg(50'000)->Unit(benchmark::kMicrosecond);

// Budget with a per-vertex field: the error/allowed ratio heap.
void BM_RefineBudgetPerVertex(benchmark::State& state) {
  const model::Mt* mt = dragon_mt();
  if (!mt) return state.SkipWithError("dragon-vrip-871k.ply not found");
  const model::Mesh& mesh = *dragon();
  const std::vector<float> field = focus_field(mesh, mesh.triangles[3 * 1000], 1e-5f, 1e-3f, 0.05f);
  cut::Refiner refiner(*mt);
  cut::CutMesh cut;
  for (auto _ : state) {
    refined(refiner.refine(cut::Refinement::from_root(cut::AllowedError::from_vertices(field))
                               .within(std::size_t(state.range(0))),
                           cut));
    benchmark::DoNotOptimize(cut.triangles.data());
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(cut.triangle_count()));
  state.counters["triangles"] = double(cut.triangle_count());
}
BENCHMARK(BM_RefineBudgetPerVertex)->Arg(50'000)->Unit(benchmark::kMicrosecond);

// Two per-vertex fields whose foci are neighbouring vertices: a small change between requests.
struct FieldPair {
  std::vector<float> a, b;
};
const FieldPair& small_change_fields() {
  static const FieldPair pair = [] {
    const model::Mesh& mesh = *dragon();
    const model::Mt& mt = *dragon_mt();
    const float e = error_for_size(mt, 50'000);
    const std::uint32_t f = mesh.triangles[3 * 1000];
    const std::uint32_t g = mesh.triangles[3 * 1000 + 1];  // a neighbour of f
    return FieldPair{focus_field(mesh, f, e * 0.1f, e * 2, 0.02f),
                     focus_field(mesh, g, e * 0.1f, e * 2, 0.02f)};
  }();
  return pair;
}

// The same field with 20 vertices changed: the smallest change a request can bring.
const FieldPair& few_vertex_fields() {
  static const FieldPair pair = [] {
    FieldPair p{small_change_fields().a, small_change_fields().a};
    for (std::size_t i = 0; i < 20; ++i) p.b[(i * 7919 * 13) % p.b.size()] *= 0.25f;
    return p;
  }();
  return pair;
}
const FieldPair& fields_for(std::int64_t which) {
  return which == 0 ? small_change_fields() : few_vertex_fields();
}

void BM_RefinePerVertexStatic(benchmark::State& state) {
  const model::Mt* mt = dragon_mt();
  if (!mt) return state.SkipWithError("dragon-vrip-871k.ply not found");
  const FieldPair& fields = fields_for(state.range(0));
  cut::Refiner refiner(*mt);
  cut::CutMesh cut;
  bool flip = false;
  for (auto _ : state) {
    refined(refiner.refine(
        cut::Refinement::from_root(cut::AllowedError::from_vertices(flip ? fields.b : fields.a)), cut));
    flip = !flip;
    benchmark::DoNotOptimize(cut.triangles.data());
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(cut.triangle_count()));
  state.counters["triangles"] = double(cut.triangle_count());
}
// Arg 0: the focus moved to a neighbouring vertex; arg 1: 20 vertices changed.
BENCHMARK(BM_RefinePerVertexStatic)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_RefinePerVertexDynamic(benchmark::State& state) {
  const model::Mt* mt = dragon_mt();
  if (!mt) return state.SkipWithError("dragon-vrip-871k.ply not found");
  const FieldPair& fields = fields_for(state.range(0));
  cut::Refiner refiner(*mt);
  cut::CutMesh cut;
  refined(refiner.refine(cut::Refinement::move(cut::AllowedError::from_vertices(fields.a)), cut));
  refined(refiner.refine(cut::Refinement::move(cut::AllowedError::from_vertices(fields.b)), cut));
  bool flip = false;
  for (auto _ : state) {
    refined(refiner.refine(
        cut::Refinement::move(cut::AllowedError::from_vertices(flip ? fields.b : fields.a)), cut));
    flip = !flip;
    benchmark::DoNotOptimize(cut.triangles.data());
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(cut.triangle_count()));
  state.counters["triangles"] = double(cut.triangle_count());
}
BENCHMARK(BM_RefinePerVertexDynamic)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// 20 vertices changed, and the caller says which (no O(vertices) comparison).
void BM_RefinePerVertexDynamicChangedList(benchmark::State& state) {
  const model::Mt* mt = dragon_mt();
  if (!mt) return state.SkipWithError("dragon-vrip-871k.ply not found");
  const FieldPair& fields = few_vertex_fields();
  std::vector<std::uint32_t> changed;
  for (std::uint32_t v = 0; v < fields.a.size(); ++v)
    if (fields.a[v] != fields.b[v]) changed.push_back(v);
  cut::Refiner refiner(*mt);
  cut::CutMesh cut;
  refined(refiner.refine(cut::Refinement::move(cut::AllowedError::from_vertices(fields.a)), cut));
  refined(refiner.refine(cut::Refinement::move(cut::AllowedError::from_vertices(fields.b)), cut));
  bool flip = false;
  for (auto _ : state) {
    refined(refiner.refine(
        cut::Refinement::move(cut::AllowedError::from_vertices(flip ? fields.b : fields.a), changed), cut));
    flip = !flip;
    benchmark::DoNotOptimize(cut.triangles.data());
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(cut.triangle_count()));
  state.counters["triangles"] = double(cut.triangle_count());
  state.counters["changed_vertices"] = double(changed.size());
}
BENCHMARK(BM_RefinePerVertexDynamicChangedList)->Unit(benchmark::kMicrosecond);

}  // namespace
