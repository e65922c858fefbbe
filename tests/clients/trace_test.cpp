// Gaze traces (CSV reader, trace files, synthesiser) and the load tester's workload parsers.
#include "clients/gaze/trace.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>

#include "clients/gaze/trace_file.hpp"
#include "clients/load/workload.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::clients {
namespace {

TEST(GazeTrace, ReadsHeaderCommentsAndCrlf) {
  auto trace = parse_gaze_trace("time_ms,x,y\r\n# a comment\n0,0.5,0.5\r\n\n8.3, 0.25 ,1\n16.6,0,0\n");
  ASSERT_TRUE(trace.ok()) << trace.error().message;
  ASSERT_EQ(trace->size(), 3u);
  EXPECT_EQ((*trace)[1].time_ms, 8.3);
  EXPECT_EQ((*trace)[1].x, 0.25);
  EXPECT_EQ((*trace)[1].y, 1.0);
}

TEST(GazeTrace, RejectsBadLinesNamingThem) {
  const struct {
    const char* text;
    const char* message;
  } cases[] = {
      {"0,0.5,0.5\n5,1.5,0.5\n", "line 2: x and y must lie in 0..1"},
      {"0,0.5,0.5\n5,0.5\n", "line 2: expected time_ms,x,y"},
      {"0,0.5,0.5\n5,0.5,0.5,7\n", "line 2: expected time_ms,x,y"},
      {"10,0.5,0.5\n5,0.5,0.5\n", "line 2: time 5 ms goes backwards"},
      {"0,0.5,0.5\nx,y,z\n", "line 2: expected"},
      {"time_ms,x,y\n", "no sample"},
      {"0,0.5,0.5\n1,0.5,0.5\n4,inf,0\n", "line 3: expected"},
      {"0,nan,0.5\n", "line 1: x and y must both be numbers, or both empty or nan"},
      {"0,0.5,0.5\n5,,0.5\n", "line 2: x and y must both"},
      {"0,0.5,0.5\nnan,0.5,0.5\n", "line 2: expected"},
      {"0,0.5,0.5\n5,,\n4,,\n", "line 3: time 4 ms goes backwards"},
      {"0,,\n5,nan,nan\n", "no sample with a gaze"},
  };
  for (const auto& c : cases) {
    auto trace = parse_gaze_trace(c.text);
    ASSERT_FALSE(trace.ok()) << c.text;
    EXPECT_NE(trace.error().message.find(c.message), std::string::npos) << trace.error().message;
  }
}

TEST(GazeTrace, ReadsLostSamplesInBothForms) {
  auto trace = parse_gaze_trace("time_ms,x,y\n0,0.5,0.5\n5,,\n10,nan,nan\n15, NaN , NAN \n20,0.25,0.75\n");
  ASSERT_TRUE(trace.ok()) << trace.error().message;
  ASSERT_EQ(trace->size(), 5u);
  EXPECT_TRUE((*trace)[0].tracked);
  for (std::size_t i = 1; i <= 3; ++i) EXPECT_FALSE((*trace)[i].tracked) << i;
  EXPECT_TRUE((*trace)[4].tracked);
  EXPECT_EQ((*trace)[3].time_ms, 15.0);
  EXPECT_EQ((*trace)[4].x, 0.25);
  EXPECT_EQ(format_gaze_sample((*trace)[1]), "5.000,,");
  EXPECT_EQ(format_gaze_sample((*trace)[4]), "20.000,0.25000,0.75000");
}

TEST(GazeTrace, ExampleTraceIsValid) {
  std::ifstream in(std::string(MTLOD_SOURCE_DIR) + "/clients/gaze/example-trace.csv");
  std::stringstream text;
  text << in.rdbuf();
  auto trace = parse_gaze_trace(text.str());
  ASSERT_TRUE(trace.ok()) << trace.error().message;
  EXPECT_GE(trace->size(), 200u);
}

// ---- Synthesis: properties measured from the samples, as a tracker's analysis would ----

// Speeds in degrees per second of visual angle, over windows of samples (SynthesisOptions' screen).
class Motion {
 public:
  Motion(const std::vector<GazeSample>& trace, const SynthesisOptions& o)
      : trace_(trace), width_deg_(o.screen_deg), height_deg_(o.screen_deg / o.aspect) {
    lost_before_.push_back(0);
    for (const auto& s : trace) lost_before_.push_back(lost_before_.back() + !s.tracked);
  }

  // The velocity over samples [i - half, i + half], or none when one of them is lost or missing.
  std::optional<std::array<double, 2>> velocity(std::size_t i, std::size_t half) const {
    if (i < half || i + half >= trace_.size() || lost_before_[i + half + 1] != lost_before_[i - half])
      return {};
    const GazeSample &a = trace_[i - half], &b = trace_[i + half];
    const double seconds = (b.time_ms - a.time_ms) / 1000;
    return std::array<double, 2>{(b.x - a.x) * width_deg_ / seconds, (b.y - a.y) * height_deg_ / seconds};
  }
  std::optional<double> speed(std::size_t i, std::size_t half) const {
    const auto v = velocity(i, half);
    if (!v) return {};
    return std::hypot((*v)[0], (*v)[1]);
  }

 private:
  const std::vector<GazeSample>& trace_;
  const double width_deg_, height_deg_;
  std::vector<std::size_t> lost_before_;
};

// Maximal runs [first, last] of indices where `in(i)` holds.
template <typename Predicate>
std::vector<std::pair<std::size_t, std::size_t>> runs(std::size_t n, Predicate in) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (std::size_t i = 0; i < n; ++i) {
    if (!in(i)) continue;
    std::size_t j = i;
    while (j + 1 < n && in(j + 1)) ++j;
    out.push_back({i, j});
    i = j;
  }
  return out;
}

// At 1000 Hz: saccades are samples faster than 60°/s over 10 ms (the noise is far below: jitter
// 0.03° gives about 4°/s); pursuit is 4..35°/s over 100 ms (jitter about 0.4°/s, fixational drift
// under 1°/s) with no saccade within that window, lasting 250 ms or more. A pursuit's first and last
// window (100 ms) blend in what comes before and after.
struct Episodes {
  std::vector<double> saccade_peaks;                          // °/s
  std::vector<std::pair<std::size_t, std::size_t>> pursuits;  // their steady parts, [first, last]
};

Episodes episodes(const std::vector<GazeSample>& trace, const Motion& motion) {
  constexpr std::size_t kShort = 5, kLong = 50;
  const std::size_t n = trace.size();
  std::vector<std::size_t> fast_before{0};
  for (std::size_t i = 0; i < n; ++i)
    fast_before.push_back(fast_before.back() + (motion.speed(i, kShort) > 60.0));
  Episodes e;
  for (const auto& [first, last] : runs(n, [&](std::size_t i) { return motion.speed(i, kShort) > 60.0; })) {
    double peak = 0;
    for (std::size_t i = first; i <= last; ++i) peak = std::max(peak, *motion.speed(i, kShort));
    e.saccade_peaks.push_back(peak);
  }
  const auto slow = [&](std::size_t i) {
    const auto v = motion.speed(i, kLong);
    return v && *v >= 4 && *v <= 35 && fast_before[i + kLong + 1] == fast_before[i - kLong];
  };
  for (const auto& run : runs(n, slow)) {
    if (run.second - run.first >= 250) e.pursuits.push_back({run.first + 100, run.second - 100});
  }
  return e;
}

TEST(GazeSynthesis, SamplesAreSpacedAtTheRate) {
  for (const double hz : {60.0, 120.0, 250.0, 1000.0}) {
    SynthesisOptions o;
    o.rate_hz = hz;
    o.duration_ms = 3000;
    const auto trace = synthesize_gaze_trace(o);
    const double step = 1000 / hz;
    ASSERT_FALSE(trace.empty());
    EXPECT_EQ(trace.front().time_ms, 0);
    for (std::size_t i = 1; i < trace.size(); ++i)
      ASSERT_NEAR(trace[i].time_ms - trace[i - 1].time_ms, step, 1e-9) << hz << " Hz, sample " << i;
    EXPECT_LT(trace.back().time_ms, o.duration_ms);
    EXPECT_GE(trace.back().time_ms + step, o.duration_ms - 1e-9) << hz;
  }
}

TEST(GazeSynthesis, EveryTrackedSampleLiesInTheViewport) {
  // Edge cases too: pursuit after every fixation, a narrow screen, wide amplitudes.
  for (const double hz : {60.0, 250.0, 1000.0}) {
    for (std::uint64_t seed = 1; seed <= 4; ++seed) {
      SynthesisOptions o;
      o.rate_hz = hz;
      o.duration_ms = 20'000;
      o.seed = seed;
      if (seed == 2) o.pursuit_share = 1, o.blink_share = 0;
      if (seed == 3) o.aspect = 0.5, o.saccade_max_deg = 40;
      const auto trace = synthesize_gaze_trace(o);
      ASSERT_TRUE(trace.front().tracked);
      for (const auto& s : trace) {
        if (!s.tracked) continue;
        ASSERT_TRUE(s.x >= 0 && s.x <= 1 && s.y >= 0 && s.y <= 1) << s.time_ms << ": " << s.x << ", " << s.y;
      }
    }
  }
}

TEST(GazeSynthesis, BlinksLoseTheEyeFor100To400Ms) {
  // A run of lost samples lasts from its first sample to the next tracked one: the blink's length
  // to within a sample period. The last run may be cut by the trace's end.
  for (const double hz : {60.0, 250.0, 1000.0}) {
    SynthesisOptions o;
    o.rate_hz = hz;
    o.duration_ms = 60'000;
    o.seed = 5;
    const auto trace = synthesize_gaze_trace(o);
    const double step = 1000 / hz;
    const auto blinks = runs(trace.size(), [&](std::size_t i) { return !trace[i].tracked; });
    EXPECT_GE(blinks.size(), 5u) << hz;
    for (const auto& [first, last] : blinks) {
      if (last + 1 == trace.size()) continue;
      const double ms = trace[last + 1].time_ms - trace[first].time_ms;
      EXPECT_GE(ms, 100 - step) << hz << " Hz, at " << trace[first].time_ms;
      EXPECT_LE(ms, 400 + step) << hz << " Hz, at " << trace[first].time_ms;
    }
  }
}

TEST(GazeSynthesis, PursuitMovesAtANearConstantVelocity) {
  // Targets move at 5..30°/s; the eye follows at a gain a little below 1 (catch-up saccades make
  // up the rest), so the eye's pursuit speed lies a little below that range at its low end. A
  // pursuit's velocity stays within 2.5°/s of its mean: over 100 ms the noise is about 0.4°/s per
  // axis.
  SynthesisOptions o;
  o.rate_hz = 1000;
  o.duration_ms = 60'000;
  o.seed = 11;
  const auto trace = synthesize_gaze_trace(o);
  const Motion motion(trace, o);
  const Episodes e = episodes(trace, motion);
  EXPECT_GE(e.pursuits.size(), 5u);
  for (const auto& [first, last] : e.pursuits) {
    std::array<double, 2> mean{0, 0};
    std::size_t count = 0;
    for (std::size_t i = first; i <= last; ++i, ++count) {
      const auto v = *motion.velocity(i, 50);
      mean[0] += v[0], mean[1] += v[1];
    }
    mean[0] /= static_cast<double>(count), mean[1] /= static_cast<double>(count);
    const double speed = std::hypot(mean[0], mean[1]);
    EXPECT_GE(speed, 0.9 * 5) << "pursuit at " << trace[first].time_ms << " ms";
    EXPECT_LE(speed, 30 * 1.05) << "pursuit at " << trace[first].time_ms << " ms";
    for (std::size_t i = first; i <= last; ++i) {
      const auto v = *motion.velocity(i, 50);
      ASSERT_LE(std::hypot(v[0] - mean[0], v[1] - mean[1]), 2.5)
          << "at " << trace[i].time_ms << " ms in the pursuit from " << trace[first].time_ms << " ms";
    }
  }
}

TEST(GazeSynthesis, SaccadesPeakFarAbovePursuitSpeeds) {
  // Main-sequence saccades of 1..15° peak at about 80..500°/s; pursuit stays at 30°/s or less.
  SynthesisOptions o;
  o.rate_hz = 1000;
  o.duration_ms = 60'000;
  o.seed = 11;
  const auto trace = synthesize_gaze_trace(o);
  const Motion motion(trace, o);
  Episodes e = episodes(trace, motion);
  ASSERT_GE(e.saccade_peaks.size(), 30u);
  double pursuit_max = 0;
  for (const auto& [first, last] : e.pursuits) {
    for (std::size_t i = first; i <= last; ++i) pursuit_max = std::max(pursuit_max, *motion.speed(i, 50));
  }
  ASSERT_GT(pursuit_max, 0);
  std::sort(e.saccade_peaks.begin(), e.saccade_peaks.end());
  const double median = e.saccade_peaks[e.saccade_peaks.size() / 2];
  EXPECT_GT(median, 5 * pursuit_max);
  EXPECT_GT(e.saccade_peaks.back(), 10 * pursuit_max);
}

TEST(GazeSynthesis, IsDeterministicBySeed) {
  SynthesisOptions o;
  o.duration_ms = 5000;
  o.seed = 7;
  const auto a = synthesize_gaze_trace(o), b = synthesize_gaze_trace(o);
  o.seed = 8;
  const auto c = synthesize_gaze_trace(o);
  const auto same = [](const std::vector<GazeSample>& p, const std::vector<GazeSample>& q) {
    return p.size() == q.size() &&
           std::equal(p.begin(), p.end(), q.begin(), [](const auto& s, const auto& t) {
             return s.time_ms == t.time_ms && s.x == t.x && s.y == t.y && s.tracked == t.tracked;
           });
  };
  EXPECT_TRUE(same(a, b));
  EXPECT_FALSE(same(a, c));
}

TEST(GazeSynthesis, RejectsInconsistentOptions) {
  SynthesisOptions o;
  EXPECT_TRUE(check_synthesis_options(o).ok());
  o.pursuit_share = 0.7, o.blink_share = 0.5;
  auto checked = check_synthesis_options(o);
  ASSERT_FALSE(checked.ok());
  EXPECT_NE(checked.error().message.find("--pursuit-share"), std::string::npos) << checked.error().message;
  o = SynthesisOptions{};
  o.blink_min_ms = 500;
  EXPECT_FALSE(check_synthesis_options(o).ok());
}

// ---- Trace files ----

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

TEST(GazeTraceFile, WritesAndReadsBackLostSamples) {
  const auto dir = test::scratch_dir("gaze-trace-file");
  SynthesisOptions o;
  o.duration_ms = 20'000;
  const auto trace = synthesize_gaze_trace(o);
  ASSERT_TRUE(std::any_of(trace.begin(), trace.end(), [](const auto& s) { return !s.tracked; }));
  const auto path = (dir / "round.csv").string();
  ASSERT_TRUE(write_trace_file(path, trace).ok());
  EXPECT_NE(read_text(path).find(",,\n"), std::string::npos);  // the written form of a lost sample
  auto read = read_trace_file(path);
  ASSERT_TRUE(read.ok()) << read.error().message;
  ASSERT_EQ(read->size(), trace.size());
  for (std::size_t i = 0; i < trace.size(); ++i) {
    const GazeSample &a = trace[i], &b = (*read)[i];
    ASSERT_EQ(a.tracked, b.tracked) << i;
    ASSERT_NEAR(a.time_ms, b.time_ms, 5e-4) << i;
    if (!a.tracked) continue;
    ASSERT_NEAR(a.x, b.x, 5e-6) << i;
    ASSERT_NEAR(a.y, b.y, 5e-6) << i;
  }
}

TEST(GazeTraceFile, ReadsFilesAndFoldersInOrder) {
  // A folder gives its *.csv files in name order; other files and folders in it are ignored.
  const auto dir = test::scratch_dir("gaze-trace-folder");
  std::filesystem::create_directories(dir / "set" / "nested.csv");
  write_text(dir / "set" / "b.csv", "0,0.2,0.2\n5,,\n");
  write_text(dir / "set" / "a.csv", "time_ms,x,y\n0,0.1,0.1\n");
  write_text(dir / "set" / "c.csv", "0,0.3,0.3\n1,0.3,0.3\n2,0.3,0.3\n");
  write_text(dir / "set" / "notes.txt", "not a trace\n");
  write_text(dir / "single.csv", "0,0.9,0.9\n1,nan,nan\n2,nan,nan\n3,0.9,0.9\n");
  auto traces = read_trace_files({(dir / "single.csv").string(), (dir / "set").string()});
  ASSERT_TRUE(traces.ok()) << traces.error().message;
  ASSERT_EQ(traces->size(), 4u);
  EXPECT_EQ((*traces)[0].size(), 4u);
  EXPECT_EQ((*traces)[1].size(), 1u);
  EXPECT_EQ((*traces)[1][0].x, 0.1);
  EXPECT_EQ((*traces)[2].size(), 2u);
  EXPECT_EQ((*traces)[3].size(), 3u);
  auto none = read_trace_files({});
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->empty());
}

TEST(GazeTraceFile, ErrorsNameTheFolderFileAndLine) {
  const auto dir = test::scratch_dir("gaze-trace-errors");
  std::filesystem::create_directories(dir / "empty");
  write_text(dir / "empty" / "readme.txt", "no traces here\n");
  write_text(dir / "bad.csv", "time_ms,x,y\n0,0.5,0.5\n5,0.5\n");
  const struct {
    std::filesystem::path path;
    std::string message;
  } cases[] = {
      {dir / "empty", (dir / "empty").string() + ": no .csv trace"},
      {dir / "missing.csv", (dir / "missing.csv").string() + ": cannot read"},
      {dir / "bad.csv", (dir / "bad.csv").string() + ": line 3: expected time_ms,x,y"},
  };
  for (const auto& c : cases) {
    auto traces = read_trace_files({c.path.string()});
    ASSERT_FALSE(traces.ok()) << c.path;
    EXPECT_NE(traces.error().message.find(c.message), std::string::npos) << traces.error().message;
  }
}

TEST(Workload, CameraScriptAndMix) {
  auto script = parse_camera_script("# eye, target, focus\n0,0,3,0,0,0\n1,2,3,0,0,0,0.25,0.75\n");
  ASSERT_TRUE(script.ok()) << script.error().message;
  ASSERT_EQ(script->size(), 2u);
  EXPECT_FALSE((*script)[0].has_focus);
  EXPECT_TRUE((*script)[1].has_focus);
  EXPECT_EQ((*script)[1].focus[1], 0.75);
  EXPECT_FALSE(parse_camera_script("0,0,3,0,0\n").ok());
  EXPECT_FALSE(parse_camera_script("0,0,3,0,0,0,2,0\n").ok());

  auto mix = parse_mix("extract=1,gaze=3");
  ASSERT_TRUE(mix.ok());
  EXPECT_EQ(mix->extract, 1);
  EXPECT_EQ(mix->gaze, 3);
  EXPECT_EQ(parse_mix("gaze=1")->extract, 0);
  EXPECT_FALSE(parse_mix("extract=0").ok());
  EXPECT_FALSE(parse_mix("teleport=1").ok());
  EXPECT_FALSE(parse_mix("gaze=-1").ok());
}

}  // namespace
}  // namespace mtlod::clients
