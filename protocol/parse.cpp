// Request parsing and validation (PROTOCOL.md, "Messages"). nlohmann's exceptions are caught at
// the entry point; inside, a small reader walks each object, checks types and ranges with the
// field's full path in every message, and reports fields nobody asked for.
#include "protocol/parse.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <string_view>
#include <type_traits>
#include <utility>
#include <variant>

#include "fmt/format.h"
#include "fmt/ranges.h"
#include "nlohmann/json.hpp"
#include "protocol/text.hpp"

namespace mtlod::protocol {
namespace {

using nlohmann::json;

// Thrown only inside this file and caught in parse_request.
struct Failure {
  ErrorKind code;
  std::string message;
};

[[noreturn]] void fail(ErrorKind code, std::string message) {
  throw Failure{code, std::move(message)};
}

const char* type_name(const json& v) {
  if (v.is_null()) return "null";
  if (v.is_boolean()) return "boolean";
  if (v.is_number_integer()) return "integer";
  if (v.is_number()) return "number";
  if (v.is_string()) return "string";
  if (v.is_array()) return "array";
  return "object";
}

std::string show(const json& v) {
  std::string s = v.dump(-1, ' ', false, json::error_handler_t::replace);
  if (s.size() > 40) s = std::string(utf8_prefix(s, 37)) + "...";
  return s;
}

// Walks one JSON object; remembers which keys were read so finish() can name the others.
class ObjectReader {
 public:
  ObjectReader(const json& object, std::string path) : object_(object), path_(std::move(path)) {
    if (!object_.is_object())
      fail(ErrorKind::kBadRequest, fmt::format("{} must be an object, got {}", where(), type_name(object_)));
  }

  bool has(const char* key) const { return object_.contains(key); }

  const json* find(const char* key) {
    read_.insert(key);
    auto it = object_.find(key);
    return it == object_.end() ? nullptr : &*it;
  }
  const json& require(const char* key) {
    const json* v = find(key);
    if (!v) fail(ErrorKind::kBadRequest, fmt::format("{} is required", field(key)));
    return *v;
  }

  double number(const char* key, double fallback, double min, double max) {
    const json* v = find(key);
    return v ? check_number(*v, field(key), min, max) : fallback;
  }
  double required_number(const char* key, double min, double max) {
    return check_number(require(key), field(key), min, max);
  }
  std::uint64_t integer(const char* key, std::uint64_t fallback, std::uint64_t min, std::uint64_t max) {
    const json* v = find(key);
    return v ? check_integer(*v, field(key), min, max) : fallback;
  }
  bool boolean(const char* key, bool fallback) {
    const json* v = find(key);
    if (!v) return fallback;
    if (!v->is_boolean())
      fail(ErrorKind::kBadRequest, fmt::format("{} must be a boolean, got {}", field(key), type_name(*v)));
    return v->get<bool>();
  }
  std::string string(const char* key, std::size_t max_length) {
    return check_string(require(key), field(key), max_length);
  }
  std::string optional_string(const char* key, std::string fallback, std::size_t max_length) {
    const json* v = find(key);
    return v ? check_string(*v, field(key), max_length) : fallback;
  }
  // One of `names` (index into it).
  template <std::size_t N>
  std::size_t choice(const char* key, const std::array<const char*, N>& names, std::size_t fallback) {
    const json* v = find(key);
    if (!v) return fallback;
    const std::string s = check_string(*v, field(key), 64);
    for (std::size_t i = 0; i < N; ++i) {
      if (s == names[i]) return i;
    }
    std::string options;
    for (const char* n : names) options += fmt::format("{}'{}'", options.empty() ? "" : ", ", n);
    fail(ErrorKind::kBadRequest, fmt::format("{} is '{}'; expected one of {}", field(key), s, options));
  }

  void finish() const {
    for (auto it = object_.begin(); it != object_.end(); ++it) {
      if (!read_.count(it.key()))
        fail(ErrorKind::kBadRequest, fmt::format("unknown field {}", field(it.key())));
    }
  }

  std::string field(const std::string& key) const {
    return path_.empty() ? "'" + key + "'" : "'" + path_ + "." + key + "'";
  }
  std::string child(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  std::string where() const { return path_.empty() ? "the request" : "'" + path_ + "'"; }

  static double check_number(const json& v, const std::string& name, double min, double max) {
    if (!v.is_number())
      fail(ErrorKind::kBadRequest, fmt::format("{} must be a number, got {}", name, type_name(v)));
    const double x = v.get<double>();
    if (!std::isfinite(x) || x < min || x > max) {
      fail(ErrorKind::kBadRequest, fmt::format("{} is {}; expected {} to {}", name, show(v), min, max));
    }
    return x;
  }
  static std::uint64_t check_integer(const json& v, const std::string& name, std::uint64_t min,
                                     std::uint64_t max) {
    if (!v.is_number_integer() ||
        (v.is_number_integer() && !v.is_number_unsigned() && v.get<std::int64_t>() < 0)) {
      fail(ErrorKind::kBadRequest,
           fmt::format("{} must be a non-negative integer, got {} {}", name, type_name(v), show(v)));
    }
    const std::uint64_t x = v.get<std::uint64_t>();
    if (x < min || x > max)
      fail(ErrorKind::kBadRequest, fmt::format("{} is {}; expected {} to {}", name, x, min, max));
    return x;
  }
  static std::string check_string(const json& v, const std::string& name, std::size_t max_length) {
    if (!v.is_string())
      fail(ErrorKind::kBadRequest, fmt::format("{} must be a string, got {}", name, type_name(v)));
    std::string s = v.get<std::string>();
    if (s.size() > max_length)
      fail(ErrorKind::kBadRequest, fmt::format("{} is longer than {} characters", name, max_length));
    return s;
  }

 private:
  const json& object_;
  std::string path_;
  std::set<std::string, std::less<>> read_;
};

// 4×4 determinant by cofactor expansion in double precision.
double determinant(const Matrix4& m) {
  auto a = [&m](int row, int col) { return m[col * 4 + row]; };
  double det = 0;
  for (int c = 0; c < 4; ++c) {
    double minor[9];
    int k = 0;
    for (int r = 1; r < 4; ++r)
      for (int cc = 0; cc < 4; ++cc)
        if (cc != c) minor[k++] = a(r, cc);
    const double d3 = minor[0] * (minor[4] * minor[8] - minor[5] * minor[7]) -
                      minor[1] * (minor[3] * minor[8] - minor[5] * minor[6]) +
                      minor[2] * (minor[3] * minor[7] - minor[4] * minor[6]);
    det += (c % 2 ? -1.0 : 1.0) * a(0, c) * d3;
  }
  return det;
}

Matrix4 read_matrix(const json& v, const std::string& name) {
  if (!v.is_array() || v.size() != 16) {
    fail(ErrorKind::kBadRequest,
         fmt::format("{} must be an array of 16 numbers (column-major), got {}", name,
                     v.is_array() ? fmt::format("{} elements", v.size()) : type_name(v)));
  }
  Matrix4 m;
  double largest = 0;
  for (std::size_t i = 0; i < 16; ++i) {
    m[i] = ObjectReader::check_number(v[i], fmt::format("{}[{}]", name, i), -1e12, 1e12);
    largest = std::max(largest, std::abs(m[i]));
  }
  // Singular, or so badly conditioned that projecting through it is meaningless.
  const double det = determinant(m);
  if (largest == 0 || !(std::abs(det) > 1e-12 * std::pow(largest, 4))) {
    fail(ErrorKind::kBadRequest, fmt::format("{} is singular (determinant {:g})", name, det));
  }
  return m;
}

std::array<std::uint32_t, 2> read_pair(const json& v, const std::string& name, std::uint32_t max,
                                       ErrorKind over) {
  if (!v.is_array() || v.size() != 2)
    fail(ErrorKind::kBadRequest, fmt::format("{} must be [width, height]", name));
  std::array<std::uint32_t, 2> out;
  for (std::size_t i = 0; i < 2; ++i) {
    const std::string element = fmt::format("{}[{}]", name, i);
    const std::uint64_t x = ObjectReader::check_integer(v[i], element, 1, UINT32_MAX);
    if (x > max) fail(over, fmt::format("{} {} exceeds the server limit {}", element, x, max));
    out[i] = static_cast<std::uint32_t>(x);
  }
  return out;
}

// A criterion's entry in `criteria`: for a point-seeded one, a point {x, y, distance, factor} or an
// array of them (every point shares the first one's distance and factor: one transform); for the
// others, true/false or {distance, factor}.
std::optional<Region> read_region(const json& v, core::view::Criterion criterion) {
  const CriterionWire& w = wire(criterion);
  const std::string path = fmt::format("criteria.{}", w.name);
  Region region = default_region(criterion);
  auto read_law = [&](ObjectReader& r) {
    region.distance = r.number("distance", w.distance, 0, 1e6);
    region.factor = r.number("factor", w.factor, w.factor_min, w.factor_max);
  };
  if (core::view::traits(criterion).seeds != core::view::Seeds::kPoints) {
    if (v.is_boolean()) return v.get<bool>() ? std::optional(region) : std::nullopt;
    ObjectReader r(v, path);
    read_law(r);
    r.finish();
    return region;
  }
  auto read_point = [&](const json& p, const std::string& point_path) {
    ObjectReader r(p, point_path);
    const Point point{r.required_number("x", 0, 1), r.required_number("y", 0, 1)};
    if (region.points.empty()) {
      read_law(r);
    } else {  // checked, then shared
      r.number("distance", 0, 0, 1e6);
      r.number("factor", 1, w.factor_min, w.factor_max);
    }
    r.finish();
    region.points.push_back(point);
  };
  if (v.is_object()) {  // a single point may be given without the array
    read_point(v, path);
  } else if (v.is_array()) {
    for (std::size_t i = 0; i < v.size(); ++i) read_point(v[i], fmt::format("{}[{}]", path, i));
  } else {
    fail(ErrorKind::kBadRequest, fmt::format("'{}' must be an array of {{x, y, ...}} objects", path));
  }
  if (region.points.empty()) return std::nullopt;
  return region;
}

Criteria read_criteria(const json& v, const Limits& limits) {
  ObjectReader r(v, "criteria");
  Criteria c;
  std::size_t points = 0;
  for (const core::view::Criterion criterion : core::view::kAllCriteria) {
    std::optional<Region>& region = c.regions[criterion];
    if (const json* entry = r.find(wire(criterion).name)) region = read_region(*entry, criterion);
    if (region) points += region->points.size();
  }
  if (points > limits.max_foci)
    fail(ErrorKind::kLimitExceeded,
         fmt::format("{} criteria points exceed the server limit {}", points, limits.max_foci));
  c.falloff = static_cast<core::view::FalloffLaw>(r.choice("falloff", kFalloffNames, 0));
  c.distance = static_cast<core::view::DistanceMetric>(r.choice("distance", kDistanceMetricNames, 0));
  c.units = static_cast<DistanceUnit>(r.choice("units", kDistanceUnitNames, 0));
  c.internal_silhouettes = r.boolean("internal_silhouettes", false);
  c.frustum_factor = r.number("frustum_factor", c.frustum_factor, 1, 1e6);
  c.backface_factor = r.number("backface_factor", c.backface_factor, 1, 1e6);
  c.hidden_factor = r.number("hidden_factor", c.hidden_factor, 1, 1e6);
  r.finish();
  return c;
}

// position_bits and normal_bits, in `quantization` or under their older names in `draco`. Positions
// are floats (24-bit mantissa), and Draco's entropy coder's time and memory double with each bit: 20
// bits is finer than any model needs and still cheap. Octahedral normal coding needs at least 2 bits.
void read_quantization(ObjectReader& r, Quantization& q) {
  q.position_bits = static_cast<int>(r.integer("position_bits", q.position_bits, 1, 20));
  q.normal_bits = static_cast<int>(r.integer("normal_bits", q.normal_bits, 2, 16));
}

// A scene's instances: {"instances": [{"model", "matrix"}, ...]}, at least one, at most the limit.
std::vector<Instance> read_scene(const json& v, const Limits& limits) {
  ObjectReader r(v, "scene");
  const json& list = r.require("instances");
  if (!list.is_array()) fail(ErrorKind::kBadRequest, "'scene.instances' must be an array of {model, matrix}");
  if (list.empty()) fail(ErrorKind::kBadRequest, "'scene.instances' is empty: a scene needs an instance");
  if (list.size() > limits.max_instances) {
    fail(ErrorKind::kLimitExceeded,
         fmt::format("{} scene instances exceed the server limit {}", list.size(), limits.max_instances));
  }
  std::vector<Instance> instances;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string path = fmt::format("scene.instances[{}]", i);
    ObjectReader ir(list[i], path);
    Instance instance;
    instance.model = ir.string("model", 256);
    if (const json* m = ir.find("matrix")) {
      const std::string name = path + ".matrix";
      instance.matrix = read_matrix(*m, name);
      const Matrix4& a = instance.matrix;
      if (a[3] != 0 || a[7] != 0 || a[11] != 0 || a[15] != 1)
        fail(ErrorKind::kBadRequest, fmt::format("{} must be affine: its last row 0, 0, 0, 1", name));
    }
    ir.finish();
    instances.push_back(std::move(instance));
  }
  r.finish();
  return instances;
}

Extract read_extract(ObjectReader& r, const Limits& limits) {
  Extract e;
  if (const json* scene = r.find("scene")) {
    if (r.has("model")) fail(ErrorKind::kBadRequest, "give 'model' or 'scene', not both");
    if (scene->is_string()) {
      e.scene_name = ObjectReader::check_string(*scene, "'scene'", 256);
    } else {
      e.instances = read_scene(*scene, limits);
    }
  } else {
    e.model = r.string("model", 256);
  }
  {
    ObjectReader camera(r.require("camera"), "camera");
    e.view = read_matrix(camera.require("view"), "camera.view");
    e.projection = read_matrix(camera.require("projection"), "camera.projection");
    if (const json* vp = camera.find("viewport"))
      e.viewport = read_pair(*vp, "camera.viewport", 16384, ErrorKind::kBadRequest);
    camera.finish();
  }
  if (const json* g = r.find("grid"))
    e.grid = read_pair(*g, "grid", limits.max_grid, ErrorKind::kLimitExceeded);
  const json& error = r.require("error");
  if (error.is_number()) {
    e.error = ObjectReader::check_number(error, "'error'", 0, 1e12);
  } else {
    ObjectReader er(error, "error");
    e.error = er.required_number("value", 0, 1e12);
    e.error_unit = static_cast<core::view::ErrorUnits>(er.choice("unit", kErrorUnitNames, 0));
    er.finish();
  }
  if (const json* c = r.find("criteria")) e.criteria = read_criteria(*c, limits);
  if (const json* b = r.find("budget")) {
    const std::uint64_t budget = ObjectReader::check_integer(*b, "'budget'", 1, UINT32_MAX);
    if (budget > limits.max_budget) {
      fail(ErrorKind::kLimitExceeded,
           fmt::format("'budget' {} exceeds the server limit {}", budget, limits.max_budget));
    }
    e.budget = static_cast<std::uint32_t>(budget);
  }
  if (const json* a = r.find("attributes")) {
    ObjectReader ar(*a, "attributes");
    e.normals = ar.boolean("normals", true);
    if (ar.has("colors")) e.colors = ar.boolean("colors", false);
    e.labels = ar.boolean("labels", false);
    ar.finish();
  }
  e.delta = r.boolean("delta", false);
  if (r.has("codec")) e.codec = static_cast<core::codec::Codec>(r.choice("codec", kCodecNames, 0));
  bool older_names = false;  // the bits under their names from when Draco was the only codec
  if (const json* d = r.find("draco")) {
    ObjectReader dr(*d, "draco");
    if (dr.has("method"))
      e.draco.method = static_cast<core::codec::DracoMethod>(dr.choice("method", kDracoMethodNames, 0));
    e.draco.speed = static_cast<int>(dr.integer("speed", e.draco.speed, 0, 10));
    older_names = dr.has("position_bits") || dr.has("normal_bits");
    read_quantization(dr, e.quantization);
    if (dr.has("entropy_coding")) e.draco.entropy_coding = dr.boolean("entropy_coding", true);
    dr.finish();
  }
  if (const json* q = r.find("quantization")) {
    if (older_names) {
      fail(ErrorKind::kBadRequest,
           "give the bits in 'quantization' only: draco.position_bits and draco.normal_bits are their older "
           "names");
    }
    ObjectReader qr(*q, "quantization");
    read_quantization(qr, e.quantization);
    qr.finish();
  }
  if (e.codec) {
    if (auto refusal = codec_refusal(e, *e.codec)) fail(ErrorKind::kBadRequest, std::move(*refusal));
  }
  if (e.delta && e.draco.method == core::codec::DracoMethod::kEdgebreaker) {
    fail(ErrorKind::kBadRequest, "'delta' needs draco.method 'sequential': edgebreaker reorders the faces");
  }
  if ((!e.instances.empty() || !e.scene_name.empty()) && e.labels)
    fail(ErrorKind::kBadRequest, "a scene carries no attributes.labels: its silhouettes are the picture's");
  if (e.delta && e.labels) {
    fail(ErrorKind::kBadRequest,
         "'delta' cannot carry attributes.labels: the labels of kept triangles would go stale");
  }
  return e;
}

// One reader per request type, found by overload: read_request's table is built from the variant's
// alternatives, so a request type without a reader does not compile.
Hello read(std::type_identity<Hello>, ObjectReader& r, const Limits&) {
  Hello h;
  h.version = static_cast<int>(r.integer("version", kProtocolVersion, 0, 1000));
  h.client = r.optional_string("client", "", 256);
  h.token = r.optional_string("token", "", 256);
  if (r.has("codec")) h.codec = static_cast<core::codec::Codec>(r.choice("codec", kCodecNames, 0));
  if (h.version != kProtocolVersion) {
    fail(ErrorKind::kUnsupportedVersion,
         fmt::format("protocol version {} is not supported; this server speaks version {}", h.version,
                     kProtocolVersion));
  }
  return h;
}
ListModels read(std::type_identity<ListModels>, ObjectReader&, const Limits&) {
  return {};
}
ModelInfo read(std::type_identity<ModelInfo>, ObjectReader& r, const Limits&) {
  return ModelInfo{r.string("model", 256)};
}
Extract read(std::type_identity<Extract>, ObjectReader& r, const Limits& limits) {
  return read_extract(r, limits);
}
Gaze read(std::type_identity<Gaze>, ObjectReader& r, const Limits&) {
  Gaze g;
  g.x = r.required_number("x", 0, 1);
  g.y = r.required_number("y", 0, 1);
  if (r.has("distance")) g.distance = r.number("distance", 0, 0, 1e6);
  if (r.has("factor")) g.factor = r.number("factor", 0, 0, 1);
  return g;
}
Cancel read(std::type_identity<Cancel>, ObjectReader& r, const Limits&) {
  return Cancel{r.integer("target", 0, 0, UINT64_MAX)};
}
Stats read(std::type_identity<Stats>, ObjectReader&, const Limits&) {
  return {};
}
Ping read(std::type_identity<Ping>, ObjectReader&, const Limits&) {
  return {};
}
Reload read(std::type_identity<Reload>, ObjectReader& r, const Limits&) {
  return Reload{r.string("token", 256)};
}

Request read_request(ObjectReader& r, const std::string& type, const Limits& limits) {
  using Reader = Request (*)(ObjectReader&, const Limits&);
  static constexpr auto kReaders = []<std::size_t... I>(std::index_sequence<I...>) {
    return std::array<Reader, sizeof...(I)>{+[](ObjectReader& r, const Limits& limits) -> Request {
      return read(std::type_identity<std::variant_alternative_t<I, Request>>{}, r, limits);
    }...};
  }
  (std::make_index_sequence<std::variant_size_v<Request>>{});
  const auto* name = std::find(kRequestTypeNames.begin(), kRequestTypeNames.end(), std::string_view(type));
  if (name == kRequestTypeNames.end()) {
    fail(ErrorKind::kUnknownType, fmt::format("unknown request type '{}'; expected one of {}", type,
                                              fmt::join(kRequestTypeNames, ", ")));
  }
  return kReaders[static_cast<std::size_t>(name - kRequestTypeNames.begin())](r, limits);
}

}  // namespace

const char* to_string(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::kBadFrame:
      return "bad_frame";
    case ErrorKind::kBadJson:
      return "bad_json";
    case ErrorKind::kBadRequest:
      return "bad_request";
    case ErrorKind::kUnknownType:
      return "unknown_type";
    case ErrorKind::kUnsupportedVersion:
      return "unsupported_version";
    case ErrorKind::kLimitExceeded:
      return "limit_exceeded";
    case ErrorKind::kUnknownModel:
      return "unknown_model";
    case ErrorKind::kNoView:
      return "no_view";
    case ErrorKind::kCancelled:
      return "cancelled";
    case ErrorKind::kSuperseded:
      return "superseded";
    case ErrorKind::kShuttingDown:
      return "shutting_down";
    case ErrorKind::kUnauthorized:
      return "unauthorized";
    case ErrorKind::kUnavailable:
      return "unavailable";
    case ErrorKind::kInternal:
      return "internal";
  }
  return "internal";
}

std::optional<std::string> codec_refusal(const Extract& e, core::codec::Codec codec) {
  const core::codec::CodecTraits& can = core::codec::traits(codec);
  if (e.labels && !can.carries_labels) {
    std::vector<std::string_view> carriers;
    for (std::size_t c = 0; c < kCodecNames.size(); ++c)
      if (core::codec::kCodecTraits[c].carries_labels) carriers.emplace_back(kCodecNames[c]);
    return fmt::format("codec '{}' cannot carry attributes.labels: use '{}'", enum_name(kCodecNames, codec),
                       fmt::join(carriers, "' or '"));
  }
  if (e.quantization.position_bits > can.max_position_bits) {
    return fmt::format("codec '{}' quantizes positions to at most {} bits, not quantization.position_bits {}",
                       enum_name(kCodecNames, codec), can.max_position_bits, e.quantization.position_bits);
  }
  return std::nullopt;
}

Result<ParsedRequest, ProtocolError> parse_request(std::string_view text, const Limits& limits) {
  // Messages quote the request's bytes; what goes back to the client and into logs must be text.
  json doc;
  try {
    doc = json::parse(text.begin(), text.end());
  } catch (const json::parse_error& e) {
    // The parser's message quotes the bytes it last read, whatever they are.
    return ProtocolError{ErrorKind::kBadJson,
                         printable(fmt::format("JSON does not parse at byte {}: {}", e.byte, e.what()))};
  } catch (const json::exception& e) {
    return ProtocolError{ErrorKind::kBadJson, printable(fmt::format("JSON does not parse: {}", e.what()))};
  }
  std::optional<std::uint64_t> id;
  try {
    ObjectReader r(doc, "");
    // Read the id first so that even a bad request's error reply carries it.
    if (const json* j = r.find("id"); j && j->is_number_unsigned()) id = j->get<std::uint64_t>();
    r.integer("id", 0, 0, UINT64_MAX);
    if (!id) fail(ErrorKind::kBadRequest, "'id' is required: a non-negative integer chosen by the client");
    const std::string type = r.string("type", 64);
    Request request = read_request(r, type, limits);
    r.finish();
    return ParsedRequest{*id, std::move(request)};
  } catch (const Failure& f) {
    return ProtocolError{f.code, printable(f.message), id};
  } catch (const json::exception& e) {
    return ProtocolError{ErrorKind::kBadRequest, printable(e.what()), id};
  }
}

Result<std::vector<Instance>, ProtocolError> parse_scene(std::string_view text, const Limits& limits) {
  try {
    return read_scene(json::parse(text.begin(), text.end()), limits);
  } catch (const json::parse_error& e) {
    return ProtocolError{ErrorKind::kBadJson,
                         printable(fmt::format("JSON does not parse at byte {}: {}", e.byte, e.what()))};
  } catch (const Failure& f) {
    return ProtocolError{f.code, printable(f.message)};
  } catch (const json::exception& e) {
    return ProtocolError{ErrorKind::kBadRequest, printable(e.what())};
  }
}

// ---- Serialisation for clients ----------------------------------------------------------------

namespace {

json region_json(const Region& region, core::view::Criterion criterion) {
  if (core::view::traits(criterion).seeds != core::view::Seeds::kPoints)
    return {{"distance", region.distance}, {"factor", region.factor}};
  json out = json::array();
  for (const Point& p : region.points)
    out.push_back({{"x", p.x}, {"y", p.y}, {"distance", region.distance}, {"factor", region.factor}});
  return out;
}

json extract_json(const Extract& e) {
  json j;
  if (!e.scene_name.empty()) {
    j["scene"] = e.scene_name;
  } else if (e.instances.empty()) {
    j["model"] = e.model;
  } else {
    json instances = json::array();
    for (const Instance& i : e.instances) instances.push_back({{"model", i.model}, {"matrix", i.matrix}});
    j["scene"] = {{"instances", instances}};
  }
  j["camera"] = {{"view", e.view}, {"projection", e.projection}, {"viewport", e.viewport}};
  j["grid"] = e.grid;
  j["error"] = {{"value", e.error}, {"unit", enum_name(kErrorUnitNames, e.error_unit)}};
  json c;
  for (const core::view::Criterion criterion : core::view::kAllCriteria) {
    if (const std::optional<Region>& region = e.criteria.regions[criterion])
      c[wire(criterion).name] = region_json(*region, criterion);
  }
  c["falloff"] = enum_name(kFalloffNames, e.criteria.falloff);
  c["distance"] = enum_name(kDistanceMetricNames, e.criteria.distance);
  c["units"] = enum_name(kDistanceUnitNames, e.criteria.units);
  c["internal_silhouettes"] = e.criteria.internal_silhouettes;
  c["frustum_factor"] = e.criteria.frustum_factor;
  c["backface_factor"] = e.criteria.backface_factor;
  c["hidden_factor"] = e.criteria.hidden_factor;
  j["criteria"] = c;
  if (e.budget) j["budget"] = *e.budget;
  j["attributes"] = {{"normals", e.normals}, {"labels", e.labels}};
  if (e.colors) j["attributes"]["colors"] = *e.colors;
  if (e.delta) j["delta"] = true;
  if (e.codec) j["codec"] = enum_name(kCodecNames, *e.codec);
  j["quantization"] = {{"position_bits", e.quantization.position_bits},
                       {"normal_bits", e.quantization.normal_bits}};
  j["draco"] = {{"speed", e.draco.speed}};
  if (e.draco.method) j["draco"]["method"] = enum_name(kDracoMethodNames, *e.draco.method);
  if (e.draco.entropy_coding) j["draco"]["entropy_coding"] = *e.draco.entropy_coding;
  return j;
}

// One writer per request type, found by overload (no generic fallback: a request type without a
// writer does not compile).
json write(const Hello& r) {
  json h = {{"version", r.version}, {"client", r.client}};
  if (!r.token.empty()) h["token"] = r.token;
  if (r.codec) h["codec"] = enum_name(kCodecNames, *r.codec);
  return h;
}
json write(const ListModels&) {
  return json::object();
}
json write(const ModelInfo& r) {
  return {{"model", r.model}};
}
json write(const Extract& r) {
  return extract_json(r);
}
json write(const Gaze& r) {
  json g = {{"x", r.x}, {"y", r.y}};
  if (r.distance) g["distance"] = *r.distance;
  if (r.factor) g["factor"] = *r.factor;
  return g;
}
json write(const Cancel& r) {
  return {{"target", r.target}};
}
json write(const Stats&) {
  return json::object();
}
json write(const Ping&) {
  return json::object();
}
json write(const Reload& r) {
  return {{"token", r.token}};
}

}  // namespace

std::string to_json(const Request& request, std::uint64_t id) {
  json j = std::visit([](const auto& r) { return write(r); }, request);
  j["type"] = request_type_name(request);
  j["id"] = id;
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace mtlod::protocol
