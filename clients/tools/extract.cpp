// mtlod-extract: loads an .mt file and writes one selective refinement of it as a mesh
// (core/ARCHITECTURE.md §2.4): a uniform bound (--error, model units) and/or a budget (--budget),
// or, with a camera or criteria, the view-dependent extraction the server computes for the same
// flags (core/ARCHITECTURE.md §1; the flags are clients/common/extract_flags, shared with
// mtlod-client), with the occupancy and distance images on request.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "clients/common/extract_flags.hpp"
#include "core/build/vertex_normals.hpp"
#include "core/codec/cut_encoder.hpp"
#include "core/cut/refine.hpp"
#include "core/io/gltf.hpp"
#include "core/io/image_io.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/model/bounds.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/view_extract.hpp"
#include "fmt/format.h"
#include "fmt/ranges.h"
#include "protocol/parse.hpp"
#include "protocol/view_request.hpp"

namespace {

struct ExtractOptions {
  std::string model;                    // .mt file to read
  std::string output;                   // mesh to write (.ply, .obj, .drc or .glb)
  std::string gltf_compression = "on";  // .glb: the payload of --codec under its glTF extension, or plain
  std::string dump_dt;                  // PNG of the silhouette (else focus) distance transform
  std::string dump_occupancy;           // PNG of the occupancy grid
  mtlod::clients::ExtractFlags view;    // --error, --budget, camera, criteria, grid, Draco
};

void add_extract_options(CLI::App& app, ExtractOptions& o) {
  app.add_option("model", o.model, "MT file written by mtlod-build")->required();
  app.add_option("-o,--output", o.output,
                 "mesh to write: .ply (binary), .obj, .drc (Draco), .mopt (meshopt), or .glb (binary glTF "
                 "2.0 with the "
                 "model's normals and colours)")
      ->required();
  app.add_option(
         "--gltf-compression,--gltf-draco", o.gltf_compression,
         "on: the .glb holds the cut in --codec's payload (Draco: KHR_draco_mesh_compression; meshopt: "
         "EXT_meshopt_compression); off: plain arrays, for readers without either")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option("--dump-dt", o.dump_dt, "write the distance transform as PNG (view-dependent mode)");
  app.add_option("--dump-occupancy", o.dump_occupancy,
                 "write the occupancy grid as PNG (view-dependent mode)");
  mtlod::clients::add_extract_flags(app, o.view);
}

// View-dependent when a camera, a criterion or a pixel bound is given; otherwise uniform.
bool view_dependent(const ExtractOptions& o) {
  const auto& v = o.view;
  const bool criteria = std::any_of(v.criteria.entries.begin(), v.criteria.entries.end(),
                                    [](const auto& values) { return !values.empty(); });
  return !v.eye.empty() || !v.target.empty() || criteria || v.error_px.has_value() || !o.dump_dt.empty() ||
         !o.dump_occupancy.empty();
}

// The cut with its used vertices only, renumbered in first-use order; normals and colours follow.
mtlod::core::model::Mesh compact(const mtlod::core::model::Mt& mt,
                                 const std::vector<std::uint32_t>& triangles) {
  mtlod::core::model::Mesh mesh;
  std::vector<std::uint32_t> remap(mt.vertex_count(), UINT32_MAX);
  mesh.triangles.reserve(triangles.size());
  for (const std::uint32_t v : triangles) {
    if (remap[v] == UINT32_MAX) {
      remap[v] = std::uint32_t(mesh.positions.size() / 3);
      mesh.positions.insert(mesh.positions.end(), &mt.positions[3 * std::size_t{v}],
                            &mt.positions[3 * std::size_t{v} + 3]);
      if (mt.has_normals())
        mesh.normals.insert(mesh.normals.end(), &mt.normals[3 * std::size_t{v}],
                            &mt.normals[3 * std::size_t{v} + 3]);
      if (mt.has_colors())
        mesh.colors.insert(mesh.colors.end(), &mt.colors[3 * std::size_t{v}],
                           &mt.colors[3 * std::size_t{v} + 3]);
    }
    mesh.triangles.push_back(remap[v]);
  }
  return mesh;
}

using namespace mtlod;
using namespace mtlod::core;

// Writes the cut as a mesh file, or as the payload the server would send for the request: Draco
// (.drc) or meshopt (.mopt), or either in a .glb (--codec; with the model's normals and colours, and
// no labels: glTF has no meaning for them). `named` is --codec's, when given.
Status write_output(const std::string& path, bool gltf_compressed, const model::Mt& mt,
                    const cut::CutMesh& cut, const protocol::Extract* request,
                    std::optional<codec::Codec> named, std::span<const std::uint32_t> labels) {
  const auto extension = std::filesystem::path(path).extension();
  const bool glb = extension == ".glb";
  const std::optional<codec::Codec> file_codec = codec::codec_of_file(extension.string());
  if (glb && !gltf_compressed) return io::write_glb(path, compact(mt, cut.triangles));
  if (!glb && !file_codec) return io::save_mesh(path, compact(mt, cut.triangles));
  codec::EncodeOptions options;
  if (request) {
    options = protocol::to_encode_options(*request, {false, mt.has_colors(), mt.bounds.lo, mt.bounds.hi});
    options.payload.labels = options.payload.labels && !labels.empty();
  } else {
    options.payload.normals = mt.has_normals();
    options.payload.colors = mt.has_colors();
  }
  // A payload file's extension names its codec; a .glb holds either (--codec, Draco by default).
  const codec::Codec codec = glb ? named.value_or(codec::Codec::kDraco) : *file_codec;
  if (named && *named != codec) {
    return make_error(
        ErrorCode::kInvalidArgument,
        fmt::format("{}: --codec {} writes {}", path, protocol::enum_name(protocol::kCodecNames, *named),
                    codec::traits(*named).file_extension));
  }
  if (request) {
    if (auto refusal = protocol::codec_refusal(*request, codec))
      return make_error(ErrorCode::kInvalidArgument, fmt::format("{}: {}", path, *refusal));
  }
  options.codec = codec;
  if (glb) {
    options.payload.normals = mt.has_normals();
    options.payload.colors = mt.has_colors();
    options.payload.labels = false;
  }
  std::vector<std::uint8_t> bytes;
  MTLOD_TRY(codec::EncodeStats stats,
            codec::CutEncoder().encode({mt.positions, mt.normals, labels, cut.triangles, mt.colors}, options,
                                       bytes));
  if (glb) return io::write_glb_payload(path, codec, bytes);
  std::FILE* f = std::fopen(path.c_str(), "wb");
  const bool ok = f && std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  if (f) std::fclose(f);
  if (!ok) return make_error(ErrorCode::kIoError, fmt::format("{}: write failed", path));
  (void)stats;
  return Ok{};
}

}  // namespace

int run(int argc, char** argv) {
  using namespace mtlod::core;
  CLI::App app{
      "Extract a level of detail from a Multi-Tessellation: uniform (--error, --budget) or "
      "view-dependent (camera, silhouette, focus... as mtlod-client extract)."};
  ExtractOptions options;
  add_extract_options(app, options);
  CLI11_PARSE(app, argc, argv);
  const bool view = view_dependent(options);
  if (!view && !options.view.error && !options.view.budget) {
    fmt::print(stderr, "mtlod-extract: give --error E, --budget N or both, or a camera and criteria\n");
    return 2;
  }

  auto start = std::chrono::steady_clock::now();
  auto mt = io::read_mt_file(options.model);
  if (!mt) {
    fmt::print(stderr, "mtlod-extract: {}\n", mt.error().message);
    return 1;
  }
  // An MT stored without normals gets them as the server gives them: computed once at load.
  if (const Result<bool> computed = build::ensure_normals(*mt); !computed) {
    fmt::print(stderr, "mtlod-extract: {}\n", computed.error().message);
    return 1;
  }
  const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  cut::Refiner refiner(*mt);
  cut::CutMesh cut;
  std::optional<mtlod::protocol::Extract> request;
  std::unique_ptr<view::OccupancyLevels> levels;
  std::unique_ptr<view::ViewExtractor> extractor;
  double refine_s = 0;
  if (view) {
    const model::Bounds& box = mt->bounds;
    auto made = mtlod::clients::make_extract(options.view, options.model, model::to_double(box.lo),
                                             model::to_double(box.hi));
    if (!made) {
      fmt::print(stderr, "mtlod-extract: {}\n", made.error().message);
      return 2;
    }
    request = std::move(*made);
    auto made_levels = view::OccupancyLevels::make(*mt);
    if (!made_levels) {
      fmt::print(stderr, "mtlod-extract: {}\n", made_levels.error().message);
      return 1;
    }
    levels = std::move(*made_levels);
    extractor = std::make_unique<view::ViewExtractor>(*mt, *levels);
    view::ViewRequest v = mtlod::protocol::to_view_request(*request, mt->has_normals());
    v.dynamic = false;
    if (!options.dump_dt.empty()) v.labels = true;  // every transform over the whole grid
    start = std::chrono::steady_clock::now();
    const Result<cut::CutSpan> extracted = extractor->extract(v, refiner, cut);
    if (!extracted) {
      fmt::print(stderr, "mtlod-extract: {}\n", extracted.error().message);
      return 1;
    }
    cut.assign(*extracted);
    refine_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const view::GridSize grid{request->grid[0], request->grid[1]};
    if (!options.dump_occupancy.empty()) {
      if (auto s = io::write_occupancy_png(options.dump_occupancy, extractor->occupancy_grid(), grid); !s) {
        fmt::print(stderr, "mtlod-extract: {}\n", s.error().message);
        return 1;
      }
    }
    if (!options.dump_dt.empty()) {
      const auto silhouette = extractor->distance_transform(view::Criterion::kSilhouette);
      const auto dt = silhouette.empty() ? extractor->distance_transform(view::kGazeCriterion) : silhouette;
      if (dt.empty()) {
        fmt::print(stderr, "mtlod-extract: --dump-dt needs --silhouette or --focus\n");
        return 2;
      }
      // Exact Euclidean labels come in fifths of a pixel, like 5-7-11 (see core/view/view_extract).
      const view::DistanceMetric metric = v.allowed.metric;
      const std::uint32_t per_px =
          metric == view::DistanceMetric::kEuclidean ? 5 : view::units_per_pixel(metric);
      if (auto s = io::write_distance_png(options.dump_dt, dt, grid, per_px); !s) {
        fmt::print(stderr, "mtlod-extract: {}\n", s.error().message);
        return 1;
      }
    }
  } else {
    start = std::chrono::steady_clock::now();
    // Without --error every triangle that has a finer version competes, ranked by its error.
    cut::Refinement uniform = cut::Refinement::from_root(
        cut::AllowedError::everywhere(static_cast<float>(options.view.error.value_or(0.0))));
    if (options.view.budget) uniform.within(*options.view.budget);
    if (const Status refined = refiner.refine(uniform, cut); !refined) {
      fmt::print(stderr, "mtlod-extract: {}\n", refined.error().message);
      return 1;
    }
    refine_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  if (!cut.within_budget)
    fmt::print(stderr, "mtlod-extract: warning: the coarsest mesh has {} triangles, over the budget of {}\n",
               cut.triangle_count(), *options.view.budget);

  const std::span<const std::uint32_t> labels =
      extractor ? extractor->vertex_labels() : std::span<const std::uint32_t>();
  std::optional<codec::Codec> named;
  if (!options.view.codec.empty()) {
    named = protocol::enum_from_name<codec::Codec>(protocol::kCodecNames, options.view.codec);
    if (!named) {
      fmt::print(stderr, "mtlod-extract: --codec '{}': expected one of {}\n", options.view.codec,
                 fmt::join(protocol::kCodecNames, ", "));
      return 2;
    }
  }
  if (auto saved = write_output(options.output, options.gltf_compression == "on", *mt, cut,
                                request ? &*request : nullptr, named, labels);
      !saved) {
    fmt::print(stderr, "mtlod-extract: {}\n", saved.error().message);
    return 1;
  }
  fmt::print(
      "{}: {} triangles, {} of {} nodes, max error {:.6g}{}\n  loaded in {:.3f} s, {} in {:.3f} ms; wrote "
      "{}\n",
      options.model, cut.triangle_count(), cut.node_count, mt->node_count(), cut.max_error,
      view ? fmt::format(", occupancy from {} triangles",
                         extractor->occupancy_level() ? extractor->occupancy_level()->triangle_count() : 0)
           : "",
      load_s, view ? "extracted (map, occupancy, distance transforms, allowed error, refinement)" : "refined",
      refine_s * 1e3, options.output);
  return 0;
}

int main(int argc, char** argv) {
  return run(argc, argv);
}
