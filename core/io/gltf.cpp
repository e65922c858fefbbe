// .glb writing (see gltf.hpp) with tinygltf, compiled here from Debian's header over the system
// nlohmann-json and without its image code (the TINYGLTF_NO_* switches come with mtlod_tinygltf in
// core/CMakeLists.txt, so that tests reading files back see the same declarations): the binaries
// load no tinygltf library at run time.
#include "core/io/gltf.hpp"

#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "core/codec/draco_decode.hpp"
#include "core/codec/meshopt_decode.hpp"
#include "fmt/format.h"
#include "nlohmann/json.hpp"

namespace mtlod::core::io {
namespace {

constexpr const char* kDracoExtension = "KHR_draco_mesh_compression";
constexpr const char* kMeshoptExtension = "EXT_meshopt_compression";
constexpr const char* kQuantizationExtension = "KHR_mesh_quantization";

// Appends `bytes` to the binary buffer as a view of its own. glTF wants vertex data on 4-byte
// boundaries: plain arrays here are all multiples of 4 bytes long, and a Draco payload is the only view.
int add_view(tinygltf::Model& model, std::span<const std::uint8_t> bytes, int target, std::size_t stride) {
  auto& data = model.buffers[0].data;
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = data.size();
  view.byteLength = bytes.size();
  view.byteStride = stride;
  view.target = target;
  data.insert(data.end(), bytes.begin(), bytes.end());
  model.bufferViews.push_back(std::move(view));
  return static_cast<int>(model.bufferViews.size() - 1);
}

int add_accessor(tinygltf::Model& model, int view, int component_type, int type, std::size_t count,
                 bool normalized = false) {
  tinygltf::Accessor accessor;
  accessor.bufferView = view;
  accessor.componentType = component_type;
  accessor.type = type;
  accessor.count = count;
  accessor.normalized = normalized;
  model.accessors.push_back(std::move(accessor));
  return static_cast<int>(model.accessors.size() - 1);
}

template <class T>
std::span<const std::uint8_t> as_bytes(std::span<const T> values) {
  return {reinterpret_cast<const std::uint8_t*>(values.data()), values.size_bytes()};
}

// The model around one primitive: scene, node, mesh, a plain material and the buffer. The default
// material is fully metallic and renders black in most viewers without an environment map.
tinygltf::Model make_model() {
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "mtlod";
  model.buffers.resize(1);
  tinygltf::Material material;
  material.pbrMetallicRoughness.metallicFactor = 0.0;
  material.doubleSided = true;  // cuts of scans have holes through which back faces show
  model.materials.push_back(std::move(material));
  tinygltf::Mesh mesh;
  mesh.primitives.resize(1);
  mesh.primitives[0].mode = TINYGLTF_MODE_TRIANGLES;
  mesh.primitives[0].material = 0;
  model.meshes.push_back(std::move(mesh));
  tinygltf::Node node;
  node.mesh = 0;
  model.nodes.push_back(std::move(node));
  tinygltf::Scene scene;
  scene.nodes = {0};
  model.scenes.push_back(std::move(scene));
  model.defaultScene = 0;
  return model;
}

// POSITION needs its bounds in the accessor (glTF 2.0 §3.7.2.1); they must be exactly the data's.
Status set_position_bounds(tinygltf::Accessor& accessor, std::span<const float> positions) {
  std::vector<double> lo(3, std::numeric_limits<double>::infinity());
  std::vector<double> hi(3, -std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (!std::isfinite(positions[i])) {
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("vertex {} has a non-finite coordinate", i / 3));
    }
    lo[i % 3] = std::min(lo[i % 3], double{positions[i]});
    hi[i % 3] = std::max(hi[i % 3], double{positions[i]});
  }
  accessor.minValues = std::move(lo);
  accessor.maxValues = std::move(hi);
  return Ok{};
}

Status check_triangles(std::span<const std::uint32_t> triangles, std::size_t vertices) {
  if (triangles.empty()) return make_error(ErrorCode::kInvalidArgument, "the mesh has no triangles");
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    if (triangles[i] >= vertices) {
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("triangle {} refers to vertex {}, but the mesh has {} vertices", i / 3,
                                    triangles[i], vertices));
    }
  }
  return Ok{};
}

// Rewrites the JSON chunk of a GLB (the first, right after the 12-byte header) with `edit`.
std::string edit_glb_json(const std::string& glb, const std::function<void(nlohmann::json&)>& edit) {
  auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, glb.data() + at, 4);
    return v;
  };
  const std::uint32_t json_bytes = u32(12);
  nlohmann::json json = nlohmann::json::parse(glb.substr(20, json_bytes));
  edit(json);
  std::string text = json.dump();
  text.resize((text.size() + 3) / 4 * 4, ' ');  // chunks end on four bytes; JSON pads with spaces
  std::string out = glb.substr(0, 12);
  const std::uint32_t text_bytes = static_cast<std::uint32_t>(text.size());
  out.append(reinterpret_cast<const char*>(&text_bytes), 4);
  out.append(glb, 16, 4);  // "JSON"
  out += text;
  out.append(glb, 20 + json_bytes);
  const std::uint32_t total = static_cast<std::uint32_t>(out.size());
  std::memcpy(out.data() + 8, &total, 4);
  return out;
}

// Serialises the model as GLB (its JSON then changed by `edit`, when given) and writes it; the file
// is only opened once the bytes exist.
Status write_model(const std::filesystem::path& path, const tinygltf::Model& model,
                   const std::function<void(nlohmann::json&)>& edit = {}) {
  std::ostringstream glb;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, glb, /*prettyPrint=*/false, /*writeBinary=*/true) || !glb) {
    return make_error(ErrorCode::kInternal,
                      fmt::format("{}: tinygltf could not serialise the mesh", path.string()));
  }
  const std::string bytes = edit ? edit_glb_json(std::move(glb).str(), edit) : std::move(glb).str();
  std::FILE* f = std::fopen(path.string().c_str(), "wb");
  if (!f) {
    return make_error(ErrorCode::kIoError,
                      fmt::format("{}: cannot open for writing: {}", path.string(), std::strerror(errno)));
  }
  bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  ok = (std::fclose(f) == 0) && ok;
  if (!ok) return make_error(ErrorCode::kIoError, fmt::format("{}: write failed", path.string()));
  return Ok{};
}

// What tinygltf cannot write (it writes a buffer's length as its data's, and no extensions of
// buffers or buffer views), added to the JSON afterwards: the fallback buffer's length and each
// view's EXT_meshopt_compression object.
struct MeshoptJson {
  std::size_t fallback_bytes = 0;
  std::vector<std::pair<int, nlohmann::json>> views;
};

// EXT_meshopt_compression: a view of the fallback buffer (1), `count` elements of `stride` bytes,
// whose data are `stream`, appended to the real buffer (0) and decoded with `mode` and `filter`.
int add_meshopt_view(tinygltf::Model& model, MeshoptJson& extra, std::span<const std::uint8_t> stream,
                     std::size_t count, std::size_t stride, const char* mode, const char* filter,
                     int target) {
  auto& data = model.buffers[0].data;
  nlohmann::json compressed = {{"buffer", 0},
                               {"byteOffset", data.size()},
                               {"byteLength", stream.size()},
                               {"byteStride", stride},
                               {"count", count},
                               {"mode", mode}};
  if (filter) compressed["filter"] = filter;
  data.insert(data.end(), stream.begin(), stream.end());
  // Each stream's data start on four bytes, as its fallback view does.
  data.resize((data.size() + 3) / 4 * 4);

  tinygltf::BufferView view;
  view.buffer = 1;
  view.byteOffset = extra.fallback_bytes;
  view.byteLength = count * stride;
  // Index views have no stride in glTF; the extension's byteStride still says each index's size.
  view.byteStride = target == TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER ? 0 : stride;
  view.target = target;
  extra.fallback_bytes += view.byteLength;
  model.bufferViews.push_back(std::move(view));
  const int index = static_cast<int>(model.bufferViews.size() - 1);
  extra.views.emplace_back(index, std::move(compressed));
  return index;
}

}  // namespace

namespace {

// The mesh's arrays as plain accessors of `primitive` (see write_glb).
Status add_plain_arrays(tinygltf::Model& model, const model::Mesh& mesh, tinygltf::Primitive& primitive) {
  const std::size_t n = mesh.vertex_count();
  assert(mesh.normals.empty() || mesh.normals.size() == 3 * n);
  assert(mesh.colors.empty() || mesh.colors.size() == 3 * n);
  MTLOD_RETURN_IF_ERROR(check_triangles(mesh.triangles, n));
  auto& attributes = primitive.attributes;

  const int position = add_accessor(
      model, add_view(model, as_bytes(std::span(mesh.positions)), TINYGLTF_TARGET_ARRAY_BUFFER, 0),
      TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);
  MTLOD_RETURN_IF_ERROR(set_position_bounds(model.accessors[position], mesh.positions));
  attributes["POSITION"] = position;

  if (mesh.has_normals()) {
    std::vector<float> unit(mesh.normals.size());
    for (std::size_t v = 0; v < n; ++v) {
      const float* in = &mesh.normals[3 * v];
      const float length = std::sqrt(in[0] * in[0] + in[1] * in[1] + in[2] * in[2]);
      float* out = &unit[3 * v];
      if (length > 0 && std::isfinite(length)) {
        for (int c = 0; c < 3; ++c) out[c] = in[c] / length;
      } else {
        out[0] = 0, out[1] = 0, out[2] = 1;
      }
    }
    attributes["NORMAL"] = add_accessor(
        model, add_view(model, as_bytes(std::span<const float>(unit)), TINYGLTF_TARGET_ARRAY_BUFFER, 0),
        TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);
  }

  if (mesh.has_colors()) {
    // Three bytes per vertex padded to four: vertex attributes must start on 4-byte boundaries.
    std::vector<std::uint8_t> rgbx(4 * n, 0);
    for (std::size_t v = 0; v < n; ++v) std::copy_n(&mesh.colors[3 * v], 3, &rgbx[4 * v]);
    attributes["COLOR_0"] = add_accessor(
        model, add_view(model, std::span<const std::uint8_t>(rgbx), TINYGLTF_TARGET_ARRAY_BUFFER, 4),
        TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC3, n, /*normalized=*/true);
  }

  primitive.indices = add_accessor(
      model, add_view(model, as_bytes(std::span(mesh.triangles)), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER, 0),
      TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, mesh.triangles.size());
  return Ok{};
}

}  // namespace

Status write_glb(const std::filesystem::path& path, const model::Mesh& mesh) {
  tinygltf::Model model = make_model();
  MTLOD_RETURN_IF_ERROR(add_plain_arrays(model, mesh, model.meshes[0].primitives[0]));
  return write_model(path, model);
}

Status write_glb_scene(const std::filesystem::path& path, std::span<const GlbInstance> instances) {
  if (instances.empty()) return make_error(ErrorCode::kInvalidArgument, "the scene has no instances");
  tinygltf::Model model = make_model();
  const tinygltf::Mesh mesh = model.meshes[0];
  model.meshes.clear();
  model.nodes.clear();
  model.scenes[0].nodes.clear();
  for (std::size_t i = 0; i < instances.size(); ++i) {
    model.meshes.push_back(mesh);
    const Status added = add_plain_arrays(model, *instances[i].mesh, model.meshes.back().primitives[0]);
    if (!added)
      return make_error(added.error().code, fmt::format("instance {}: {}", i, added.error().message));
    tinygltf::Node node;
    node.mesh = static_cast<int>(i);
    node.name = instances[i].name;
    node.matrix.assign(instances[i].matrix.begin(), instances[i].matrix.end());
    model.nodes.push_back(std::move(node));
    model.scenes[0].nodes.push_back(static_cast<int>(i));
  }
  return write_model(path, model);
}

Status write_glb_draco(const std::filesystem::path& path, std::span<const std::uint8_t> draco) {
  MTLOD_TRY(codec::DecodedMesh decoded, codec::decode_draco(draco));
  const model::Mesh& mesh = decoded.mesh;
  const std::size_t n = mesh.vertex_count();
  MTLOD_RETURN_IF_ERROR(check_triangles(mesh.triangles, n));
  tinygltf::Model model = make_model();
  tinygltf::Primitive& primitive = model.meshes[0].primitives[0];

  // Accessors without views: KHR_draco_mesh_compression gives their data, and they give its shape
  // (the types here are those Draco decodes to, which decoders such as three.js ask Draco for).
  tinygltf::Value::Object ids;
  const int position = add_accessor(model, -1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);
  MTLOD_RETURN_IF_ERROR(set_position_bounds(model.accessors[position], mesh.positions));
  primitive.attributes["POSITION"] = position;
  ids["POSITION"] = tinygltf::Value(decoded.attribute_ids.position);
  if (mesh.has_normals()) {
    primitive.attributes["NORMAL"] =
        add_accessor(model, -1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);
    ids["NORMAL"] = tinygltf::Value(decoded.attribute_ids.normal);
  }
  if (mesh.has_colors()) {
    primitive.attributes["COLOR_0"] = add_accessor(model, -1, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                                   TINYGLTF_TYPE_VEC3, n, /*normalized=*/true);
    ids["COLOR_0"] = tinygltf::Value(decoded.attribute_ids.color);
  }
  primitive.indices = add_accessor(model, -1, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR,
                                   mesh.triangles.size());

  // The payload is the buffer's one view (tinygltf pads the GLB chunk to four bytes).
  const int view = add_view(model, draco, /*target=*/0, /*stride=*/0);
  tinygltf::Value::Object extension;
  extension["bufferView"] = tinygltf::Value(view);
  extension["attributes"] = tinygltf::Value(std::move(ids));
  primitive.extensions[kDracoExtension] = tinygltf::Value(std::move(extension));
  model.extensionsUsed = {kDracoExtension};
  model.extensionsRequired = {kDracoExtension};
  return write_model(path, model);
}

Status write_glb_meshopt(const std::filesystem::path& path, std::span<const std::uint8_t> payload) {
  // Decoded whole first: only a payload that decodes is written, and the accessors' position bounds
  // are the stored values' own.
  MTLOD_TRY(const codec::DecodedMeshopt decoded, codec::decode_meshopt(payload));
  MTLOD_TRY(const codec::MeshoptPayload streams, codec::read_meshopt(payload));
  const std::size_t n = streams.vertex_count;
  tinygltf::Model model = make_model();
  tinygltf::Primitive& primitive = model.meshes[0].primitives[0];

  // The fallback buffer: no bytes, only a length (what the views decode into).
  model.buffers.resize(2);
  MeshoptJson extra;

  const int position = add_accessor(model,
                                    add_meshopt_view(model, extra, streams.positions, n, 8, "ATTRIBUTES",
                                                     nullptr, TINYGLTF_TARGET_ARRAY_BUFFER),
                                    TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC3, n);
  for (int k = 0; k < 3; ++k) {
    model.accessors[position].minValues.push_back(decoded.stored_min[k]);
    model.accessors[position].maxValues.push_back(decoded.stored_max[k]);
  }
  primitive.attributes["POSITION"] = position;
  if (streams.normal_stride != 0) {
    const bool wide = streams.normal_stride == 8;
    primitive.attributes["NORMAL"] =
        add_accessor(model,
                     add_meshopt_view(model, extra, streams.normals, n, streams.normal_stride, "ATTRIBUTES",
                                      "OCTAHEDRAL", TINYGLTF_TARGET_ARRAY_BUFFER),
                     wide ? TINYGLTF_COMPONENT_TYPE_SHORT : TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_TYPE_VEC3,
                     n, /*normalized=*/true);
  }
  if (streams.colors) {
    primitive.attributes["COLOR_0"] =
        add_accessor(model,
                     add_meshopt_view(model, extra, streams.colours, n, 4, "ATTRIBUTES", nullptr,
                                      TINYGLTF_TARGET_ARRAY_BUFFER),
                     TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC3, n, /*normalized=*/true);
  }
  const std::size_t indices = 3 * std::size_t{streams.triangle_count};
  primitive.indices = add_accessor(model,
                                   add_meshopt_view(model, extra, streams.triangles, indices, 4, "TRIANGLES",
                                                    nullptr, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER),
                                   TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, indices);

  // The stored q of a position is origin + q · step in the model's units: the node says so.
  tinygltf::Node& node = model.nodes[0];
  node.translation = {streams.origin[0], streams.origin[1], streams.origin[2]};
  node.scale = {streams.step, streams.step, streams.step};
  model.extensionsUsed = {kMeshoptExtension, kQuantizationExtension};
  model.extensionsRequired = {kMeshoptExtension, kQuantizationExtension};
  return write_model(path, model, [&](nlohmann::json& json) {
    json["buffers"][1] = {{"byteLength", extra.fallback_bytes},
                          {"extensions", {{kMeshoptExtension, {{"fallback", true}}}}}};
    for (auto& [view, compressed] : extra.views)
      json["bufferViews"][view]["extensions"][kMeshoptExtension] = std::move(compressed);
  });
}

Status write_glb_payload(const std::filesystem::path& path, codec::Codec codec,
                         std::span<const std::uint8_t> payload) {
  switch (codec) {
    case codec::Codec::kDraco:
      return write_glb_draco(path, payload);
    case codec::Codec::kMeshopt:
      return write_glb_meshopt(path, payload);
  }
  return make_error(ErrorCode::kInvalidArgument, "unknown codec");
}

}  // namespace mtlod::core::io
