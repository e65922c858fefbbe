// Gaze traces (CSV reader, synthesiser) and the load tester's workload parsers.
#include "clients/gaze/trace.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "clients/load/workload.hpp"

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
      {"0,nan,0.5\n1,0.5,0.5\n4,inf,0\n", "line 3"},
  };
  for (const auto& c : cases) {
    auto trace = parse_gaze_trace(c.text);
    ASSERT_FALSE(trace.ok()) << c.text;
    EXPECT_NE(trace.error().message.find(c.message), std::string::npos) << trace.error().message;
  }
}

TEST(GazeTrace, ExampleTraceIsValid) {
  std::ifstream in(std::string(MTLOD_SOURCE_DIR) + "/clients/gaze/example-trace.csv");
  std::stringstream text;
  text << in.rdbuf();
  auto trace = parse_gaze_trace(text.str());
  ASSERT_TRUE(trace.ok()) << trace.error().message;
  EXPECT_GE(trace->size(), 200u);
}

TEST(GazeTrace, SynthesisHasTheRateLengthAndRange) {
  // 250 Hz for 2 s: samples at 0, 4, ..., 1996 ms.
  SynthesisOptions o;
  o.rate_hz = 250;
  o.duration_ms = 2000;
  const auto trace = synthesize_gaze_trace(o);
  ASSERT_EQ(trace.size(), 500u);
  for (std::size_t i = 0; i < trace.size(); ++i) {
    ASSERT_NEAR(trace[i].time_ms, 4.0 * static_cast<double>(i), 1e-9);
    ASSERT_GE(trace[i].x, 0);
    ASSERT_LE(trace[i].x, 1);
    ASSERT_GE(trace[i].y, 0);
    ASSERT_LE(trace[i].y, 1);
  }
}

TEST(GazeTrace, SynthesisHasFixationsAndSaccades) {
  // Compare each sample with the one 50 ms later. Within a fixation they differ by jitter only
  // (σ 0.002 per axis: 0.02 is seven standard deviations of the difference); across a saccade by
  // its length. Over 10 s of 150..400 ms fixations most windows are still and there are at least
  // ten separate moving episodes (about 30 expected; short saccades under 0.05 are not counted).
  SynthesisOptions o;
  o.rate_hz = 1000;
  const auto trace = synthesize_gaze_trace(o);
  ASSERT_EQ(trace.size(), 10000u);
  std::size_t still = 0, episodes = 0;
  bool moving = false;
  for (std::size_t i = 0; i + 50 < trace.size(); ++i) {
    const double d = std::hypot(trace[i + 50].x - trace[i].x, trace[i + 50].y - trace[i].y);
    still += d < 0.02;
    if (d > 0.05 && !moving) ++episodes;
    moving = d > 0.05 ? true : (d < 0.02 ? false : moving);
  }
  EXPECT_GT(still, trace.size() / 2);
  EXPECT_GE(episodes, 10u);
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
