// mtlod-server: serves view-dependent, Draco-compressed extractions of Multi-Tessellations over the
// protocol in protocol/PROTOCOL.md.
#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "protocol/parse.hpp"
#include "server/auth.hpp"
#include "server/log.hpp"
#include "server/model_registry.hpp"
#include "server/server.hpp"
#include "spdlog/spdlog.h"

namespace {

// Loads a token file or ends the process: a server must not start with access rules it cannot read.
std::shared_ptr<const mtlod::server::TokenTable> load_tokens(const std::string& file, const char* what) {
  auto tokens = mtlod::server::TokenTable::load(file);
  if (!tokens) {
    spdlog::error("{}", tokens.error().message);
    std::exit(1);
  }
  spdlog::info("{}: {} from {}", what, tokens->size(), file);
  return std::make_shared<const mtlod::server::TokenTable>(std::move(*tokens));
}

void log_model(const mtlod::server::Model& model) {
  const auto s = model.summary();
  const std::size_t mapped = model.mt.mapped_bytes();
  spdlog::info(
      "model {}: {} vertices, {} input triangles, {} root triangles, {} nodes, {:.1f} MiB in memory{}",
      s.name, s.vertices, s.input_triangles, s.root_triangles, s.nodes, s.memory_bytes / 1048576.0,
      mapped ? fmt::format(", {:.1f} MiB mapped from {} ({:.1f} bytes per input triangle)",
                           mapped / 1048576.0, model.path.string(),
                           static_cast<double>(mapped) /
                               static_cast<double>(std::max<std::uint64_t>(1, s.input_triangles)))
             : fmt::format(" ({:.1f} bytes per input triangle)",
                           static_cast<double>(s.memory_bytes) /
                               static_cast<double>(std::max<std::uint64_t>(1, s.input_triangles))));
}

// Written to a temporary name and renamed, so a reader never sees a half-written port.
bool write_port_file(const std::string& port_file, unsigned port, unsigned http_port) {
  const std::string temporary = port_file + ".tmp";
  std::FILE* f = std::fopen(temporary.c_str(), "w");
  if (!f) return false;
  std::fprintf(f, "%u\n", port);
  if (http_port) std::fprintf(f, "%u\n", http_port);
  std::fclose(f);
  return std::rename(temporary.c_str(), port_file.c_str()) == 0;
}

// What the command line says beyond the server's own configuration.
struct Options {
  mtlod::server::ServerConfig config;
  std::vector<std::string> model_files, meshes, scene_files;
  std::string models_dir, cache_dir = "build/models", log_level = "info", port_file;
  std::string name, tokens_file, admin_tokens_file;
  std::string log_format = "text", reload_mode = "watch";
};

// The flags, one statement each: long because the server has many, not because it decides much.
void add_options(CLI::App& app, Options& o) {
  mtlod::server::ServerConfig& config = o.config;
  app.add_option("models", o.model_files, "MT files to serve (model name = file stem)");
  app.add_option("--models", o.models_dir, "serve every .mt file in this directory");
  app.add_option(
         "--mesh", o.meshes,
         "a mesh (PLY/OBJ/OFF/STL) to serve; its MT is built into --cache-dir on first run and reused "
         "while newer than the mesh")
      ->take_all();
  app.add_option("--cache-dir", o.cache_dir, "where MT files built from --mesh go")->capture_default_str();
  app.add_option("--host", config.host, "address to listen on")->capture_default_str();
  app.add_option("--port", config.port, "TCP port for the protocol (0: any free port, printed at start)")
      ->capture_default_str();
  app.add_option(
      "--port-file", o.port_file,
      "write the bound port to this file once listening (for scripts and tests); with --http-port the "
      "HTTP port follows on a second line");
  app.add_option(
      "--http-port", config.http_port,
      "serve the browser viewer and the protocol over WebSocket (/ws) on this HTTP port (0: any free "
      "port); off when not given");
  config.web_root = MTLOD_DEFAULT_WEB_ROOT;
  app.add_option("--web-root", config.web_root,
                 "folder holding clients/web/ and scripts/node_modules/three/ (the viewer's files)")
      ->capture_default_str();
  app.add_option("--io-threads", config.io_threads, "threads serving sockets")->capture_default_str();
  app.add_option("--workers", config.workers, "threads computing extractions (0: one per core)")
      ->capture_default_str();
  auto& limits = config.limits;
  app.add_option("--max-frame-bytes", limits.max_frame_bytes,
                 "largest request frame (JSON + payload) accepted")
      ->capture_default_str();
  app.add_option("--max-connections", limits.max_connections, "connections served at once; more are refused")
      ->capture_default_str();
  app.add_option("--max-connections-per-address", limits.max_connections_per_address,
                 "connections one client address may hold (0: no cap; raise it behind a proxy that does "
                 "not pass client addresses)")
      ->capture_default_str();
  app.add_option("--max-in-flight", limits.max_in_flight, "unanswered requests allowed per connection")
      ->capture_default_str();
  app.add_option("--max-grid", limits.max_grid, "largest distance-transform grid side")
      ->capture_default_str();
  app.add_option("--max-budget", limits.max_budget, "largest triangle budget per extraction")
      ->capture_default_str();
  app.add_option("--max-foci", limits.max_foci, "most focus points plus neglect regions per request")
      ->capture_default_str();
  app.add_option("--max-instances", limits.max_instances, "most model instances in one scene request")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--max-memory", limits.max_memory_bytes,
                 "memory for worker scratch plus every connection's session (e.g. 4G, 512M); extractions "
                 "that could pass it are refused with limit_exceeded (default: half the RAM or cgroup limit)")
      ->transform(CLI::AsSizeValue(false));
  app.add_option("--idle-timeout-ms", limits.idle_timeout_ms, "close connections idle this long")
      ->capture_default_str();
  app.add_option("--first-frame-timeout-ms", limits.first_frame_timeout_ms,
                 "close a new connection (or HTTP keep-alive connection) that sends no request this long")
      ->capture_default_str();
  app.add_option("--read-timeout-ms", limits.read_timeout_ms, "a started frame must arrive within this time")
      ->capture_default_str();
  app.add_option("--drain-timeout-ms", config.drain_timeout_ms,
                 "on SIGINT/SIGTERM, in-flight work gets this long before connections are closed")
      ->capture_default_str();
  app.add_option(
         "--name", o.name,
         "this replica's name in hello replies and /health (letters, digits, '.', '_', '-'); default: the "
         "host name")
      ->check([](const std::string& value) {
        const bool plain =
            !value.empty() && value.size() <= 64 &&
            value.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-") ==
                std::string::npos;
        return plain ? std::string() : "a name of 1 to 64 letters, digits, '.', '_' or '-'";
      });
  app.add_option(
      "--tls-cert", config.tls_cert_file,
      "PEM certificate chain (leaf first): with --tls-key, the protocol and HTTP ports speak TLS only "
      "(https, wss)");
  app.add_option("--tls-key", config.tls_key_file, "PEM private key of --tls-cert (unencrypted)");
  app.add_option(
      "--auth-tokens", o.tokens_file,
      "access tokens, one per line: TOKEN [model ...] (# comments); connections are served only after "
      "a hello with a valid token (WebSocket: /ws?token=) and see only their token's models (all "
      "when none is listed)");
  app.add_option(
         "--proxy-protocol-from", config.proxy_protocol_from,
         "networks of trusted load balancers (CIDR, comma-separated or repeated: 10.0.0.0/8,::1/128): "
         "their connections must open with a PROXY protocol v2 header (HAProxy send-proxy-v2), sent "
         "within --first-frame-timeout-ms, and are served as the client address it names; other peers "
         "may not send one")
      ->delimiter(',')
      ->type_name("CIDR");
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error or off")->capture_default_str();
  app.add_option("--log-format", o.log_format,
                 "text, or json: one JSON object per line (time, level, msg; extraction lines carry their "
                 "fields as members)")
      ->check(CLI::IsMember({"text", "json"}))
      ->capture_default_str();
  app.add_option(
         "--scene", o.scene_files,
         "a scene extracts may name (\"scene\": NAME; NAME = file stem): JSON {\"instances\": [{\"model\", "
         "\"matrix\"}, ...]} as PROTOCOL.md's scenes; repeatable")
      ->check(CLI::ExistingFile);
  app.add_option("--admin-tokens", o.admin_tokens_file,
                 "tokens that may send the `reload` message, one per line (# comments); without them "
                 "`reload` is refused");
  app.add_option("--reload", o.reload_mode,
                 "when changed model files are loaded: watch (as soon as they change, inotify), or signal "
                 "(only on SIGHUP or a `reload` message, which work in both modes)")
      ->check(CLI::IsMember({"watch", "signal"}))
      ->capture_default_str();
}

// The replica's name: --name, else the host name without characters a name may not hold.
std::string replica_name(std::string name) {
  if (!name.empty()) return name;
  char host[256] = {};
  name = ::gethostname(host, sizeof host - 1) == 0 ? host : "mtlod";
  name.erase(std::remove_if(name.begin(), name.end(),
                            [](char c) {
                              return !std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' &&
                                     c != '-';
                            }),
             name.end());
  return name.empty() ? "mtlod" : name;
}

// Ends the process on a failed step of the start: a server must not run without what it was told to serve.
void check(const mtlod::Status& status) {
  if (!status) {
    spdlog::error("{}", status.error().message);
    std::exit(1);
  }
}

// The scene files, checked as a request's scene is; a model a scene names but no file gives is likely
// a typo (it is refused per request, as an unknown model is).
void load_scenes(Options& o, const mtlod::server::ModelRegistry& registry) {
  for (const std::string& file : o.scene_files) {
    std::ifstream in(file, std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    auto instances = mtlod::protocol::parse_scene(text, o.config.limits);
    if (!instances) {
      spdlog::error("{}: {}", file, instances.error().message);
      std::exit(1);
    }
    const std::string name = std::filesystem::path(file).stem().string();
    for (const auto& instance : *instances) {
      if (!registry.find(instance.model))
        spdlog::warn("{}: model '{}' is not loaded here", file, instance.model);
    }
    spdlog::info("scene {}: {} instances from {}", name, instances->size(), file);
    if (!o.config.scenes.emplace(name, std::move(*instances)).second) {
      spdlog::error("{}: a scene named '{}' was given already", file, name);
      std::exit(1);
    }
  }
}

// Loads the models and the token files the options name (ends the process when one fails).
void load(Options& o, mtlod::server::ModelRegistry& registry) {
  if (!o.models_dir.empty()) check(registry.add_directory(o.models_dir));
  for (const std::string& file : o.model_files) check(registry.add_file(file));
  for (const std::string& mesh : o.meshes) {
    const std::filesystem::path path(mesh);
    check(registry.add_mesh(path, std::filesystem::path(o.cache_dir) / (path.stem().string() + ".mt")));
  }
  if (registry.models().empty()) {
    spdlog::error("no models: give MT files, --models DIR or --mesh FILE");
    std::exit(1);
  }
  if (!o.tokens_file.empty()) {
    o.config.tokens = load_tokens(o.tokens_file, "access tokens");
    // A name no loaded model has is likely a typo; it may also be a model this replica lacks.
    for (const std::string& name : o.config.tokens->listed_models()) {
      if (!registry.find(name)) spdlog::warn("{}: model '{}' is not loaded here", o.tokens_file, name);
    }
  }
  if (!o.admin_tokens_file.empty()) o.config.admin_tokens = load_tokens(o.admin_tokens_file, "admin tokens");
  for (const auto& model : registry.models()) log_model(*model);
  load_scenes(o, registry);
}

void announce(const mtlod::server::ServerConfig& config, const mtlod::server::Server& server) {
  const bool tls = !config.tls_cert_file.empty();
  spdlog::info("{} listening on {}:{} (protocol version {}{}{}); try: mtlod-client --port {}{}{} list",
               config.instance, config.host, server.port(), mtlod::protocol::kProtocolVersion,
               tls ? ", TLS" : "", config.tokens ? ", access tokens" : "", server.port(), tls ? " --tls" : "",
               config.tokens ? " --token TOKEN" : "");
  if (config.http_port) {
    spdlog::info("viewer: {}://{}:{}/{} (WebSocket at /ws, files from {})", tls ? "https" : "http",
                 config.host, server.http_port(), config.tokens ? "?token=TOKEN" : "", config.web_root);
  }
}

// A reply's buffers are allocated by a worker and freed by the connection's thread after sending.
// With glibc's defaults that memory goes back to the kernel between requests (big blocks are mapped
// and unmapped, arenas trimmed), and a worker pays page faults and zero fills on every large reply
// (BENCHMARKS.md, "Scaling: serving large models"). Blocks up to 32 MiB (glibc's largest mmap
// threshold) come from the arenas, which keep up to 256 MiB free before trimming; larger blocks are
// still mapped and returned at once.
void keep_reply_memory() {
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace mtlod;
  keep_reply_memory();
  CLI::App app{
      "mtlod-server: a network level-of-detail server. Clients send camera matrices and gaze points "
      "(protocol/PROTOCOL.md) and receive Draco-compressed view-dependent extractions."};
  Options o;
  add_options(app, o);
  CLI11_PARSE(app, argc, argv);
  server::ServerConfig& config = o.config;
  config.watch_models = o.reload_mode == "watch";

  spdlog::set_level(spdlog::level::from_str(o.log_level));
  server::LogFormat format = server::LogFormat::kText;
  server::parse_log_format(o.log_format, format);
  server::setup_logging(format);
  config.instance = server::instance_id(replica_name(o.name));

  server::ModelRegistry registry;
  load(o, registry);
  server::Server server(config, registry);
  check(server.listen());
  announce(config, server);
  if (!o.port_file.empty() && !write_port_file(o.port_file, server.port(), server.http_port())) {
    spdlog::error("cannot write {}", o.port_file);
    return 1;
  }
  server.run();
  // What this run delivered, for an operator (and a test) to set beside what its clients received.
  const auto& metrics = server.metrics();
  spdlog::info("stopped: {} meshes sent whole over {} connections", metrics.meshes_sent(),
               metrics.connections_accepted());
  return 0;
}
