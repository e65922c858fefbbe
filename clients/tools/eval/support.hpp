// What the subcommands of mtlod-eval share: cameras around a model, loading and caching, shaded
// renderings and their image-space comparison (core/eval/image_metrics), the focus of a view.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/codec/draco_encode.hpp"
#include "core/eval/image_metrics.hpp"
#include "core/model/bounds.hpp"
#include "core/model/mesh.hpp"
#include "core/model/mt.hpp"
#include "core/result.hpp"
#include "core/view/grid.hpp"
#include "core/view/view_grid.hpp"

namespace mtlod::eval_tool {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start);

// A perspective camera for a viewport of the given aspect (width / height); fails on a degenerate or
// non-finite setup with a message naming the flag.
Result<core::view::Camera> make_camera(const std::array<double, 3>& eye, const std::array<double, 3>& target,
                                       const std::array<double, 3>& up, double fov_deg, double near,
                                       double far, double aspect = 1.0);

// Camera k of n around a model: azimuth k·360°/n, elevation alternating +25° and −10°, far enough
// that the bounding sphere fills about 90 % of the kOrbitFovDeg field of view.
constexpr double kOrbitFovDeg = 40.0;
core::view::Camera orbit_camera(const core::model::Bounds& b, int k, int n);

// The same camera after the model turned by `degrees` about the vertical axis through the bounds'
// centre: the view an orbiting viewer reaches before a new cut arrives.
core::view::Camera turned_camera(const core::view::Camera& camera, const core::model::Bounds& b,
                                 double degrees);

// The value of a step that cannot fail on the studies' MTs, read whole (cached_mt): a failure is a
// bug, reported before the tool exits with status 1.
[[noreturn]] void fail_study(const Error& error);
template <class T>
T must(Result<T> result) {
  if (!result) fail_study(result.error());
  return std::move(*result);
}

// A mesh file with at least one triangle.
Result<core::model::Mesh> load(const std::filesystem::path& path);

// The MT of `mesh`, read whole (every block checked) from cache_dir/NAME.mt when that file holds
// the same vertex count, else built and written there.
Result<core::model::Mt> cached_mt(const core::model::Mesh& mesh, const std::string& name,
                                  const std::filesystem::path& cache_dir);

// The budgets a study can use on a mesh: above its MT's root (by a quarter) and at most half the input;
// the others are named in `notes`.
std::vector<std::size_t> usable_budgets(const std::vector<std::size_t>& budgets,
                                        const core::model::Mesh& mesh, const core::model::Mt& mt,
                                        const std::string& name, std::vector<std::string>& notes);

// A model for the image-space studies: the mesh, its MT (cached in cache_dir), and the original's
// vertex normals (its file's, else area-weighted) per mesh vertex and per MT vertex (the builder
// renumbers vertices; they are matched by position). The MT carries them too, for back-face tests.
// Held by pointer: extractors and refiners keep references to the MT.
struct ShadedModel {
  std::string name, path;
  core::model::Mesh mesh;
  core::model::Mt mt;
  std::vector<float> normals, mt_normals;
  core::model::Bounds bounds;
};

// spec is NAME=PATH.
Result<std::unique_ptr<ShadedModel>> load_shaded_model(const std::string& spec,
                                                       const std::filesystem::path& cache_dir);

// One shaded rendering: the RGB image, its luminance (core/eval/image_metrics) and the eye-space depth
// of every pixel (+inf on the background).
struct ShadedView {
  std::vector<std::uint8_t> rgb;
  std::vector<float> luminance, depth;
  std::size_t covered_px = 0;
};

// Renders (positions, triangles) through mapping, shaded smoothly with normals (per vertex, indexed
// like positions; empty: flat shading), the figures' colours on a white background.
void render_shaded(const core::view::ViewMapping& mapping, std::span<const float> positions,
                   std::span<const std::uint32_t> triangles, std::span<const float> normals, ShadedView& out);

// Image-space difference of a simplification's rendering from the original's, both from one mapping:
// the metrics of core/eval/image_metrics (covered = either rendering covers the pixel), and from the
// depth, the silhouette XOR and the depth difference where both cover a pixel.
struct ImageMeasure {
  core::eval::ImageComparison image;
  std::size_t xor_px = 0;                // covered by exactly one
  std::size_t both_px = 0;               // covered by both
  double depth_mean = 0, depth_max = 0;  // |depth a − depth b| over both_px, model units
};

// Scratch reused between calls (one per thread); `covered` and `map` describe the last call.
struct ImageScratch {
  std::vector<std::uint8_t> covered;
  std::vector<float> map;
};

ImageMeasure measure_image(const ShadedView& a, const ShadedView& b, core::view::GridSize grid,
                           std::span<const float> acuity_weights, ImageScratch& scratch);

// Normals for a simplification B of mesh A from A's: each vertex of B takes the normal of A's vertex
// at exactly the same position (a cut's vertices are the model's, copied bit for bit, whatever their
// numbering in B's file); the others get B's own area-weighted normal. Returns how many matched.
std::size_t normals_from_original(std::span<const float> a_positions, std::span<const float> a_normals,
                                  std::span<const float> b_positions,
                                  std::span<const std::uint32_t> b_triangles, std::vector<float>& b_normals);

// Focus point of a view: the centroid of the original's mask, moved to the nearest covered pixel
// when the centroid falls outside it (normalised viewport coordinates).
std::array<float, 2> focus_point(std::span<const std::uint8_t> mask, core::view::GridSize grid);

// Size of the payload the server sends for a cut by default (core::DracoOptions{}: positions only).
std::size_t draco_payload_bytes(core::codec::DracoEncoder& encoder, std::span<const float> positions,
                                std::span<const std::uint32_t> triangles, std::vector<std::uint8_t>& payload);

// The acuity weights (core::foveation_weights) within near_deg of the focus, 0 beyond: a weight
// e2/(e2 + e) is at least e2/(e2 + near_deg) exactly there.
void near_weights(std::span<const float> acuity, double e2_deg, double near_deg, std::span<float> out);

// "WxH" or "N" (square).
bool parse_viewport(const std::string& text, core::view::GridSize& out);

}  // namespace mtlod::eval_tool
