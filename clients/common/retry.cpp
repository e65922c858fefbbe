// Reconnection with backoff (see retry.hpp).
#include "clients/common/retry.hpp"

#include <algorithm>
#include <cmath>
#include <thread>

#include "CLI/CLI.hpp"
#include "fmt/format.h"

namespace mtlod::clients {

std::chrono::milliseconds Backoff::delay(unsigned attempt, std::mt19937_64& rng) const {
  const double base = static_cast<double>(initial.count()) * std::pow(factor, std::min(attempt, 60u));
  const double capped = std::min(base, static_cast<double>(max.count()));
  std::uniform_real_distribution<double> shorten(0.0, std::clamp(jitter, 0.0, 1.0));
  return std::chrono::milliseconds(static_cast<std::int64_t>(std::llround(capped * (1.0 - shorten(rng)))));
}

void add_endpoint_flags(CLI::App& app, Endpoint& endpoint) {
  app.add_option("--host", endpoint.host, "server address")->capture_default_str();
  app.add_option("--port", endpoint.port, "server port")->capture_default_str();
  app.add_flag(
      "--tls", endpoint.tls.enabled,
      "speak TLS; the server's certificate must be valid for --host and trusted by the system (or by "
      "--tls-ca)");
  app.add_option("--tls-ca", endpoint.tls.ca_file,
                 "PEM certificates to trust instead of the system's (a private CA, or a self-signed server "
                 "certificate); implies --tls")
      ->check(CLI::ExistingFile)
      ->each([&endpoint](const std::string&) { endpoint.tls.enabled = true; });
  app.add_option("--token", endpoint.token, "access token to send in hello (mtlod-server --auth-tokens)")
      ->envname("MTLOD_TOKEN");
}

Result<Session> open_session(const std::string& host, std::uint16_t port, const std::string& client,
                             const RetryPolicy& policy, std::mt19937_64& rng, unsigned* tries,
                             const std::atomic<bool>* give_up) {
  return open_session(Endpoint{host, port, {}, {}}, client, policy, rng, tries, give_up);
}

Result<Session> open_session(const Endpoint& endpoint, const std::string& client, const RetryPolicy& policy,
                             std::mt19937_64& rng, unsigned* tries, const std::atomic<bool>* give_up) {
  const std::string& host = endpoint.host;
  const std::uint16_t port = endpoint.port;
  const unsigned attempts = std::max(1u, policy.attempts);
  std::string last_error = "given up before connecting";
  ErrorCode last_code = ErrorCode::kIoError;
  unsigned made = 0;
  for (unsigned attempt = 0; attempt < attempts && !(give_up && *give_up); ++attempt) {
    made = attempt + 1;
    if (tries) *tries = made;
    if (attempt > 0) std::this_thread::sleep_for(policy.backoff.delay(attempt - 1, rng));
    auto connection = ServerConnection::open(host, port, std::chrono::seconds(5), endpoint.tls);
    if (!connection) {
      last_error = connection.error().message;
      if (connection.error().code == ErrorCode::kInvalidArgument) {
        last_code = ErrorCode::kInvalidArgument;
        break;
      }
      continue;
    }
    auto reply =
        connection->call(protocol::Hello{protocol::kProtocolVersion, client, endpoint.token, std::nullopt}, 0,
                         std::chrono::seconds(10));
    if (!reply) {
      last_error = reply.error().message;
      continue;
    }
    if (const auto* hello = std::get_if<protocol::HelloReply>(&reply->header.reply)) {
      return Session{std::move(*connection), *hello};
    }
    if (const auto* error = std::get_if<protocol::ErrorReply>(&reply->header.reply)) {
      last_error = fmt::format("{}:{} answered hello with {}: {}", host, port,
                               protocol::to_string(error->code), error->message);
      if (error->code == protocol::ErrorKind::kUnauthorized) {
        last_code = ErrorCode::kInvalidArgument;
        break;
      }
    } else {
      last_error = fmt::format("{}:{} answered hello with something else", host, port);
    }
  }
  if (made <= 1) return make_error(last_code, last_error);
  return make_error(last_code, fmt::format("{} (after {} attempts)", last_error, made));
}

bool asks_for_retry(const ReplyFrame& frame) {
  const auto* error = std::get_if<protocol::ErrorReply>(&frame.header.reply);
  return error && error->code == protocol::ErrorKind::kShuttingDown;
}

RetryingConnection::RetryingConnection(Endpoint endpoint, std::string client, RetryPolicy policy,
                                       std::uint64_t seed)
    : endpoint_(std::move(endpoint)), client_(std::move(client)), policy_(policy), rng_(seed) {}

Result<ReplyFrame> RetryingConnection::call(const protocol::Request& request,
                                            std::chrono::milliseconds timeout) {
  const unsigned attempts = std::max(1u, policy_.attempts);
  std::string last_error;
  for (unsigned attempt = 0; attempt < attempts; ++attempt) {
    if (attempt > 0) {
      ++retries_;
      std::this_thread::sleep_for(policy_.backoff.delay(attempt - 1, rng_));
    }
    if (!connection_) {
      // One connection attempt per call attempt: the outer loop does the backing off.
      RetryPolicy once = policy_;
      once.attempts = 1;
      auto session = open_session(endpoint_, client_, once, rng_);
      if (!session) {
        last_error = session.error().message;
        // A refused token is refused on every connection: say so now rather than after every attempt.
        if (session.error().code == ErrorCode::kInvalidArgument) return session.error();
        continue;
      }
      connection_ = std::move(session->connection);
      hello_ = std::move(session->hello);
    }
    const std::uint64_t id = next_id_++;
    auto reply = connection_->call(request, id, timeout);
    // A model whose file is being rewritten is served again soon: the request is sent again after
    // the backoff (streams count such replies instead, as any error).
    const auto* error = reply ? std::get_if<protocol::ErrorReply>(&reply->header.reply) : nullptr;
    const bool unavailable = error && error->code == protocol::ErrorKind::kUnavailable;
    if (reply && !asks_for_retry(*reply) && !unavailable) return reply;
    last_error = reply ? std::get<protocol::ErrorReply>(reply->header.reply).message : reply.error().message;
    connection_.reset();
  }
  return make_error(ErrorCode::kIoError,
                    fmt::format("{} (after {} attempt{})", last_error, attempts, attempts == 1 ? "" : "s"));
}

}  // namespace mtlod::clients
