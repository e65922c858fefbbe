// .glb files written by core/io/gltf read back as the mesh that was written: the container by hand
// (GLB header and chunks); plain files through tinygltf's loader (the same positions, triangles,
// colours, and unit normals); Draco files through their JSON (the payload embedded byte for byte,
// decoding to the mesh, accessors and attribute ids that describe it); and every variant through
// the Khronos glTF validator with no error and no warning.
#include "core/io/gltf.hpp"

#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include "core/codec/draco_decode.hpp"
#include "core/codec/draco_encode.hpp"
#include "core/codec/meshopt_encode.hpp"
#include "core/eval/mesh_gen.hpp"
#include "nlohmann/json.hpp"
#include "tests/core/mesh_compare.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core::io {
namespace {

using nlohmann::json;

struct Variant {
  bool normals = false;
  bool colors = false;
};

std::string name_of(const Variant& v) {
  return std::string(v.normals ? "normals" : "no-normals") + (v.colors ? "-colors" : "-no-colors");
}

// Both writers with and without each optional attribute; gtest names may not contain '-'.
const auto kEveryVariant =
    testing::Values(Variant{false, false}, Variant{true, false}, Variant{false, true}, Variant{true, true});
std::string test_name(const testing::TestParamInfo<Variant>& info) {
  std::string name = name_of(info.param);
  std::erase(name, '-');
  return name;
}

// A noisy sphere with distinct colours per vertex and, when asked, normals of every length: the
// normalised position scaled by 1, 2 or 3, except vertex 0 whose normal is zero.
model::Mesh test_mesh(const Variant& variant) {
  eval::GenerateOptions o;
  o.target_triangles = 2'000;
  model::Mesh m = eval::generate_mesh(o);
  for (std::size_t v = 0; variant.normals && v < m.vertex_count(); ++v) {
    const float* p = &m.positions[3 * v];
    const float scale = v == 0 ? 0.0f : float(1 + v % 3) / std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    m.normals.insert(m.normals.end(), {p[0] * scale, p[1] * scale, p[2] * scale});
  }
  for (std::size_t v = 0; variant.colors && v < m.vertex_count(); ++v) {
    m.colors.insert(m.colors.end(), {std::uint8_t(v), std::uint8_t(7 * v + 1), std::uint8_t(13 * v + 2)});
  }
  return m;
}

// The same sphere with unit normals (the normalised position), for Draco, which stores directions.
model::Mesh unit_normals(model::Mesh m) {
  for (std::size_t v = 0; v < m.vertex_count() && m.has_normals(); ++v) {
    const float* p = &m.positions[3 * v];
    const float length = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    for (int c = 0; c < 3; ++c) m.normals[3 * v + c] = p[c] / length;
  }
  return m;
}

tinygltf::Model load(const std::filesystem::path& path) {
  tinygltf::Model model;
  std::string error, warning;
  tinygltf::TinyGLTF loader;
  EXPECT_TRUE(loader.LoadBinaryFromFile(&model, &error, &warning, path.string())) << error;
  EXPECT_EQ(warning, "");
  return model;
}

// The elements of an accessor with a buffer view, `components` values of T each, through its stride.
template <class T>
std::vector<T> read_accessor(const tinygltf::Model& model, int index, int components) {
  const tinygltf::Accessor& a = model.accessors.at(index);
  const tinygltf::BufferView& view = model.bufferViews.at(a.bufferView);
  const std::vector<unsigned char>& data = model.buffers.at(view.buffer).data;
  const std::size_t element = components * sizeof(T);
  const std::size_t stride = view.byteStride ? view.byteStride : element;
  const std::size_t start = view.byteOffset + a.byteOffset;
  if (a.count == 0 ||
      start + (a.count - 1) * stride + element > std::min(data.size(), view.byteOffset + view.byteLength)) {
    ADD_FAILURE() << "accessor " << index << " reaches past its view";
    return {};
  }
  std::vector<T> out(a.count * components);
  for (std::size_t i = 0; i < a.count; ++i)
    std::memcpy(&out[i * components], &data[start + i * stride], element);
  return out;
}

// The bounds glTF requires on POSITION, computed here from the mesh.
void expect_position_bounds(const tinygltf::Accessor& a, const std::vector<float>& positions) {
  std::vector<double> lo(3, INFINITY), hi(3, -INFINITY);
  for (std::size_t i = 0; i < positions.size(); ++i) {
    lo[i % 3] = std::min<double>(lo[i % 3], positions[i]);
    hi[i % 3] = std::max<double>(hi[i % 3], positions[i]);
  }
  EXPECT_EQ(a.minValues, lo);
  EXPECT_EQ(a.maxValues, hi);
}

// One scene, one node, one mesh, one triangle primitive: what both variants share.
const tinygltf::Primitive& only_primitive(const tinygltf::Model& model) {
  EXPECT_EQ(model.asset.version, "2.0");
  EXPECT_EQ(model.defaultScene, 0);
  EXPECT_EQ(model.scenes.size(), 1u);
  EXPECT_EQ(model.nodes.size(), 1u);
  EXPECT_EQ(model.nodes.at(0).mesh, 0);
  EXPECT_EQ(model.meshes.size(), 1u);
  EXPECT_EQ(model.meshes.at(0).primitives.size(), 1u);
  const tinygltf::Primitive& p = model.meshes.at(0).primitives.at(0);
  EXPECT_EQ(p.mode, TINYGLTF_MODE_TRIANGLES);
  return p;
}

std::uint32_t u32_at(const std::string& bytes, std::size_t offset) {
  std::uint32_t v;
  std::memcpy(&v, bytes.data() + offset, 4);
  return v;
}

// A GLB split by hand into its JSON and BIN chunks. The Draco variant is read this way: tinygltf
// 2.7's loader (built without Draco) refuses an indices accessor without a buffer view, which is
// what KHR_draco_mesh_compression prescribes (the extension holds the data).
struct Glb {
  json gltf;
  std::string bin;
};

Glb split_glb(const std::string& bytes) {
  Glb glb;
  if (bytes.size() < 20 || bytes.substr(0, 4) != "glTF" || u32_at(bytes, 8) != bytes.size()) {
    ADD_FAILURE() << "not a GLB of " << bytes.size() << " bytes";
    return glb;
  }
  for (std::size_t at = 12; at + 8 <= bytes.size();) {
    const std::size_t length = u32_at(bytes, at);
    const std::string type = bytes.substr(at + 4, 4);
    if (at + 8 + length > bytes.size()) {
      ADD_FAILURE() << "chunk at " << at << " runs past the end";
      break;
    }
    if (type == "JSON") glb.gltf = json::parse(bytes.substr(at + 8, length));
    if (type == std::string("BIN\0", 4)) glb.bin = bytes.substr(at + 8, length);
    at += 8 + length;
  }
  return glb;
}

TEST(GltfGlb, TetrahedronFileIsHeaderJsonChunkAndBinChunkOfTheArrays) {
  // GLB 2.0: a 12-byte header (magic "glTF", version 2, total length), then chunks of (length, type,
  // data) padded to four bytes: JSON first, then BIN holding 4 positions (48 bytes) and 12 uint32
  // indices (48 bytes), nothing else for a mesh without normals and colours.
  const auto dir = test::scratch_dir("gltf-tetrahedron");
  ASSERT_TRUE(io::write_glb(dir / "t.glb", test::tetrahedron()).ok());
  const std::string bytes = test::read_file(dir / "t.glb");
  ASSERT_GE(bytes.size(), 28u);
  EXPECT_EQ(bytes.substr(0, 4), "glTF");
  EXPECT_EQ(u32_at(bytes, 4), 2u);
  EXPECT_EQ(u32_at(bytes, 8), bytes.size());
  const std::uint32_t json_length = u32_at(bytes, 12);
  EXPECT_EQ(json_length % 4, 0u);
  EXPECT_EQ(bytes.substr(16, 4), "JSON");
  ASSERT_EQ(bytes.size(), 20 + json_length + 8 + 96);
  EXPECT_EQ(u32_at(bytes, 20 + json_length), 96u);
  EXPECT_EQ(bytes.substr(24 + json_length, 4), std::string("BIN\0", 4));
  const core::model::Mesh t = test::tetrahedron();
  EXPECT_EQ(std::memcmp(bytes.data() + 28 + json_length, t.positions.data(), 48), 0);
  EXPECT_EQ(std::memcmp(bytes.data() + 28 + json_length + 48, t.triangles.data(), 48), 0);
}

class GltfPlain : public testing::TestWithParam<Variant> {};

TEST_P(GltfPlain, ReadsBackAsTheSameMesh) {
  const model::Mesh mesh = test_mesh(GetParam());
  const auto dir = test::scratch_dir("gltf-plain-" + name_of(GetParam()));
  const auto path = dir / "mesh.glb";
  const Status written = io::write_glb(path, mesh);
  ASSERT_TRUE(written.ok()) << written.error().message;
  const tinygltf::Model model = load(path);
  EXPECT_TRUE(model.extensionsUsed.empty());
  EXPECT_TRUE(model.extensionsRequired.empty());
  const tinygltf::Primitive& p = only_primitive(model);
  EXPECT_EQ(p.attributes.size(), 1u + mesh.has_normals() + mesh.has_colors());

  const int position = p.attributes.at("POSITION");
  EXPECT_EQ(model.accessors.at(position).componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
  EXPECT_EQ(model.accessors.at(position).type, TINYGLTF_TYPE_VEC3);
  EXPECT_EQ(read_accessor<float>(model, position, 3), mesh.positions);
  expect_position_bounds(model.accessors.at(position), mesh.positions);

  EXPECT_EQ(model.accessors.at(p.indices).componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
  EXPECT_EQ(model.accessors.at(p.indices).type, TINYGLTF_TYPE_SCALAR);
  EXPECT_EQ(read_accessor<std::uint32_t>(model, p.indices, 1), mesh.triangles);

  EXPECT_EQ(p.attributes.count("NORMAL"), mesh.has_normals() ? 1u : 0u);
  if (mesh.has_normals()) {
    const std::vector<float> normals = read_accessor<float>(model, p.attributes.at("NORMAL"), 3);
    ASSERT_EQ(normals.size(), mesh.normals.size());
    // glTF wants unit normals: each is the input's direction at length 1; the zero one is +Z. The
    // tolerance is a few float32 roundings of a division by the length.
    EXPECT_EQ(normals[0], 0.0f);
    EXPECT_EQ(normals[1], 0.0f);
    EXPECT_EQ(normals[2], 1.0f);
    for (std::size_t v = 1; v < mesh.vertex_count(); ++v) {
      const float* in = &mesh.normals[3 * v];
      const double length = std::sqrt(double(in[0]) * in[0] + double(in[1]) * in[1] + double(in[2]) * in[2]);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(normals[3 * v + c], in[c] / length, 1e-6) << "vertex " << v;
    }
  }

  EXPECT_EQ(p.attributes.count("COLOR_0"), mesh.has_colors() ? 1u : 0u);
  if (mesh.has_colors()) {
    const int color = p.attributes.at("COLOR_0");
    EXPECT_EQ(model.accessors.at(color).componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE);
    EXPECT_EQ(model.accessors.at(color).type, TINYGLTF_TYPE_VEC3);
    EXPECT_TRUE(model.accessors.at(color).normalized);
    EXPECT_EQ(read_accessor<std::uint8_t>(model, color, 3), mesh.colors);
  }
}

INSTANTIATE_TEST_SUITE_P(Attributes, GltfPlain, kEveryVariant, test_name);

class GltfDraco : public testing::TestWithParam<Variant> {};

TEST_P(GltfDraco, EmbedsThePayloadUnchangedAndItDecodesToTheMesh) {
  const model::Mesh mesh = unit_normals(test_mesh(GetParam()));
  // Labels ride along in the payload with normals and colours; glTF has no attribute for them.
  std::vector<std::uint32_t> labels(mesh.vertex_count());
  for (std::size_t v = 0; v < labels.size(); ++v) labels[v] = static_cast<std::uint32_t>(v % 5);
  codec::DracoOptions options;
  options.normals = mesh.has_normals();
  options.colors = mesh.has_colors();
  options.labels = mesh.has_normals() && mesh.has_colors();
  codec::DracoInput input;
  input.positions = mesh.positions;
  input.normals = mesh.normals;
  input.colors = mesh.colors;
  input.triangles = mesh.triangles;
  if (options.labels) input.labels = labels;
  std::vector<std::uint8_t> payload;
  const auto encoded = codec::DracoEncoder().encode(input, options, payload);
  ASSERT_TRUE(encoded.ok()) << encoded.error().message;

  const auto dir = test::scratch_dir("gltf-draco-" + name_of(GetParam()));
  const auto path = dir / "mesh.glb";
  const Status written = io::write_glb_draco(path, payload);
  ASSERT_TRUE(written.ok()) << written.error().message;
  const Glb glb = split_glb(test::read_file(path));
  const json& gltf = glb.gltf;
  ASSERT_TRUE(gltf.is_object());
  const json draco_only = {"KHR_draco_mesh_compression"};
  EXPECT_EQ(gltf.value("extensionsUsed", json()), draco_only);
  EXPECT_EQ(gltf.value("extensionsRequired", json()), draco_only);  // there is no uncompressed fallback
  EXPECT_EQ(gltf.at("asset").at("version"), "2.0");
  EXPECT_EQ(gltf.at("scene"), 0);
  EXPECT_EQ(gltf.at("scenes"), json::parse(R"([{"nodes": [0]}])"));
  EXPECT_EQ(gltf.at("nodes"), json::parse(R"([{"mesh": 0}])"));
  ASSERT_EQ(gltf.at("meshes").size(), 1u);
  ASSERT_EQ(gltf.at("meshes")[0].at("primitives").size(), 1u);
  const json& p = gltf.at("meshes")[0].at("primitives")[0];
  EXPECT_EQ(p.value("mode", 4), 4);  // triangles
  const json& extension = p.at("extensions").at("KHR_draco_mesh_compression");

  // The extension's view holds exactly the payload, and the one buffer is the BIN chunk.
  ASSERT_EQ(gltf.at("buffers").size(), 1u);
  EXPECT_FALSE(gltf.at("buffers")[0].contains("uri"));
  const json& view = gltf.at("bufferViews").at(extension.at("bufferView").get<std::size_t>());
  EXPECT_EQ(view.at("buffer"), 0);
  const std::size_t offset = view.value("byteOffset", 0u), length = view.at("byteLength");
  ASSERT_LE(offset + length, glb.bin.size());
  const std::vector<std::uint8_t> embedded(glb.bin.begin() + offset, glb.bin.begin() + offset + length);
  EXPECT_EQ(embedded, payload);

  // It decodes to the mesh: the same triangles over vertices within Draco's quantization, the same
  // colours, and normals within 10-bit quantization (as in draco_encode_test).
  const auto decoded = codec::decode_draco(embedded);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  const model::Mesh& out = decoded->mesh;
  const float tolerance = test::draco_tolerance(test::used_extent(mesh.positions, mesh.triangles), 14);
  const auto match =
      test::match_vertices(out.positions, mesh.positions, mesh.triangles, 4 * tolerance, tolerance);
  EXPECT_EQ(test::canonical_triangles(out.triangles, &match), test::canonical_triangles(mesh.triangles));
  ASSERT_EQ(out.has_colors(), mesh.has_colors());
  ASSERT_EQ(out.has_normals(), mesh.has_normals());
  for (std::size_t i = 0; i < out.vertex_count(); ++i) {
    const std::size_t v = match[i];
    if (v >= mesh.vertex_count()) continue;  // match_vertices has failed the test already
    for (int c = 0; c < 3 && mesh.has_colors(); ++c) EXPECT_EQ(out.colors[3 * i + c], mesh.colors[3 * v + c]);
    if (mesh.has_normals()) {
      const float* n = &out.normals[3 * i];
      EXPECT_GT(n[0] * mesh.normals[3 * v] + n[1] * mesh.normals[3 * v + 1] + n[2] * mesh.normals[3 * v + 2],
                0.9999f);
    }
  }

  // The accessors describe the decoded mesh without views of their own, and the extension names
  // each attribute by the id Draco gave it.
  const json& attributes = p.at("attributes");
  const json& ids = extension.at("attributes");
  std::vector<std::string> names;
  for (const auto& [name, accessor] : attributes.items()) names.push_back(name);
  std::vector<std::string> want;  // in key order, as nlohmann's objects iterate
  if (mesh.has_colors()) want.push_back("COLOR_0");
  if (mesh.has_normals()) want.push_back("NORMAL");
  want.push_back("POSITION");
  EXPECT_EQ(names, want);
  EXPECT_EQ(ids.size(), attributes.size());
  const json& accessors = gltf.at("accessors");
  for (const auto& [name, index] : attributes.items()) {
    const json& a = accessors.at(index.get<std::size_t>());
    EXPECT_FALSE(a.contains("bufferView")) << name;
    EXPECT_EQ(a.at("count"), out.vertex_count()) << name;
    EXPECT_EQ(a.at("type"), "VEC3") << name;
  }
  EXPECT_EQ(ids.at("POSITION"), decoded->attribute_ids.position);
  const json& position = accessors.at(attributes.at("POSITION").get<std::size_t>());
  EXPECT_EQ(position.at("componentType"), TINYGLTF_COMPONENT_TYPE_FLOAT);
  std::vector<double> lo(3, INFINITY), hi(3, -INFINITY);
  for (std::size_t i = 0; i < out.positions.size(); ++i) {
    lo[i % 3] = std::min<double>(lo[i % 3], out.positions[i]);
    hi[i % 3] = std::max<double>(hi[i % 3], out.positions[i]);
  }
  EXPECT_EQ(position.at("min").get<std::vector<double>>(), lo);
  EXPECT_EQ(position.at("max").get<std::vector<double>>(), hi);
  if (mesh.has_normals()) {
    EXPECT_EQ(ids.at("NORMAL"), decoded->attribute_ids.normal);
    EXPECT_EQ(accessors.at(attributes.at("NORMAL").get<std::size_t>()).at("componentType"),
              TINYGLTF_COMPONENT_TYPE_FLOAT);
  }
  if (mesh.has_colors()) {
    EXPECT_EQ(ids.at("COLOR_0"), decoded->attribute_ids.color);
    const json& color = accessors.at(attributes.at("COLOR_0").get<std::size_t>());
    EXPECT_EQ(color.at("componentType"), TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE);
    EXPECT_EQ(color.value("normalized", false), true);
  }
  const json& indices = accessors.at(p.at("indices").get<std::size_t>());
  EXPECT_FALSE(indices.contains("bufferView"));
  EXPECT_EQ(indices.at("count"), out.triangles.size());
  EXPECT_EQ(indices.at("componentType"), TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
  EXPECT_EQ(indices.at("type"), "SCALAR");
}

INSTANTIATE_TEST_SUITE_P(Attributes, GltfDraco, kEveryVariant, test_name);

TEST(GltfGlb, BadInputIsNamed) {
  const auto dir = test::scratch_dir("gltf-bad");
  model::Mesh mesh = test::tetrahedron();

  const auto missing = dir / "no-such-dir" / "t.glb";
  Status s = io::write_glb(missing, mesh);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kIoError);
  EXPECT_NE(s.error().message.find(missing.string() + ": cannot open for writing"), std::string::npos)
      << s.error().message;
  EXPECT_FALSE(std::filesystem::exists(missing));

  mesh.triangles[4] = 4;  // a tetrahedron has vertices 0..3
  s = io::write_glb(dir / "t.glb", mesh);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(s.error().message, "triangle 1 refers to vertex 4, but the mesh has 4 vertices");

  mesh = test::tetrahedron();
  mesh.positions[7] = NAN;
  s = io::write_glb(dir / "t.glb", mesh);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message, "vertex 2 has a non-finite coordinate");

  mesh.triangles.clear();
  s = io::write_glb(dir / "t.glb", mesh);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().message, "the mesh has no triangles");

  const std::vector<std::uint8_t> not_draco = {'n', 'o', 't', ' ', 'd', 'r', 'a', 'c', 'o'};
  s = io::write_glb_draco(dir / "d.glb", not_draco);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kCorrupt);
  EXPECT_FALSE(std::filesystem::exists(dir / "d.glb"));
  s = io::write_glb_meshopt(dir / "m.glb", not_draco);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kCorrupt);
  EXPECT_FALSE(std::filesystem::exists(dir / "m.glb"));
  EXPECT_FALSE(std::filesystem::exists(dir / "t.glb"));
}

// The Khronos validator (tests/core/gltf_validate.mjs) on `files`: its exit status (0: no error and
// no warning in any file, 77: not installed) and its report.
struct Validation {
  int status = -1;
  std::string report;
};

Validation khronos_validate(const std::vector<std::filesystem::path>& files,
                            const std::filesystem::path& dir) {
#ifdef MTLOD_NODE_BINARY
  const auto log = dir / "validator.log";
  std::string command =
      std::string(MTLOD_NODE_BINARY) + " " + MTLOD_SOURCE_DIR + "/tests/core/gltf_validate.mjs";
  for (const auto& f : files) command += " " + f.string();
  command += " > " + log.string() + " 2>&1";
  const int status = std::system(command.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, test::read_file(log)};
#else
  (void)files, (void)dir;
  return {77, "node was not found when the tests were configured"};
#endif
}

// Writes every variant: the tetrahedron, and the sphere plain, Draco- and meshopt-compressed, each
// with and without normals and colours.
std::vector<std::filesystem::path> write_every_variant(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> files = {dir / "tetrahedron.glb"};
  EXPECT_TRUE(io::write_glb(files[0], test::tetrahedron()).ok());
  for (const Variant v :
       {Variant{false, false}, Variant{true, false}, Variant{false, true}, Variant{true, true}}) {
    const model::Mesh mesh = test_mesh(v);
    files.push_back(dir / ("plain-" + name_of(v) + ".glb"));
    const Status plain = io::write_glb(files.back(), mesh);
    EXPECT_TRUE(plain.ok()) << plain.error().message;
    codec::DracoOptions options;
    options.normals = v.normals;
    options.colors = v.colors;
    const model::Mesh unit = unit_normals(mesh);
    codec::DracoInput input;
    input.positions = unit.positions;
    input.normals = unit.normals;
    input.colors = unit.colors;
    input.triangles = unit.triangles;
    std::vector<std::uint8_t> payload;
    EXPECT_TRUE(codec::DracoEncoder().encode(input, options, payload).ok());
    files.push_back(dir / ("draco-" + name_of(v) + ".glb"));
    const Status draco = io::write_glb_draco(files.back(), payload);
    EXPECT_TRUE(draco.ok()) << draco.error().message;
    codec::MeshoptOptions meshopt;
    meshopt.normals = v.normals;
    meshopt.colors = v.colors;
    EXPECT_TRUE(codec::MeshoptEncoder().encode(input, meshopt, payload).ok());
    files.push_back(dir / ("meshopt-" + name_of(v) + ".glb"));
    const Status streams = io::write_glb_meshopt(files.back(), payload);
    EXPECT_TRUE(streams.ok()) << streams.error().message;
  }
  return files;
}

TEST(GltfValidator, EveryVariantHasNoErrorAndNoWarning) {
  const auto dir = test::scratch_dir("gltf-validator");
  const auto files = write_every_variant(dir);
  const Validation v = khronos_validate(files, dir);
  if (v.status == 77) GTEST_SKIP() << v.report;
  std::cout << v.report;
  EXPECT_EQ(v.status, 0) << v.report;
  // One line per file saying so, whatever the exit status.
  std::size_t clean = 0;
  for (std::size_t at = 0; (at = v.report.find(": 0 errors, 0 warnings,", at)) != std::string::npos; ++at)
    ++clean;
  EXPECT_EQ(clean, files.size()) << v.report;
}

TEST(GltfValidator, ReportsABrokenFile) {
  // The check above must be able to fail: a file cut short by its last four bytes (the GLB header
  // still claims the full length) has errors.
  const auto dir = test::scratch_dir("gltf-validator-broken");
  ASSERT_TRUE(io::write_glb(dir / "whole.glb", test::tetrahedron()).ok());
  const std::string bytes = test::read_file(dir / "whole.glb");
  test::write_file(dir / "cut.glb", bytes.substr(0, bytes.size() - 4));
  const Validation v = khronos_validate({dir / "cut.glb"}, dir);
  if (v.status == 77) GTEST_SKIP() << v.report;
  EXPECT_EQ(v.status, 1) << v.report;
  EXPECT_EQ(v.report.find(": 0 errors"), std::string::npos) << v.report;
}

}  // namespace
}  // namespace mtlod::core::io
