// The in-process server and the reply checks of the end-to-end fuzz targets (server_harness.hpp).
#include "tests/fuzz/server_harness.hpp"

#include <unistd.h>

#include <boost/asio/dispatch.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/strand.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <future>
#include <string>
#include <utility>

#include "core/build/mt_builder.hpp"
#include "core/codec/cut_encoder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mt_file.hpp"
#include "fmt/format.h"
#include "protocol/frame.hpp"
#include "protocol/parse.hpp"
#include "protocol/text.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::fuzz {
namespace {

namespace net = boost::asio;

// The memory ceiling (worker scratch plus sessions): far above what a grid of max_grid needs on
// this model, so that only an accounting error reaches it.
constexpr std::uint64_t kMemoryLimitBytes = std::uint64_t{256} << 20;

// How long a connection whose input has ended may take to write its replies and close: far longer
// than any input's extractions should take, so only a stuck or runaway connection reaches it. It
// counts the process's CPU time, not the wall clock, so a campaign paused (SIGSTOP, to measure
// something else on the machine) or starved by other work does not look like a stuck connection.
constexpr auto kCloseDeadline = std::chrono::seconds(10);
constexpr auto kCloseCheck = std::chrono::milliseconds(50);

std::chrono::nanoseconds process_cpu_time() {
  timespec t{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return std::chrono::seconds(t.tv_sec) + std::chrono::nanoseconds(t.tv_nsec);
}

// The reply each request type gets when it does not fail (PROTOCOL.md, "Requests").
constexpr std::pair<std::string_view, const char*> kReplyTypes[] = {
    {"hello", "hello"},  {"list_models", "models"}, {"model_info", "model_info"},
    {"extract", "mesh"}, {"gaze", "mesh"},          {"cancel", "cancel"},
    {"stats", "stats"},  {"ping", "pong"},          {"reload", "reloaded"}};

// MTLOD_FUZZ_TRACE=1 prints every request and reply, to read what a reproducer does.
const bool kTrace = std::getenv("MTLOD_FUZZ_TRACE") != nullptr;

const char* reply_type_for(const protocol::Request& request) {
  const std::string_view type = protocol::request_type_name(request);
  for (const auto& [request_type, reply_type] : kReplyTypes) {
    if (request_type == type) return reply_type;
  }
  fail(fmt::format("no reply type is known for request type '{}'", type));
}

// The errors a request that parses may still get: the ones its session, the server's state or the
// model can cause (limits in flight and in memory, a cancel, a newer gaze, a drain, a missing token, an
// unknown model or one being rewritten, a codec or colours the model cannot give). Never `internal`,
// and never one about the request's own bytes (bad_frame, bad_json, unknown_type...), which parsing
// would have found.
bool session_error(std::string_view reply_type, protocol::ErrorKind error) {
  using protocol::ErrorKind;
  switch (error) {
    case ErrorKind::kShuttingDown:
    case ErrorKind::kUnauthorized:
      return true;
    case ErrorKind::kUnknownModel:
      return reply_type == "mesh" || reply_type == "model_info";
    case ErrorKind::kLimitExceeded:
    case ErrorKind::kNoView:
    case ErrorKind::kCancelled:
    case ErrorKind::kSuperseded:
    case ErrorKind::kUnavailable:
    case ErrorKind::kBadRequest:
      return reply_type == "mesh";
    default:
      return false;
  }
}

std::string id_text(std::optional<std::uint64_t> id) {
  return id ? std::to_string(*id) : "none";
}

std::string outcome_text(const char* type, std::optional<protocol::ErrorKind> error) {
  return error ? fmt::format("error {}", protocol::to_string(*error)) : std::string(type ? type : "?");
}

}  // namespace

void fail(const std::string& what) {
  std::fprintf(stderr, "mtlod fuzz: %s\n", what.c_str());
  std::fflush(stderr);
  __builtin_trap();
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::size_t write_fuzz_model(const std::filesystem::path& file) {
  // A noisy sphere of about 2000 triangles, with normals so that requests for them take the
  // encoder's normal path (a sphere's normals are its directions).
  core::eval::GenerateOptions options;
  options.target_triangles = 2000;
  core::model::Mesh mesh = core::eval::generate_mesh(options);
  mesh.normals.resize(mesh.positions.size());
  for (std::size_t v = 0; v < mesh.positions.size(); v += 3) {
    const float* p = &mesh.positions[v];
    const float length = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    for (int c = 0; c < 3; ++c) mesh.normals[v + c] = p[c] / length;
  }
  auto mt = core::build::build_mt(mesh);
  if (!mt) fail("building the model: " + mt.error().message);
  if (auto written = core::io::write_mt_file(file, *mt); !written) fail(written.error().message);
  return mt->triangle_count();
}

// ---- Transcript ----

Transcript::Transcript(const protocol::Limits& limits, std::size_t model_triangles)
    : limits_(limits), client_has_(model_triangles) {}

void Transcript::expect_request(std::string_view json) {
  if (kTrace) std::fprintf(stderr, "-> %s\n", protocol::printable(json).c_str());
  const auto parsed = protocol::parse_request(json, limits_);
  if (parsed) {
    expected_.push_back(Expected{parsed->id, std::nullopt, reply_type_for(parsed->request)});
  } else {
    expected_.push_back(Expected{parsed.error().request_id, parsed.error().code, nullptr});
  }
}

void Transcript::expect_bad_frame() {
  if (kTrace) std::fprintf(stderr, "-> (bad frame)\n");
  expected_.push_back(Expected{std::nullopt, protocol::ErrorKind::kBadFrame, nullptr});
}

void Transcript::check_reply(std::span<const std::uint8_t> frame) {
  const std::size_t n = written_.size();
  if (frame.size() < protocol::kFrameHeaderBytes)
    fail(fmt::format("reply {} is {} bytes long", n, frame.size()));
  const auto header = protocol::decode_frame_header(frame.first<protocol::kFrameHeaderBytes>(), frame.size());
  if (!header || header->body_bytes() != frame.size() - protocol::kFrameHeaderBytes) {
    fail(fmt::format("reply {}: a frame of {} bytes whose header does not announce its body", n,
                     frame.size()));
  }
  const std::string_view json(reinterpret_cast<const char*>(frame.data()) + protocol::kFrameHeaderBytes,
                              header->json_bytes);
  // A WebSocket text message must be UTF-8, and clients log what they get.
  if (protocol::printable(json) != json) {
    fail(fmt::format("reply {} is not printable UTF-8: {}", n, protocol::printable(json)));
  }
  const auto payload = frame.subspan(protocol::kFrameHeaderBytes + header->json_bytes);
  if (kTrace) std::fprintf(stderr, "<- %s + %zu bytes\n", std::string(json).c_str(), payload.size());
  auto reply = protocol::parse_reply(json);
  if (!reply) fail(fmt::format("reply {} does not parse ({}): {}", n, reply.error().message, json));
  std::optional<protocol::ErrorKind> error;
  if (const auto* e = std::get_if<protocol::ErrorReply>(&reply->reply)) {
    // The server answers `internal` only when its own code failed: that is what fuzzing looks for.
    if (e->code == protocol::ErrorKind::kInternal)
      fail(fmt::format("reply {} is an internal error: {}", n, json));
    error = e->code;
  }
  if (const auto* mesh = std::get_if<protocol::MeshReply>(&reply->reply)) {
    check_mesh(*mesh, payload);
  } else if (!payload.empty()) {
    fail(fmt::format("reply {} carries a payload of {} bytes: {}", n, payload.size(), json));
  }
  written_.push_back(Written{reply->id, protocol::reply_type_name(reply->reply), error});
}

void Transcript::check_mesh(const protocol::MeshReply& mesh, std::span<const std::uint8_t> payload) {
  const std::size_t n = written_.size();
  if (mesh.model != "bunny") fail(fmt::format("mesh reply {} names model '{}'", n, mesh.model));
  if (mesh.bytes != payload.size()) {
    fail(fmt::format("mesh reply {} announces {} bytes and carries {}", n, mesh.bytes, payload.size()));
  }
  if (!mesh.delta) {
    const auto decoded = core::codec::decode_payload(mesh.codec, payload);
    if (!decoded)
      fail(fmt::format("mesh reply {}: the payload does not decode: {}", n, decoded.error().message));
    if (decoded->triangle_count() != mesh.triangles || decoded->vertex_count() != mesh.vertices) {
      fail(fmt::format("mesh reply {} announces {} triangles and {} vertices; its payload holds {} and {}", n,
                       mesh.triangles, mesh.vertices, decoded->triangle_count(), decoded->vertex_count()));
    }
    client_keyed_ = false;  // the client now holds a mesh without ids: a delta must start afresh
    return;
  }
  // A delta: applied to the client's mesh as a client keyed by id would, it must give the cut.
  const auto parts = protocol::split_delta_payload(*mesh.delta, payload);
  if (!parts) fail(fmt::format("delta reply {}: {}", n, parts.error().message));
  if (!parts->mesh.empty()) {
    const auto decoded = core::codec::decode_payload(mesh.codec, parts->mesh);
    if (!decoded)
      fail(fmt::format("delta reply {}: the mesh part does not decode: {}", n, decoded.error().message));
    if (decoded->triangle_count() != parts->added_ids.size() || decoded->vertex_count() != mesh.vertices) {
      fail(fmt::format(
          "delta reply {} adds {} ids and {} vertices; its mesh part holds {} triangles and {} vertices", n,
          parts->added_ids.size(), mesh.vertices, decoded->triangle_count(), decoded->vertex_count()));
    }
  }
  if (mesh.delta->reset) {
    client_has_.assign(client_has_.size(), false);
    client_triangles_ = 0;
    client_keyed_ = true;
  } else if (!client_keyed_) {
    fail(fmt::format("delta reply {} builds on a mesh the client does not hold by id", n));
  }
  for (const std::uint32_t id : parts->removed_ids) {
    if (id >= client_has_.size() || !client_has_[id])
      fail(fmt::format("delta reply {} removes {}, not held", n, id));
    client_has_[id] = false;
    --client_triangles_;
  }
  for (const std::uint32_t id : parts->added_ids) {
    if (id >= client_has_.size() || client_has_[id]) fail(fmt::format("delta reply {} adds {} again", n, id));
    client_has_[id] = true;
    ++client_triangles_;
  }
  if (client_triangles_ != mesh.triangles) {
    fail(fmt::format("delta reply {} leaves the client {} triangles for a cut of {}", n, client_triangles_,
                     mesh.triangles));
  }
}

void Transcript::check_complete() const {
  if (written_.size() != expected_.size()) {
    fail(fmt::format("{} replies were owed and {} written", expected_.size(), written_.size()));
  }
  for (std::size_t i = 0; i < written_.size(); ++i) {
    const Expected& expected = expected_[i];
    const Written& written = written_[i];
    if (written.id != expected.id) {
      fail(fmt::format("reply {} has id {}; its request has id {}", i, id_text(written.id),
                       id_text(expected.id)));
    }
    // A valid request gets its reply type or an error its session can cause (session_error).
    const bool ok = expected.error  ? written.error == expected.error
                    : written.error ? session_error(expected.reply_type, *written.error)
                                    : std::string_view(written.type) == expected.reply_type;
    if (!ok) {
      fail(fmt::format("reply {} is {}; its request wants {}", i, outcome_text(written.type, written.error),
                       outcome_text(expected.reply_type, expected.error)));
    }
  }
}

bool Transcript::asked_for_meshes() const {
  return std::any_of(expected_.begin(), expected_.end(), [](const Expected& e) {
    return e.reply_type && std::string_view(e.reply_type) == "mesh";
  });
}

// ---- FuzzConnection ----

void FuzzConnection::start() {
  net::dispatch(strand(), [self = std::static_pointer_cast<FuzzConnection>(shared_from_this())] {
    self->opened();
    self->read();
  });
}

void FuzzConnection::write_frame(std::vector<std::uint8_t>& frame) {
  transcript_.check_reply(frame);
  // The write completes later, as an async_write does: replies owed meanwhile wait in order.
  net::post(strand(),
            [self = std::static_pointer_cast<FuzzConnection>(shared_from_this()), bytes = frame.size()] {
              self->guarded("write", [&] {
                self->on_written(!self->transport_closed_, bytes);
                if (self->awaiting_replies_ && !self->waiting_on_server()) {
                  self->awaiting_replies_ = false;
                  self->read();
                }
              });
            });
}

bool FuzzConnection::may_read_next() {
  if (!may_read()) return false;
  if (patient_ && waiting_on_server()) {
    awaiting_replies_ = true;
    return false;
  }
  return true;
}

// ---- FuzzServer ----

FuzzServer& FuzzServer::get() {
  // Never destroyed: exit() need not join the worker thread.
  static FuzzServer* const server = new FuzzServer;
  return *server;
}

FuzzServer::FuzzServer() : memory_(kMemoryLimitBytes) {
  // Errors stay visible (each comes with a failed check); per-request logging would cost more than
  // the request.
  spdlog::set_level(spdlog::level::err);
  // Small limits: extractions on this model stay cheap (milliseconds under ASan), and inputs reach
  // every limit.
  protocol::Limits& limits = config_.limits;
  limits.max_frame_bytes = 4096;
  limits.max_in_flight = 4;
  limits.max_grid = 64;
  limits.max_budget = 3000;
  limits.max_foci = 4;
  limits.max_memory_bytes = kMemoryLimitBytes;
  config_.workers = 1;
  config_.instance = "fuzz";

  // The registry loads models from files only; the file is read whole and can go at once.
  const auto dir = std::filesystem::temp_directory_path() / fmt::format("mtlod-fuzz-{}", ::getpid());
  std::filesystem::create_directories(dir);
  model_triangles_ = write_fuzz_model(dir / "bunny.mt");
  if (auto added = models_.add_file(dir / "bunny.mt"); !added) fail(added.error().message);
  std::filesystem::remove_all(dir);
}

void FuzzServer::on_closed() {
  closed_ = true;
  guard_.reset();
}

void FuzzServer::wait_for_workers() {
  // One worker thread runs jobs in order: once this one runs, every earlier job has finished.
  std::promise<void> done;
  net::post(workers_, [&done] { done.set_value(); });
  done.get_future().wait();
}

void FuzzServer::run(const Factory& make) {
  if (run(make, /*patient=*/false)) run(make, /*patient=*/true);
}

bool FuzzServer::run(const Factory& make, bool patient) {
  Transcript transcript(config_.limits, model_triangles_);
  closed_ = false;
  guard_.emplace(io_.get_executor());
  std::weak_ptr<server::Connection> alive;
  {
    const std::shared_ptr<FuzzConnection> connection =
        make(ConnectionArgs{context_, net::make_strand(io_), next_number_++, addresses_.acquire("192.0.2.1"),
                            transcript, patient});
    alive = connection;
    connection->start();
  }  // from here its own pending handlers keep it, as in the server
  const auto cpu_start = process_cpu_time();
  while (!closed_ && process_cpu_time() - cpu_start < kCloseDeadline) {
    io_.restart();
    io_.run_for(kCloseCheck);
  }
  if (!closed_) fail("the connection did not close after its input ended");
  // An extraction may still be on the worker, or its closure (holding the connection) not yet
  // destroyed; what it posts back runs here.
  for (int round = 0; !alive.expired(); ++round) {
    if (round == 10) fail("the connection is still referenced after it closed");
    wait_for_workers();
    io_.restart();
    io_.run();
  }
  transcript.check_complete();
  // With no connection open, the ceiling counts the worker's retained scratch and nothing else.
  if (memory_.held() > server::Engine::kRetainedScratchBytes) {
    fail(fmt::format("the memory ceiling holds {} bytes with no connection open", memory_.held()));
  }
  return transcript.asked_for_meshes();
}

}  // namespace mtlod::fuzz
