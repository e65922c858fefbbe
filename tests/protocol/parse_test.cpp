// Request parsing: valid requests read back what a client wrote, and every malformed request named
// in protocol/PROTOCOL.md gets the error code the document gives.
#include "protocol/parse.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <regex>
#include <set>
#include <variant>

#include "fmt/format.h"
#include "nlohmann/json.hpp"
#include "tests/protocol/protocol_cases.hpp"

namespace mtlod::protocol {
namespace {

Extract sample_extract() {
  Extract e;
  e.model = "bunny";
  e.view = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -3, 1};
  e.projection = {1.5, 0, 0, 0, 0, 2, 0, 0, 0, 0, -1.002, -1, 0, 0, -0.2002, 0};
  e.viewport = {1024, 768};
  e.grid = {512, 384};
  e.error = 0.5;
  e.error_unit = core::view::ErrorUnits::kScreenPixels;
  // Every criterion in use, with values other than its defaults.
  for (const core::view::Criterion c : core::view::kAllCriteria) {
    const CriterionWire& w = wire(c);
    Region region{w.distance + 1, (w.factor + w.factor_max) / 2, {}};
    if (core::view::traits(c).seeds == core::view::Seeds::kPoints)
      region.points = {{0.25, 0.75}, {0.5, 0.125}};
    e.criteria.regions[c] = region;
  }
  e.criteria.falloff = core::view::FalloffLaw::kFoveal;
  e.criteria.distance = core::view::DistanceMetric::kEuclidean;
  e.criteria.units = DistanceUnit::kChamfer;
  e.criteria.internal_silhouettes = true;
  e.criteria.frustum_factor = 4;
  e.criteria.backface_factor = 2;
  e.criteria.hidden_factor = 16;
  e.budget = 50'000;
  e.normals = true;
  e.labels = true;
  e.quantization = {12, 8};
  e.draco = {core::codec::DracoMethod::kSequential, 3, false};
  return e;
}

TEST(ParseRequest, ReadsBackEveryFieldAClientWrote) {
  const Extract e = sample_extract();
  const auto parsed = parse_request(to_json(e, 42), Limits{});
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_EQ(parsed->id, 42u);
  const auto& got = std::get<Extract>(parsed->request);
  EXPECT_EQ(got.model, e.model);
  EXPECT_EQ(got.view, e.view);
  EXPECT_EQ(got.projection, e.projection);
  EXPECT_EQ(got.viewport, e.viewport);
  EXPECT_EQ(got.grid, e.grid);
  EXPECT_EQ(got.error, e.error);
  EXPECT_EQ(got.error_unit, e.error_unit);
  for (const core::view::Criterion c : core::view::kAllCriteria) {
    ASSERT_TRUE(got.criteria.regions[c]) << wire(c).name;
    EXPECT_EQ(*got.criteria.regions[c], *e.criteria.regions[c]) << wire(c).name;
  }
  EXPECT_EQ(got.criteria.falloff, core::view::FalloffLaw::kFoveal);
  EXPECT_EQ(got.criteria.distance, core::view::DistanceMetric::kEuclidean);
  EXPECT_EQ(got.criteria.units, DistanceUnit::kChamfer);
  EXPECT_TRUE(got.criteria.internal_silhouettes);
  EXPECT_EQ(got.criteria.backface_factor, 2);
  EXPECT_EQ(got.criteria.hidden_factor, 16);
  EXPECT_EQ(got.budget, 50'000u);
  EXPECT_TRUE(got.normals && got.labels);
  EXPECT_EQ(got.draco.method, core::codec::DracoMethod::kSequential);
  EXPECT_EQ(got.draco.speed, 3);
  EXPECT_EQ(got.quantization.position_bits, 12);
  EXPECT_EQ(got.draco.entropy_coding, false);
}

TEST(ParseRequest, EveryRequestTypeRoundTrips) {
  const Limits limits;
  const std::vector<Request> requests = {Hello{1, "test", ""},
                                         ListModels{},
                                         ModelInfo{"dragon"},
                                         sample_extract(),
                                         Gaze{0.1, 0.9, 12.0, 0.5},
                                         Cancel{77},
                                         Stats{},
                                         Ping{},
                                         Reload{"admin"}};
  std::vector<bool> seen(std::variant_size_v<Request>);
  for (const Request& r : requests) {
    const auto parsed = parse_request(to_json(r, 5), limits);
    ASSERT_TRUE(parsed.ok()) << request_type_name(r) << ": " << parsed.error().message;
    EXPECT_EQ(parsed->request.index(), r.index());
    seen[r.index()] = true;
  }
  for (std::size_t i = 0; i < seen.size(); ++i) EXPECT_TRUE(seen[i]) << kRequestTypeNames[i] << " not tried";
  EXPECT_EQ(std::get<Reload>(parse_request(to_json(Reload{"admin"}, 5), limits)->request).token, "admin");
  const auto gaze = std::get<Gaze>(parse_request(to_json(Gaze{0.1, 0.9, 12.0, 0.5}, 5), limits)->request);
  EXPECT_EQ(gaze.x, 0.1);
  EXPECT_EQ(gaze.distance, 12.0);
  EXPECT_EQ(std::get<Cancel>(parse_request(to_json(Cancel{77}, 5), limits)->request).target, 77u);
}

TEST(ParseRequest, DefaultsFillWhatAMinimalExtractLeavesOut) {
  const auto parsed = parse_request(
      R"({"type":"extract","id":1,"model":"bunny","error":0.01,
          "camera":{"view":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,-3,1],"projection":[1,0,0,0,0,1,0,0,0,0,-1,-1,0,0,-0.2,0]}})",
      Limits{});
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  const auto& e = std::get<Extract>(parsed->request);
  const Extract defaults;
  EXPECT_EQ(e.grid, defaults.grid);
  EXPECT_EQ(e.error_unit, core::view::ErrorUnits::kModel);
  for (const core::view::Criterion c : core::view::kAllCriteria) EXPECT_FALSE(e.criteria.regions[c]);
  EXPECT_FALSE(e.budget);
  EXPECT_FALSE(e.draco.method);
  EXPECT_FALSE(e.draco.entropy_coding);
}

// A criterion named with nothing else (true, or a point) takes its table's defaults.
TEST(ParseRequest, CriteriaTakeTheDefaultsOfTheTable) {
  for (const core::view::Criterion c : core::view::kAllCriteria) {
    const bool points = core::view::traits(c).seeds == core::view::Seeds::kPoints;
    nlohmann::json request = nlohmann::json::parse(
        R"({"type":"extract","id":1,"model":"bunny","error":0.01,
            "camera":{"view":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,-3,1],"projection":[1,0,0,0,0,1,0,0,0,0,-1,-1,0,0,-0.2,0]}})");
    request["criteria"][wire(c).name] =
        points ? nlohmann::json{{"x", 0.25}, {"y", 0.5}} : nlohmann::json(true);
    const auto parsed = parse_request(request.dump(), Limits{});
    ASSERT_TRUE(parsed.ok()) << wire(c).name << ": " << parsed.error().message;
    const Criteria& got = std::get<Extract>(parsed->request).criteria;
    Region expected{wire(c).distance, wire(c).factor, {}};
    if (points) expected.points = {{0.25, 0.5}};
    for (const core::view::Criterion other : core::view::kAllCriteria) {
      if (other == c) {
        ASSERT_TRUE(got.regions[c]) << wire(c).name;
        EXPECT_EQ(*got.regions[c], expected) << wire(c).name;
      } else {
        EXPECT_FALSE(got.regions[other]) << wire(other).name << " with only " << wire(c).name << " given";
      }
    }
    // A factor outside the table's range is refused with the field's name.
    nlohmann::json& entry = request["criteria"][wire(c).name];
    if (!points) entry = nlohmann::json::object();
    entry["factor"] = wire(c).factor_max + 1;
    const auto refused = parse_request(request.dump(), Limits{});
    ASSERT_FALSE(refused.ok()) << wire(c).name;
    EXPECT_NE(refused.error().message.find(fmt::format("'criteria.{}.factor'", wire(c).name)),
              std::string::npos)
        << refused.error().message;
  }
}

// PROTOCOL.md's table of criteria has one row per entry of the table, and no other.
TEST(ParseRequest, TheDocumentedCriteriaAreTheTable) {
  std::ifstream in(test::protocol_document());
  const std::regex row(R"(^\|\s*`criteria\.([a-z_]+)`\s*\|)");
  std::set<std::string> documented, table;
  std::string line;
  bool in_criteria = false;
  while (std::getline(in, line)) {
    if (line.rfind("#### Criteria", 0) == 0)
      in_criteria = true;
    else if (line.rfind("#", 0) == 0)
      in_criteria = false;
    std::smatch m;
    if (in_criteria && std::regex_search(line, m, row)) documented.insert(m[1]);
  }
  for (const CriterionWire& w : kCriterionWire) table.insert(w.name);
  EXPECT_EQ(documented, table);
}

TEST(ParseRequest, TheCodecRoundTrips) {
  for (std::size_t i = 0; i < kCodecNames.size(); ++i) {
    Extract e = sample_extract();
    e.codec = static_cast<core::codec::Codec>(i);
    e.labels = false;  // meshopt carries none
    const auto parsed = parse_request(to_json(e, 3), Limits{});
    ASSERT_TRUE(parsed.ok()) << kCodecNames[i] << ": " << parsed.error().message;
    EXPECT_EQ(std::get<Extract>(parsed->request).codec, e.codec) << kCodecNames[i];
  }
  Extract fine = sample_extract();
  fine.labels = false;
  fine.codec = core::codec::Codec::kMeshopt;
  fine.quantization.position_bits = 17;
  const auto refused = parse_request(to_json(fine, 4), Limits{});
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("at most 16 bits"), std::string::npos) << refused.error().message;
}

TEST(ParseRequest, AnExtractWithoutACodecLeavesItToTheConnection) {
  Extract e = sample_extract();
  e.codec.reset();
  const auto parsed = parse_request(to_json(e, 5), Limits{});
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_FALSE(std::get<Extract>(parsed->request).codec.has_value());
  // The connection's codec is checked against the extract with the parser's own rule.
  e.labels = true;
  EXPECT_FALSE(codec_refusal(e, core::codec::Codec::kDraco).has_value());
  ASSERT_TRUE(codec_refusal(e, core::codec::Codec::kMeshopt).has_value());
  EXPECT_NE(codec_refusal(e, core::codec::Codec::kMeshopt)->find("labels"), std::string::npos);

  for (std::size_t i = 0; i < kCodecNames.size(); ++i) {
    const Hello hello{1, "test", "", static_cast<core::codec::Codec>(i)};
    const auto read = parse_request(to_json(hello, 6), Limits{});
    ASSERT_TRUE(read.ok()) << read.error().message;
    EXPECT_EQ(std::get<Hello>(read->request).codec, hello.codec) << kCodecNames[i];
  }
  const auto unknown = parse_request(R"({"type":"hello","id":7,"version":1,"codec":"zstd"})", Limits{});
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.error().message.find("'codec' is 'zstd'"), std::string::npos) << unknown.error().message;
}

TEST(ParseRequest, QuantizationIsReadUnderEitherName) {
  const std::string head =
      R"({"type":"extract","id":1,"model":"bunny","error":0.01,"camera":{"view":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,-3,1],)"
      R"("projection":[1,0,0,0,0,1,0,0,0,0,-1,-1,0,0,-0.2,0]})";
  const auto quantization = [](const Result<ParsedRequest, ProtocolError>& parsed) {
    EXPECT_TRUE(parsed.ok()) << parsed.error().message;
    const Quantization q = std::get<Extract>(parsed->request).quantization;
    return std::pair(q.position_bits, q.normal_bits);
  };
  EXPECT_EQ(quantization(parse_request(head + "}", Limits{})), std::pair(14, 10));
  EXPECT_EQ(quantization(
                parse_request(head + R"(,"quantization":{"position_bits":11,"normal_bits":7}})", Limits{})),
            std::pair(11, 7));
  EXPECT_EQ(quantization(parse_request(head + R"(,"draco":{"position_bits":12,"normal_bits":8}})", Limits{})),
            std::pair(12, 8));
  EXPECT_FALSE(parse_request(head + R"(,"quantization":{"position_bits":21}})", Limits{}).ok());
  EXPECT_FALSE(parse_request(head + R"(,"quantization":{"bits":12}})", Limits{}).ok());  // unknown field
}

TEST(ParseRequest, LimitsComeFromTheServerConfiguration) {
  Extract e = sample_extract();
  e.grid = {600, 600};
  Limits limits;
  limits.max_grid = 512;
  const auto parsed = parse_request(to_json(e, 9), limits);
  ASSERT_FALSE(parsed.ok());
  EXPECT_EQ(parsed.error().code, ErrorKind::kLimitExceeded);
  EXPECT_EQ(parsed.error().message, "grid[0] 600 exceeds the server limit 512");
  EXPECT_EQ(parsed.error().request_id, 9u);
}

// A scene of three instances as a client writes it; without labels, which a scene refuses.
Extract sample_scene() {
  Extract e = sample_extract();
  e.model.clear();
  e.labels = false;
  e.instances = {{"bunny", {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 1, 2, 3, 1}},
                 {"dragon", {0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1, 0, -4, 0, 0.5, 1}},
                 {"bunny", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}};
  return e;
}

TEST(ParseRequest, AScenesInstancesRoundTrip) {
  const Extract e = sample_scene();
  const auto parsed = parse_request(to_json(e, 3), Limits{});
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  const auto& got = std::get<Extract>(parsed->request);
  EXPECT_TRUE(got.model.empty());
  EXPECT_EQ(got.instances, e.instances);
  EXPECT_EQ(got.budget, e.budget);
  // A matrix left out is the identity.
  const auto minimal = parse_scene(R"({"instances": [{"model": "bunny"}]})", Limits{});
  ASSERT_TRUE(minimal.ok()) << minimal.error().message;
  ASSERT_EQ(minimal->size(), 1u);
  EXPECT_EQ((*minimal)[0], (Instance{"bunny", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}));
}

TEST(ParseRequest, AScenePastTheInstanceLimitIsRefusedWhole) {
  Limits limits;
  limits.max_instances = 2;
  const auto parsed = parse_request(to_json(sample_scene(), 4), limits);
  ASSERT_FALSE(parsed.ok());
  EXPECT_EQ(parsed.error().code, ErrorKind::kLimitExceeded);
  EXPECT_EQ(parsed.error().message, "3 scene instances exceed the server limit 2");
  const auto file = parse_scene(R"({"instances": [{"model": "a"}, {"model": "b"}, {"model": "c"}]})", limits);
  ASSERT_FALSE(file.ok());
  EXPECT_EQ(file.error().code, ErrorKind::kLimitExceeded);
  const auto broken = parse_scene(R"({"instances": [{"model": "a", "matrix": [1, 2]}]})", Limits{});
  ASSERT_FALSE(broken.ok());
  EXPECT_EQ(broken.error().message,
            "scene.instances[0].matrix must be an array of 16 numbers (column-major), got 2 elements");
  EXPECT_EQ(parse_scene("{\"instances\": [", Limits{}).error().code, ErrorKind::kBadJson);
}

TEST(ParseRequest, EveryMalformedCaseInTheDocumentGetsItsCode) {
  const std::vector<test::MalformedCase> cases = test::malformed_cases();
  ASSERT_GE(cases.size(), 15u) << "PROTOCOL.md's table of malformed requests was not found";
  for (const test::MalformedCase& c : cases) {
    const auto parsed = parse_request(c.json, Limits{});
    if (c.code == "unknown_model" || c.code == "no_view") {
      EXPECT_TRUE(parsed.ok()) << c.json << " should parse: the server rejects it";
      continue;
    }
    ASSERT_FALSE(parsed.ok()) << c.json;
    EXPECT_EQ(to_string(parsed.error().code), c.code) << c.json << " -> " << parsed.error().message;
    EXPECT_NE(parsed.error().message.find(c.message_contains), std::string::npos)
        << c.json << " -> '" << parsed.error().message << "' lacks '" << c.message_contains << "'";
  }
}

TEST(ParseRequest, RandomBytesNeverThrowOrCrash) {
  std::mt19937 rng(11);
  const std::string valid = to_json(sample_extract(), 3);
  for (int round = 0; round < 2000; ++round) {
    std::string text = valid;
    const int edits = 1 + rng() % 4;
    for (int k = 0; k < edits; ++k) text[rng() % text.size()] = static_cast<char>(rng() % 256);
    const auto parsed = parse_request(text, Limits{});
    EXPECT_TRUE(parsed.ok() || !parsed.error().message.empty());
  }
}

}  // namespace
}  // namespace mtlod::protocol
