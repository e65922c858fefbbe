// Gaze traces (see trace.hpp).
#include "clients/gaze/trace.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <numbers>
#include <random>
#include <sstream>

#include "clients/common/extract_flags.hpp"
#include "fmt/format.h"

namespace mtlod::clients {
namespace {

// ---- Reading ----

// The fields of a CSV line, empty ones included ("5,," has three).
std::vector<std::string> split_fields(const std::string& line) {
  std::vector<std::string> fields(1);
  for (const char c : line) {
    if (c == ',')
      fields.emplace_back();
    else
      fields.back() += c;
  }
  return fields;
}

enum class Field { kNumber, kMissing, kBad };

// A field holds a finite number, nothing (empty or "nan": no gaze), or something else.
Field read_field(const std::string& text, double& value) {
  const auto first = text.find_first_not_of(" \t");
  if (first == std::string::npos) return Field::kMissing;
  std::string word = text.substr(first, text.find_last_not_of(" \t") + 1 - first);
  std::transform(word.begin(), word.end(), word.begin(), [](unsigned char c) { return std::tolower(c); });
  if (word == "nan") return Field::kMissing;
  std::vector<double> v;
  if (!parse_number_list(word, v) || v.size() != 1) return Field::kBad;
  value = v.front();
  return Field::kNumber;
}

// The sample on a line, or why the line is not one. `timed` tells whether it starts with a time.
Result<GazeSample> read_sample(const std::string& line, bool& timed) {
  const std::vector<std::string> fields = split_fields(line);
  double v[3] = {0, 0, 0};
  Field kind[3] = {Field::kBad, Field::kBad, Field::kBad};
  for (std::size_t i = 0; i < std::min<std::size_t>(3, fields.size()); ++i)
    kind[i] = read_field(fields[i], v[i]);
  timed = kind[0] == Field::kNumber;
  if (fields.size() != 3 || !timed || kind[1] == Field::kBad || kind[2] == Field::kBad)
    return make_error(ErrorCode::kInvalidArgument, fmt::format("expected time_ms,x,y, got '{}'", line));
  if (kind[1] != kind[2]) {
    return make_error(
        ErrorCode::kInvalidArgument,
        fmt::format("x and y must both be numbers, or both empty or nan (no gaze), got '{}'", line));
  }
  if (kind[1] == Field::kMissing) return GazeSample{v[0], 0.5, 0.5, false};
  if (v[1] < 0 || v[1] > 1 || v[2] < 0 || v[2] > 1) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("x and y must lie in 0..1, got {}, {}", v[1], v[2]));
  }
  return GazeSample{v[0], v[1], v[2]};
}

// ---- Synthesis ----

// A point in degrees of visual angle, right of and below the viewport's top left corner; also a
// velocity in degrees per millisecond.
struct Point {
  double u = 0, v = 0;
};

Point operator+(Point a, Point b) {
  return {a.u + b.u, a.v + b.v};
}
Point operator-(Point a, Point b) {
  return {a.u - b.u, a.v - b.v};
}
Point operator*(Point a, double s) {
  return {a.u * s, a.v * s};
}
double length(Point a) {
  return std::hypot(a.u, a.v);
}

enum class Motion { kFixation, kSaccade, kPursuit, kBlink };

// [start_ms, end_ms) of the plan: a fixation or blink at `from`, or a move from `from` to `to`.
struct Segment {
  Motion motion;
  double start_ms, end_ms;
  Point from, to;
};

// The eye's motion without noise, from time 0 past the duration: fixations, each followed by a
// saccade to the next, smooth pursuit or a blink, as the shares draw.
class Planner {
 public:
  explicit Planner(const SynthesisOptions& o)
      : o_(o), rng_(o.seed), width_(o.screen_deg), height_(o.screen_deg / o.aspect) {}

  std::vector<Segment> plan() {
    Point at = box_point();
    while (now_ < o_.duration_ms) {
      add(Motion::kFixation, uniform(o_.fixation_min_ms, o_.fixation_max_ms), at, at);
      const double next = uniform(0, 1);
      if (next < o_.pursuit_share) {
        at = pursue(at);
      } else if (next < o_.pursuit_share + o_.blink_share) {
        add(Motion::kBlink, uniform(o_.blink_min_ms, o_.blink_max_ms), at, at);
      } else {
        at = saccade(at, saccade_target(at));
      }
    }
    return std::move(segments_);
  }

 private:
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }

  void add(Motion motion, double length_ms, Point from, Point to) {
    segments_.push_back(Segment{motion, now_, now_ + length_ms, from, to});
    now_ += length_ms;
  }

  // Fixations and pursuits stay within the middle [0.1, 0.9]² of the viewport.
  bool inside(Point p) const {
    return p.u >= 0.1 * width_ && p.u <= 0.9 * width_ && p.v >= 0.1 * height_ && p.v <= 0.9 * height_;
  }
  Point box_point() { return {uniform(0.1 * width_, 0.9 * width_), uniform(0.1 * height_, 0.9 * height_)}; }
  Point direction() {
    const double angle = uniform(0, 2 * std::numbers::pi);
    return {std::cos(angle), std::sin(angle)};
  }

  Point saccade_target(Point from) {
    for (int attempt = 0; attempt < 32; ++attempt) {
      const Point to = from + direction() * uniform(o_.saccade_min_deg, o_.saccade_max_deg);
      if (inside(to)) return to;
    }
    return box_point();  // the viewport is small for the amplitudes
  }

  double saccade_ms(double amplitude_deg) const {
    return o_.saccade_ms_per_deg * amplitude_deg + o_.saccade_base_ms;
  }

  Point saccade(Point from, Point to) {
    add(Motion::kSaccade, saccade_ms(length(to - from)), from, to);
    return to;
  }

  // The target's velocity (degrees per ms) for a pursuit from `from` that stays in the box,
  // shortening `length_ms` when no drawn direction fits.
  Point pursuit_velocity(Point from, double speed_deg_s, double& length_ms) {
    const double speed = speed_deg_s / 1000;
    for (int attempt = 0; attempt < 32; ++attempt) {
      const Point velocity = direction() * speed;
      if (inside(from + velocity * length_ms)) return velocity;
    }
    // Towards the box's farthest corner, as far as it lies.
    const Point corner{from.u < width_ / 2 ? 0.9 * width_ : 0.1 * width_,
                       from.v < height_ / 2 ? 0.9 * height_ : 0.1 * height_};
    const double distance = length(corner - from);
    length_ms = std::min(length_ms, distance / speed);
    return (corner - from) * (speed / distance);
  }

  // Smooth pursuit of a target leaving `from`: the eye lags at (1 - gain) of the target's speed
  // and catches up by a saccade onto the target whenever the lag reaches catch_up_deg. Returns
  // where the eye ends.
  Point pursue(Point from) {
    const double speed_deg_s = uniform(o_.pursuit_min_deg_s, o_.pursuit_max_deg_s);
    double length_ms = uniform(o_.pursuit_min_ms, o_.pursuit_max_ms);
    const Point velocity = pursuit_velocity(from, speed_deg_s, length_ms);
    const double start = now_, end = now_ + length_ms;
    const auto target = [&](double t) { return from + velocity * (t - start); };
    const double lag_per_ms = (1 - o_.pursuit_gain) * speed_deg_s / 1000;
    Point eye = from;
    while (now_ < end) {
      double run_ms = end - now_;
      if (lag_per_ms > 0)
        run_ms = std::min(run_ms, std::max(0.0, (o_.catch_up_deg - length(target(now_) - eye)) / lag_per_ms));
      if (run_ms > 0) {
        const Point next = eye + velocity * (o_.pursuit_gain * run_ms);
        add(Motion::kPursuit, run_ms, eye, next);
        eye = next;
      }
      if (now_ >= end) break;
      // Land where the target will be when the saccade ends.
      const double first_guess = saccade_ms(length(target(now_) - eye));
      eye = saccade(eye, target(now_ + saccade_ms(length(target(now_ + first_guess) - eye))));
    }
    return eye;
  }

  const SynthesisOptions& o_;
  std::mt19937_64 rng_;
  const double width_, height_;
  double now_ = 0;
  std::vector<Segment> segments_;
};

// Minimum-jerk position profile of a saccade: 0 at s = 0, 1 at s = 1, peak speed 1.875 at s = 0.5.
double min_jerk(double s) {
  return s * s * s * (10 - 15 * s + 6 * s * s);
}

}  // namespace

Result<std::vector<GazeSample>> parse_gaze_trace(const std::string& text) {
  std::vector<GazeSample> samples;
  std::stringstream in(text);
  std::string line;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    bool timed = false;
    auto sample = read_sample(line, timed);
    if (!sample) {
      if (!timed && samples.empty() && number == 1) continue;  // a header line such as "time_ms,x,y"
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("line {}: {}", number, sample.error().message));
    }
    if (sample->time_ms < 0 || (!samples.empty() && sample->time_ms < samples.back().time_ms)) {
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("line {}: time {} ms goes backwards", number, sample->time_ms));
    }
    samples.push_back(*sample);
  }
  if (samples.empty()) return make_error(ErrorCode::kInvalidArgument, "the trace holds no sample");
  if (std::none_of(samples.begin(), samples.end(), [](const GazeSample& s) { return s.tracked; }))
    return make_error(ErrorCode::kInvalidArgument, "the trace holds no sample with a gaze (all are lost)");
  return samples;
}

std::string format_gaze_sample(const GazeSample& s) {
  if (!s.tracked) return fmt::format("{:.3f},,", s.time_ms);
  return fmt::format("{:.3f},{:.5f},{:.5f}", s.time_ms, s.x, s.y);
}

Status check_synthesis_options(const SynthesisOptions& o) {
  const auto fail = [](const std::string& message) {
    return make_error(ErrorCode::kInvalidArgument, message);
  };
  if (!(o.rate_hz > 0) || !(o.duration_ms > 0)) return fail("the rate and the duration must be positive");
  if (!(o.screen_deg > 0) || !(o.aspect > 0)) return fail("the screen's width in degrees must be positive");
  if (!(o.pursuit_share >= 0) || !(o.blink_share >= 0) || !(o.pursuit_share + o.blink_share <= 1))
    return fail(fmt::format("--pursuit-share {} and --blink-share {} must be at least 0 and sum to at most 1",
                            o.pursuit_share, o.blink_share));
  if (!(o.pursuit_gain > 0 && o.pursuit_gain <= 1))
    return fail(fmt::format("--pursuit-gain {} must lie in (0, 1]", o.pursuit_gain));
  const struct {
    double lo, hi;
    const char* what;
  } ranges[] = {{o.fixation_min_ms, o.fixation_max_ms, "fixation lengths"},
                {o.saccade_min_deg, o.saccade_max_deg, "saccade amplitudes"},
                {o.pursuit_min_deg_s, o.pursuit_max_deg_s, "pursuit speeds"},
                {o.pursuit_min_ms, o.pursuit_max_ms, "pursuit lengths"},
                {o.blink_min_ms, o.blink_max_ms, "blink lengths"}};
  for (const auto& r : ranges) {
    if (!(r.lo > 0 && r.lo <= r.hi))
      return fail(fmt::format("{} {}..{}: not a positive range", r.what, r.lo, r.hi));
  }
  if (!(o.saccade_base_ms > 0) || !(o.saccade_ms_per_deg >= 0) || !(o.catch_up_deg > 0) ||
      !(o.jitter_deg >= 0) || !(o.drift_deg >= 0))
    return fail("saccade timing, catch-up, jitter and drift must be positive");
  return Ok{};
}

std::vector<GazeSample> synthesize_gaze_trace(const SynthesisOptions& o) {
  const std::vector<Segment> plan = Planner(o).plan();
  const double width = o.screen_deg, height = o.screen_deg / o.aspect;
  std::mt19937_64 rng(o.seed ^ 0x9e3779b97f4a7c15u);  // the noise, drawn apart from the plan
  const double step_ms = 1000.0 / o.rate_hz;
  std::normal_distribution<double> jitter(0.0, o.jitter_deg);
  std::normal_distribution<double> drift_step(0.0, o.drift_deg * std::sqrt(step_ms / 1000));
  Point drift;  // walks during fixations, held through pursuits and blinks, undone by saccades
  std::vector<GazeSample> samples;
  std::size_t k = 0;
  for (std::uint64_t i = 0;; ++i) {
    const double t = static_cast<double>(i) * step_ms;
    if (t >= o.duration_ms) break;
    for (; plan[k].end_ms <= t; ++k) {
      if (plan[k].motion == Motion::kSaccade) drift = {};
    }
    const Segment& s = plan[k];
    const double along = (t - s.start_ms) / (s.end_ms - s.start_ms);
    Point p = s.from;
    switch (s.motion) {
      case Motion::kBlink:
        samples.push_back(GazeSample{t, 0.5, 0.5, false});
        continue;
      case Motion::kFixation:
        drift = drift + Point{drift_step(rng), drift_step(rng)};
        p = p + drift;
        break;
      case Motion::kSaccade:
        p = p + (s.to - s.from) * min_jerk(along) + drift * (1 - min_jerk(along));
        break;
      case Motion::kPursuit:
        p = p + (s.to - s.from) * along + drift;
        break;
    }
    p = p + Point{jitter(rng), jitter(rng)};
    samples.push_back(GazeSample{t, std::clamp(p.u / width, 0.0, 1.0), std::clamp(p.v / height, 0.0, 1.0)});
  }
  return samples;
}

}  // namespace mtlod::clients
