#include "clients/tools/eval/gaze_study.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <deque>
#include <fstream>
#include <sstream>

#include "clients/common/extract_flags.hpp"
#include "clients/gaze/trace.hpp"
#include "clients/tools/eval/support.hpp"
#include "core/codec/draco_encode.hpp"
#include "core/cut/refine.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/view_extract.hpp"
#include "fmt/format.h"

namespace mtlod::eval_tool {

namespace {

using namespace mtlod::core;
namespace fs = std::filesystem;

// One cut's rendering compared with the original's: the SSIM map and the pixels either covers, from
// which any weighting's score follows.
struct ScoredCut {
  std::size_t sample = 0;  // the gaze sample it was made for
  std::size_t bytes = 0, triangles = 0;
  std::vector<float> map;
  std::vector<std::uint8_t> covered;
};

struct Scorer {
  view::GridSize grid;
  ShadedView reference, cut;

  void score(const ShadedModel& m, const view::ViewMapping& image, std::span<const std::uint32_t> triangles,
             ScoredCut& out) {
    render_shaded(image, m.mt.positions, triangles, m.mt_normals, cut);
    out.covered.resize(grid.cell_count());
    for (std::size_t c = 0; c < out.covered.size(); ++c)
      out.covered[c] = std::isfinite(reference.depth[c]) || std::isfinite(cut.depth[c]);
    out.map.resize(eval::ssim_map_size(grid).cell_count());
    eval::ssim(reference.luminance, cut.luminance, grid, out.map);
    out.triangles = triangles.size() / 3;
  }

  // 1 − SSIM over the covered windows, weighted.
  double error(const ScoredCut& c, std::span<const float> weights) const {
    return 1.0 - eval::weighted_ssim(c.map, grid, {c.covered, weights});
  }
};

// The default criteria's budgeted cut for a focus (the budget alone decides the size: the bound is
// far below what any cut reaches, as in FIDELITY.md).
void default_cut(view::ViewExtractor& extractor, cut::Refiner& refiner, const view::Camera& camera,
                 view::GridSize grid, std::array<float, 2> focus, std::size_t budget, cut::CutMesh& out) {
  view::ViewRequest r;
  r.camera = camera;
  r.grid = grid;
  r.allowed.units = view::ErrorUnits::kScreenPixels;
  r.allowed.error = 1e-6f;
  r.allowed.criteria[view::kGazeCriterion] =
      view::RegionLaw{view::FalloffLaw::kFoveal, 0.0f, 1.0f, 16.0f, 2.3f};
  r.allowed.outside_view_factor = 8.0f;
  r.allowed.hidden_factor = static_cast<float>(clients::kDefaultHiddenFactor);
  r.points[view::kGazeCriterion] = {focus};
  r.budget = budget;
  r.dynamic = false;
  out.assign(must(extractor.extract(r, refiner, out)));
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(p * double(v.size() - 1) + 0.5))];
}

struct Frame {
  double time_ms = 0;
  std::size_t shown = 0;  // the sample whose cut is on screen
  std::size_t bytes = 0;
  double error = 0, near_error = 0;                  // gaze-driven, around the eye's position now
  double uniform_error = 0, uniform_near_error = 0;  // the uniform cut, the same weights
};

struct Recovery {
  std::size_t saccades = 0, measured = 0, unsettled = 0;
  std::vector<double> ms;
};

struct LatencyResult {
  double latency_ms = 0;
  std::vector<Frame> frames;
  Recovery recovery;
};

struct MeshResult {
  std::string name;
  std::size_t uniform_bytes = 0, uniform_triangles = 0;
  std::vector<LatencyResult> latencies;
};

}  // namespace

int run_gaze_study(const GazeStudyOptions& o, const std::string& command) {
  const auto start = Clock::now();
  if (o.meshes.empty())
    return fmt::print(stderr, "mtlod-eval: gaze needs at least one --mesh NAME=PATH\n"), 2;
  if (o.latencies_ms.empty() || !std::all_of(o.latencies_ms.begin(), o.latencies_ms.end(),
                                             [](double l) { return l >= 0 && std::isfinite(l); }))
    return fmt::print(stderr, "mtlod-eval: --latencies must be non-negative milliseconds\n"), 2;
  std::vector<clients::GazeSample> trace;
  if (!o.trace.empty()) {
    std::ifstream in(o.trace);
    std::stringstream text;
    text << in.rdbuf();
    if (!in) return fmt::print(stderr, "mtlod-eval: cannot read {}\n", o.trace), 1;
    auto parsed = clients::parse_gaze_trace(text.str());
    if (!parsed) return fmt::print(stderr, "mtlod-eval: {}: {}\n", o.trace, parsed.error().message), 2;
    trace = std::move(*parsed);
  } else {
    // Fixations and saccades only: the study measures the recovery after saccades. The view is the
    // square orbit image, kOrbitFovDeg across.
    clients::SynthesisOptions s;
    s.rate_hz = o.hz, s.duration_ms = o.duration_ms, s.seed = o.seed;
    s.screen_deg = kOrbitFovDeg, s.aspect = 1, s.pursuit_share = 0, s.blink_share = 0;
    trace = clients::synthesize_gaze_trace(s);
  }
  // Samples where the tracker lost the eye (blinks) move no focus: the cut stays what it was.
  std::erase_if(trace, [](const clients::GazeSample& s) { return !s.tracked; });
  if (trace.size() < 2) return fmt::print(stderr, "mtlod-eval: the trace needs at least two samples\n"), 2;

  const view::GridSize grid{o.image_px, o.image_px}, dt_grid{o.grid_px, o.grid_px};
  const double focal_px = eval::focal_px_from_fov(o.image_px, kOrbitFovDeg);
  const auto pixel = [&](const clients::GazeSample& s) {
    return std::array<double, 2>{s.x * o.image_px, s.y * o.image_px};
  };
  // I-VT: a sample is in a saccade when the eye moved faster than the threshold since the previous.
  std::vector<std::uint8_t> in_saccade(trace.size(), 0);
  for (std::size_t k = 1; k < trace.size(); ++k) {
    eval::Foveation f;
    f.focal_px = focal_px;
    const auto a = pixel(trace[k - 1]), b = pixel(trace[k]);
    f.focus_x_px = float(a[0]), f.focus_y_px = float(a[1]);
    const double dt = std::max(1e-6, trace[k].time_ms - trace[k - 1].time_ms) / 1000.0;
    in_saccade[k] = eval::pixel_eccentricity_deg(grid, f, b[0], b[1]) / dt > o.saccade_deg_per_s;
  }
  // Fixations after saccades: [end, next start) in sample indices.
  std::vector<std::pair<std::size_t, std::size_t>> fixations;
  for (std::size_t k = 1; k < trace.size(); ++k) {
    if (!(in_saccade[k - 1] && !in_saccade[k])) continue;
    std::size_t next = k;
    while (next < trace.size() && !in_saccade[next]) ++next;
    fixations.push_back({k, next});
  }

  std::vector<MeshResult> results;
  std::string csv =
      "mesh,latency_ms,frame,time_ms,gaze_x,gaze_y,shown_sample,bytes,foveated_error,near_error,"
      "uniform_foveated_error,uniform_near_error\n";
  for (const std::string& spec : o.meshes) {
    const auto mesh_start = Clock::now();
    auto loaded = load_shaded_model(spec, o.cache_dir);
    if (!loaded) return fmt::print(stderr, "mtlod-eval: {}\n", loaded.error().message), 1;
    ShadedModel& model = **loaded;
    if (o.budget <= model.mt.root_triangle_count() || o.budget > model.mesh.triangle_count())
      return fmt::print(stderr, "mtlod-eval: {}: --budget {} is outside the MT's {}..{} triangles\n",
                        model.name, o.budget, model.mt.root_triangle_count(), model.mesh.triangle_count()),
             2;
    const std::unique_ptr<view::OccupancyLevels> levels = must(view::OccupancyLevels::make(model.mt));
    view::ViewExtractor extractor(model.mt, *levels);
    cut::Refiner refiner(model.mt);
    codec::DracoEncoder encoder;
    std::vector<std::uint8_t> payload;
    cut::CutMesh cut;
    const view::Camera camera = orbit_camera(model.bounds, 0, 8);
    const view::ViewMapping image(camera, grid);
    Scorer scorer;
    scorer.grid = grid;
    render_shaded(image, model.mesh.positions, model.mesh.triangles, model.normals, scorer.reference);

    // The gaze-driven cuts, one per sample, scored once; frames read them through the latency.
    std::vector<ScoredCut> cuts(trace.size());
    std::size_t bytes_sum = 0;
    for (std::size_t k = 0; k < trace.size(); ++k) {
      default_cut(extractor, refiner, camera, dt_grid, {float(trace[k].x), float(trace[k].y)}, o.budget, cut);
      scorer.score(model, image, cut.triangles, cuts[k]);
      cuts[k].sample = k;
      cuts[k].bytes = draco_payload_bytes(encoder, model.mt.positions, cut.triangles, payload);
      bytes_sum += cuts[k].bytes;
    }
    // The uniform cut of the same mean bytes (secant steps on its triangle count).
    const double target_bytes = double(bytes_sum) / double(trace.size());
    ScoredCut uniform;
    {
      std::size_t n = o.budget, best_bytes = 0;
      cut::CutMesh best;
      for (int step = 0; step < 8; ++step) {
        must(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(n), cut));
        const std::size_t bytes = draco_payload_bytes(encoder, model.mt.positions, cut.triangles, payload);
        if (best_bytes == 0 ||
            std::abs(double(bytes) - target_bytes) < std::abs(double(best_bytes) - target_bytes))
          best_bytes = bytes, best = cut;
        if (bytes == 0 || std::abs(double(bytes) - target_bytes) <= 0.005 * target_bytes) break;
        const auto next = std::clamp<std::size_t>(
            std::size_t(std::llround(double(cut.triangle_count()) * target_bytes / double(bytes))), 1,
            model.mesh.triangle_count());
        if (next == n) break;
        n = next;
      }
      scorer.score(model, image, best.triangles, uniform);
      uniform.bytes = best_bytes;
    }

    MeshResult result;
    result.name = model.name;
    result.uniform_bytes = uniform.bytes, result.uniform_triangles = uniform.triangles;
    for (const double latency : o.latencies_ms) result.latencies.push_back({latency, {}, {}});
    std::vector<float> weights(grid.cell_count()), near(grid.cell_count());
    for (std::size_t k = 0; k < trace.size(); ++k) {
      // The eye is at sample k now: acuity weights around it, and the same within near_deg only.
      eval::Foveation f;
      f.focal_px = focal_px;
      const auto eye = pixel(trace[k]);
      f.focus_x_px = float(eye[0]), f.focus_y_px = float(eye[1]);
      eval::foveation_weights(grid, f, weights);
      near_weights(weights, f.e2_deg, o.near_deg, near);
      const double uniform_error = scorer.error(uniform, weights), uniform_near = scorer.error(uniform, near);
      for (LatencyResult& l : result.latencies) {
        // On screen: the cut of the newest sample that had reached the viewer latency ms ago.
        const double seen = trace[k].time_ms - l.latency_ms;
        if (seen < trace.front().time_ms) continue;
        std::size_t shown = k;
        while (trace[shown].time_ms > seen) --shown;
        Frame frame{trace[k].time_ms,
                    shown,
                    cuts[shown].bytes,
                    scorer.error(cuts[shown], weights),
                    scorer.error(cuts[shown], near),
                    uniform_error,
                    uniform_near};
        l.frames.push_back(frame);
        csv += fmt::format("{},{},{},{:.3f},{:.4f},{:.4f},{},{},{:.6f},{:.6f},{:.6f},{:.6f}\n", model.name,
                           l.latency_ms, k, frame.time_ms, trace[k].x, trace[k].y, shown, frame.bytes,
                           frame.error, frame.near_error, frame.uniform_error, frame.uniform_near_error);
      }
    }
    // Recovery after each saccade: frames of the fixation that follows, the settled error the median
    // of those from 50 ms past the largest latency on.
    const double longest = *std::max_element(o.latencies_ms.begin(), o.latencies_ms.end());
    for (LatencyResult& l : result.latencies) {
      for (const auto& [first, end] : fixations) {
        ++l.recovery.saccades;
        const double t0 = trace[first].time_ms;
        std::vector<const Frame*> frames;
        std::vector<double> settled;
        for (const Frame& fr : l.frames) {
          if (fr.time_ms < t0 || fr.time_ms >= (end < trace.size() ? trace[end].time_ms : INFINITY)) continue;
          frames.push_back(&fr);
          if (fr.time_ms >= t0 + longest + 50.0) settled.push_back(fr.near_error);
        }
        if (settled.size() < 3) continue;
        ++l.recovery.measured;
        const double bound = (1.0 + o.settle_tolerance) * percentile(settled, 0.5);
        const auto back = std::find_if(frames.begin(), frames.end(),
                                       [&](const Frame* fr) { return fr->near_error <= bound; });
        if (back == frames.end())
          ++l.recovery.unsettled;
        else
          l.recovery.ms.push_back((*back)->time_ms - t0);
      }
    }
    fmt::print("{}: {} samples, {} fixations after saccades, in {:.1f} s; uniform cut {} bytes\n", model.name,
               trace.size(), fixations.size(), seconds_since(mesh_start), result.uniform_bytes);
    for (const LatencyResult& l : result.latencies) {
      double err = 0, uerr = 0, near_err = 0, unear = 0, bytes = 0;
      for (const Frame& f : l.frames)
        err += f.error, uerr += f.uniform_error, near_err += f.near_error, unear += f.uniform_near_error,
            bytes += double(f.bytes);
      const double n = std::max<double>(1, double(l.frames.size()));
      fmt::print(
          "  latency {} ms: {} frames, {:.0f} bytes, foveated error {:.2f}x lower than uniform's, near the "
          "fixation {:.2f}x, recovery median {} ms\n",
          l.latency_ms, l.frames.size(), bytes / n, uerr / std::max(1e-12, err),
          unear / std::max(1e-12, near_err),
          l.recovery.ms.empty() ? std::string("-") : fmt::format("{:.0f}", percentile(l.recovery.ms, 0.5)));
    }
    results.push_back(std::move(result));
    std::fflush(stdout);
  }

  // The report.
  std::string md = "# A gaze study: gaze-driven cuts against a uniform cut of the same bytes\n\n";
  md += fmt::format("Generated by `{}` in {:.0f} s. Do not edit by hand.\n\n## Setup\n\n", command,
                    seconds_since(start));
  md += fmt::format(
      "- Trace: {} ({} samples over {:.0f} ms). Frames: one per sample, the display running at the trace's "
      "rate.\n",
      o.trace.empty() ? fmt::format("synthesised by mtlod-gaze's generator (seed {}, {} Hz; fixations of "
                                    "150–400 ms, main-sequence saccades of 1–15°, no pursuit or blinks)",
                                    o.seed, o.hz)
                      : "`" + o.trace + "`",
      trace.size(), trace.back().time_ms - trace.front().time_ms);
  md += fmt::format(
      "- View: camera 0 of FIDELITY.md's orbit ({}×{} image, {}° field of view), the eye at the centre of "
      "projection.\n",
      o.image_px, o.image_px, kOrbitFovDeg);
  md += fmt::format(
      "- Gaze-driven: every sample's cut with the clients' default criteria (`--falloff foveal --focus "
      "X,Y,0,1 --hidden-factor 16`, "
      "the bound growing ×(1 + e/2.3°) from the gaze, hidden surfaces coarsened) and a budget of {} "
      "triangles; the frame at time t "
      "shows "
      "the cut of the newest sample from before t − latency. Uniform: one cut, one allowed error everywhere, "
      "whose Draco payload matches the gaze-driven cuts' mean.\n",
      o.budget);
  md += fmt::format(
      "- Scores per frame, around where the eye is at that frame: the foveated error (1 − foveated SSIM, "
      "acuity weights e2/(e2 + e), FIDELITY.md) and the error near the fixation (the same within {}° of the "
      "gaze).\n",
      o.near_deg);
  md += fmt::format(
      "- Saccades: I-VT (Salvucci and Goldberg 2000), samples faster than {}°/s. Recovery: the time from a "
      "saccade's end until the error near the new fixation is back within {:.0f} % of its settled value (the "
      "median over the fixation's frames from {:.0f} ms on); fixations too short to settle are left out. "
      "Gaze-contingent displays go unnoticed when they update within about 60 ms of a saccade's end "
      "(Loschky and Wolverton 2007) and tolerate 50–70 ms of latency in foveated rendering (Albert et al. "
      "2017).\n",
      o.saccade_deg_per_s, 100 * o.settle_tolerance,
      *std::max_element(o.latencies_ms.begin(), o.latencies_ms.end()) + 50.0);
  md +=
      "- Latencies: 0 (ideal), 8 ms (one 120 Hz frame, about the gaze-to-mesh p99 of BENCHMARKS.md's "
      "default-criteria row), 16 ms (two frames), 50 ms (a distant server).\n";
  for (const std::string& n : o.notes) md += "- " + n + "\n";
  md +=
      "\n## Results\n\n| mesh | latency ms | frames | bytes gaze-driven / uniform | foveated error "
      "gaze-driven / "
      "uniform | frames better | near the fixation gaze-driven / uniform | saccades (measured) | recovery ms "
      "median / p90 / max |\n| --- | ---: | ---: | --- | --- | ---: | --- | ---: | --- |\n";
  for (const MeshResult& r : results) {
    for (const LatencyResult& l : r.latencies) {
      double bytes = 0, err = 0, uerr = 0, near_err = 0, unear = 0;
      std::size_t better = 0;
      for (const Frame& f : l.frames) {
        bytes += double(f.bytes), err += f.error, uerr += f.uniform_error, near_err += f.near_error,
            unear += f.uniform_near_error, better += f.error < f.uniform_error;
      }
      const double n = std::max<double>(1, double(l.frames.size()));
      std::string recovery = "–";
      if (!l.recovery.ms.empty())
        recovery = fmt::format("{:.0f} / {:.0f} / {:.0f}", percentile(l.recovery.ms, 0.5),
                               percentile(l.recovery.ms, 0.9), percentile(l.recovery.ms, 1.0));
      if (l.recovery.unsettled) recovery += fmt::format(" ({} never back)", l.recovery.unsettled);
      md += fmt::format(
          "| {} | {:.0f} | {} | {:.0f} / {} | {:.4f} / {:.4f} ({:.2f}×) | {}/{} | {:.4f} / {:.4f} ({:.2f}×) "
          "| "
          "{} ({}) | {} |\n",
          r.name, l.latency_ms, l.frames.size(), bytes / n, r.uniform_bytes, err / n, uerr / n,
          (uerr / n) / std::max(1e-12, err / n), better, l.frames.size(), near_err / n, unear / n,
          (unear / n) / std::max(1e-12, near_err / n), l.recovery.saccades, l.recovery.measured, recovery);
    }
  }
  md += fmt::format("\nRaw numbers for every frame: [`{}`]({}).\n", o.csv, o.csv);
  const fs::path out_dir = o.out_dir;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  for (const auto& [file, text] : {std::pair{out_dir / o.csv, csv}, std::pair{out_dir / o.report, md}}) {
    std::FILE* f = std::fopen(file.c_str(), "wb");
    const bool ok = f && std::fwrite(text.data(), 1, text.size(), f) == text.size();
    if (f) std::fclose(f);
    if (!ok) return fmt::print(stderr, "mtlod-eval: cannot write {}\n", file.string()), 1;
  }
  fmt::print("wrote {} in {:.1f} s\n", (out_dir / o.report).string(), seconds_since(start));
  return 0;
}

}  // namespace mtlod::eval_tool
