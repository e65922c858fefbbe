// mtlod-client: talks to mtlod-server from the command line: list models, describe one, extract a
// view-dependent mesh with the same camera and criteria flags as mtlod-extract.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "clients/common/extract_flags.hpp"
#include "clients/common/retry.hpp"
#include "clients/common/scene_view.hpp"
#include "core/codec/cut_encoder.hpp"
#include "core/io/gltf.hpp"
#include "core/io/mesh_io.hpp"
#include "fmt/format.h"
#include "protocol/parse.hpp"

namespace {

using namespace mtlod;

int fail(const std::string& message) {
  fmt::print(stderr, "mtlod-client: {}\n", message);
  return 1;
}

// Prints an error reply and returns true when the frame is one.
bool is_error(const clients::ReplyFrame& frame) {
  if (const auto* e = std::get_if<protocol::ErrorReply>(&frame.header.reply)) {
    fmt::print(stderr, "mtlod-client: server error {}: {}\n", protocol::to_string(e->code), e->message);
    return true;
  }
  return false;
}

// `mtlod-client scene`: one request for the whole scene (the camera flags' defaults frame its
// bounding box), a line per instance, and with -o a .glb of a node per instance.
int fetch_scene(clients::RetryingConnection& c, const std::string& file, clients::ExtractFlags& flags,
                const std::string& output) {
  auto instances = clients::read_scene_file(file);
  if (!instances) return fail(instances.error().message);
  clients::apply_default_criteria(flags);
  const auto info = [&c](const std::string& model) {
    return clients::model_info_reply(c.call(protocol::ModelInfo{model}));
  };
  auto scene = clients::describe_scene(info, file, *instances, flags);
  if (!scene) return fail(scene.error().message);
  const protocol::Extract& request = scene->extract;
  auto reply = c.call(request, std::chrono::seconds(120));
  if (!reply) return fail(reply.error().message);
  if (is_error(*reply)) return 1;
  const auto& mesh = std::get<protocol::MeshReply>(reply->header.reply);
  auto parts = protocol::split_scene_payload(mesh, reply->payload);
  if (!parts) return fail(parts.error().message);
  const auto& t = mesh.timings;
  fmt::print(
      "scene: {} instances, {} triangles, {} bytes{}; server µs: occupancy {} dt {} refine {} encode {} "
      "total {}\n",
      mesh.instances.size(), mesh.triangles, mesh.bytes, mesh.within_budget ? "" : " (over the budget)",
      t.occupancy_us, t.dt_us, t.refine_us, t.encode_us, t.total_us);
  std::vector<core::model::Mesh> meshes;
  for (std::size_t i = 0; i < mesh.instances.size(); ++i) {
    const protocol::InstanceMesh& one = mesh.instances[i];
    fmt::print("  {:>4} {:<16} {:>8} triangles {:>9} bytes  max error {:.4g}\n", i, one.model, one.triangles,
               one.bytes, one.max_error);
    if (output.empty()) continue;
    std::span<const std::uint8_t> part = (*parts)[i];
    if (one.delta) {
      auto split = protocol::split_delta_payload(*one.delta, part);
      if (!split) return fail(split.error().message);
      part = split->mesh;
    }
    auto decoded = core::codec::decode_payload(mesh.codec, part);
    if (!decoded) return fail(fmt::format("instance {}: {}", i, decoded.error().message));
    meshes.push_back(std::move(*decoded));
  }
  if (output.empty()) return 0;
  if (std::filesystem::path(output).extension() != ".glb")
    return fail(output + ": a scene is written as .glb");
  std::vector<core::io::GlbInstance> nodes;
  for (std::size_t i = 0; i < meshes.size(); ++i)
    nodes.push_back(
        {&meshes[i], request.instances[i].matrix, fmt::format("{} {}", i, mesh.instances[i].model)});
  if (auto saved = core::io::write_glb_scene(output, nodes); !saved) return fail(saved.error().message);
  fmt::print("wrote {}\n", output);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"mtlod-client: query mtlod-server and fetch view-dependent extractions."};
  std::string model, output;
  clients::Endpoint endpoint;
  clients::add_endpoint_flags(app, endpoint);
  clients::RetryPolicy retry;
  retry.attempts = 5;
  app.add_option(
         "--attempts", retry.attempts,
         "tries per request: a dropped connection or a draining server (shutting_down) makes the client "
         "reconnect with backoff and send the request again")
      ->capture_default_str()
      ->check(CLI::Range(1u, 100u));
  app.require_subcommand(1);
  auto* list = app.add_subcommand("list", "list the server's models");
  auto* info = app.add_subcommand("info", "describe one model");
  info->add_option("model", model, "model name")->required();
  auto* stats = app.add_subcommand("stats", "print the server's counters");
  std::string admin_token;
  auto* reload = app.add_subcommand("reload", "load changed model files now (as SIGHUP does)");
  reload->add_option("--admin-token", admin_token, "a token of the server's --admin-tokens file")->required();
  auto* extract = app.add_subcommand("extract", "fetch a view-dependent extraction");
  extract->add_option("model", model, "model name")->required();
  extract->add_option("-o,--output", output,
                      "write the mesh: .drc or .mopt (as received, by --codec), .ply or .obj (decoded), or "
                      ".glb (binary glTF 2.0 with the normals and colours the reply carries)");
  std::string gltf_compression = "on";
  extract
      ->add_option("--gltf-compression,--gltf-draco", gltf_compression,
                   "on: the .glb embeds the payload as received (Draco: KHR_draco_mesh_compression; meshopt: "
                   "EXT_meshopt_compression); off: decoded into plain arrays, for readers without either")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  clients::ExtractFlags flags;
  clients::add_extract_flags(*extract, flags);
  std::string scene_file;
  auto* scene = app.add_subcommand("scene", "fetch a view of a scene: one mesh per instance, one request");
  scene
      ->add_option(
          "scene", scene_file,
          "JSON file {\"instances\": [{\"model\": NAME, \"matrix\": [16 numbers, column-major]}, ...]}")
      ->required()
      ->check(CLI::ExistingFile);
  scene->add_option("-o,--output", output, "write the scene as .glb: a node per instance with its matrix");
  clients::add_extract_flags(*scene, flags);
  CLI11_PARSE(app, argc, argv);

  // Every request here is idempotent, so each is retried on a new connection when one drops.
  clients::RetryingConnection c(endpoint, "mtlod-client/0.1", retry);

  if (*list) {
    auto reply = c.call(protocol::ListModels{});
    if (!reply) return fail(reply.error().message);
    if (is_error(*reply)) return 1;
    fmt::print("{:<16} {:>10} {:>12} {:>8} {:>9} {:>10} {:>10} {:>8}\n", "model", "vertices", "triangles",
               "root", "nodes", "MiB", "max error", "version");
    for (const auto& m : std::get<protocol::ModelsReply>(reply->header.reply).models) {
      fmt::print("{:<16} {:>10} {:>12} {:>8} {:>9} {:>10.1f} {:>10.4g} {:>8}\n", m.name, m.vertices,
                 m.input_triangles, m.root_triangles, m.nodes, m.memory_bytes / 1048576.0, m.max_error,
                 m.version);
    }
    return 0;
  }
  if (*reload) {
    auto reply = c.call(protocol::Reload{admin_token});
    if (!reply) return fail(reply.error().message);
    if (is_error(*reply)) return 1;
    for (const auto& m : std::get<protocol::ReloadReply>(reply->header.reply).models) {
      fmt::print("{:<16} {:<10} version {}{}\n", m.name, m.change, m.version,
                 m.message.empty() ? "" : "  (" + m.message + ")");
    }
    return 0;
  }
  if (*stats) {
    auto reply = c.call(protocol::Stats{});
    if (!reply) return fail(reply.error().message);
    if (is_error(*reply)) return 1;
    for (const auto& [name, value] : std::get<protocol::StatsReply>(reply->header.reply).counters) {
      fmt::print("{:<28} {}\n", name, value);
    }
    return 0;
  }

  if (*scene) return fetch_scene(c, scene_file, flags, output);

  auto described = c.call(protocol::ModelInfo{model});
  if (!described) return fail(described.error().message);
  if (is_error(*described)) return 1;
  const auto& m = std::get<protocol::ModelInfoReply>(described->header.reply);
  if (*info) {
    fmt::print("{}: {} vertices, {} input triangles, {} root triangles, {} nodes, {:.1f} MiB\n", m.model.name,
               m.model.vertices, m.model.input_triangles, m.model.root_triangles, m.model.nodes,
               m.model.memory_bytes / 1048576.0);
    fmt::print(
        "bounds [{:.4g} {:.4g} {:.4g}] .. [{:.4g} {:.4g} {:.4g}], error {:.4g} .. {:.4g}, normals {}, "
        "colours {}\n",
        m.bounds_min[0], m.bounds_min[1], m.bounds_min[2], m.bounds_max[0], m.bounds_max[1], m.bounds_max[2],
        m.min_error, m.model.max_error, m.normals ? "yes" : "no", m.colors ? "yes" : "no");
    return 0;
  }

  // The criteria the flags leave open are the clients' defaults (1 px, a foveal focus at the centre).
  clients::apply_default_criteria(flags);
  auto request = clients::make_extract(flags, model, m.bounds_min, m.bounds_max);
  if (!request) return fail(request.error().message);
  const auto start = std::chrono::steady_clock::now();
  auto reply = c.call(*request, std::chrono::seconds(120));
  if (!reply) return fail(reply.error().message);
  if (is_error(*reply)) return 1;
  const double round_trip_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  const auto& mesh = std::get<protocol::MeshReply>(reply->header.reply);
  const auto& t = mesh.timings;
  fmt::print("{}: {} triangles, {} vertices, {} bytes ({:.1f} bits/triangle), max error {:.4g}\n", mesh.model,
             mesh.triangles, mesh.vertices, mesh.bytes,
             8.0 * mesh.bytes / std::max<std::uint64_t>(1, mesh.triangles), mesh.max_error);
  fmt::print(
      "server µs: queue {} map {} occupancy {} dt {} labels {} refine {} encode {} total {}; round trip "
      "{:.2f} ms\n",
      t.queue_us, t.map_us, t.occupancy_us, t.dt_us, t.labels_us, t.refine_us, t.encode_us, t.total_us,
      round_trip_ms);
  fmt::print("server memory: {:.1f} MiB for this connection's cut, {:.1f} MiB of worker scratch\n",
             mesh.session_bytes / 1048576.0, mesh.scratch_bytes / 1048576.0);
  fmt::print("served by {}{}\n", c.hello().instance,
             c.retries() ? fmt::format(" after {} retr{}", c.retries(), c.retries() == 1 ? "y" : "ies") : "");
  if (!output.empty()) {
    // A delta reply (--delta) starts from an empty mesh here: its mesh part is the whole cut.
    std::span<const std::uint8_t> payload = reply->payload;
    if (mesh.delta) {
      auto parts = protocol::split_delta_payload(*mesh.delta, reply->payload);
      if (!parts) return fail(parts.error().message);
      payload = parts->mesh;
      fmt::print("delta: {} triangles added, {} removed (ids follow the mesh in the payload)\n",
                 mesh.delta->added, mesh.delta->removed);
    }
    const std::string ext = std::filesystem::path(output).extension().string();
    if (const auto file_codec = core::codec::codec_of_file(ext); file_codec == mesh.codec) {
      std::ofstream out(output, std::ios::binary);
      out.write(reinterpret_cast<const char*>(payload.data()), static_cast<std::streamsize>(payload.size()));
      if (!out) return fail(fmt::format("{}: write failed", output));
    } else if (file_codec) {
      return fail(fmt::format("{}: the payload is {}; write it as {} or as a mesh file", output,
                              protocol::enum_name(protocol::kCodecNames, mesh.codec),
                              core::codec::traits(mesh.codec).file_extension));
    } else if (ext == ".glb" && gltf_compression == "on") {
      if (auto saved = core::io::write_glb_payload(output, mesh.codec, payload); !saved)
        return fail(saved.error().message);
    } else {
      auto decoded = core::codec::decode_payload(mesh.codec, payload);
      if (!decoded) return fail(decoded.error().message);
      auto saved =
          ext == ".glb" ? core::io::write_glb(output, *decoded) : core::io::save_mesh(output, *decoded);
      if (!saved) return fail(saved.error().message);
    }
    fmt::print("wrote {}\n", output);
  }
  return 0;
}
