// Reconnecting with backoff, for clients of a server that may restart or sit behind a load
// balancer that moves them to another replica: exponential backoff with jitter, a hello (with the
// access token) on every new connection, and which replies ask for a request to be sent again.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <random>
#include <string>

#include "clients/common/server_connection.hpp"
#include "core/result.hpp"
#include "protocol/replies.hpp"

namespace CLI {
class App;
}

namespace mtlod::clients {

// Where a client's sessions go and what they show: the address, TLS and the access token.
struct Endpoint {
  std::string host = "127.0.0.1";
  std::uint16_t port = 7878;
  TlsOptions tls;
  std::string token;  // sent in every hello (mtlod-server --auth-tokens); empty: none
};

// The flags every network client takes for its endpoint: --host, --port, --tls, --tls-ca and
// --token (also read from the environment variable MTLOD_TOKEN, which other users cannot see).
void add_endpoint_flags(CLI::App& app, Endpoint& endpoint);

// Delays between connection attempts: initial × factor^attempt, capped at max, each shortened by
// a random fraction up to `jitter` so that clients dropped together do not return together.
struct Backoff {
  std::chrono::milliseconds initial{50};
  std::chrono::milliseconds max{2000};
  double factor = 2.0;
  double jitter = 0.25;

  // The wait before attempt `attempt` + 1 (attempt 0 is the first retry).
  std::chrono::milliseconds delay(unsigned attempt, std::mt19937_64& rng) const;
};

struct RetryPolicy {
  unsigned attempts = 8;  // connection attempts per outage, the first included; 1 = never retry
  Backoff backoff;
};

// A connection that has said hello.
struct Session {
  ServerConnection connection;
  protocol::HelloReply hello;
};

// Connects and says hello as `client`, with the endpoint's token. A failed connect, a dropped
// connection or an error reply to hello (a server at its connection limit answers one) counts as a
// failed attempt; after each, it waits policy.backoff and tries again, up to policy.attempts
// attempts, and none once `give_up` (when given) is set. An `unauthorized` reply or a server
// certificate that is not trusted ends the attempts at once, as kInvalidArgument: trying again
// would meet the same refusal. `tries`, when given, receives the number of attempts made. Errors:
// the last attempt's, with the count.
Result<Session> open_session(const Endpoint& endpoint, const std::string& client, const RetryPolicy& policy,
                             std::mt19937_64& rng, unsigned* tries = nullptr,
                             const std::atomic<bool>* give_up = nullptr);
// The same for plain TCP without a token.
Result<Session> open_session(const std::string& host, std::uint16_t port, const std::string& client,
                             const RetryPolicy& policy, std::mt19937_64& rng, unsigned* tries = nullptr,
                             const std::atomic<bool>* give_up = nullptr);

// True for a reply that asks the client to send its request again on a new connection: the server
// is draining (`shutting_down`) and will close this one.
bool asks_for_retry(const ReplyFrame& frame);

// One request at a time, reconnecting as needed: for command-line clients whose requests are
// idempotent (list, info, extract, stats, ping).
class RetryingConnection {
 public:
  RetryingConnection(Endpoint endpoint, std::string client, RetryPolicy policy,
                     std::uint64_t seed = std::random_device{}());

  // Sends `request` and returns its reply. When the connection drops, the reply does not come in
  // time, or the server answers `shutting_down`, it reconnects (with backoff) and sends it again,
  // up to policy.attempts times in all.
  Result<ReplyFrame> call(const protocol::Request& request,
                          std::chrono::milliseconds timeout = std::chrono::seconds(30));
  // The hello reply of the current connection (empty before the first call).
  const protocol::HelloReply& hello() const { return hello_; }
  // Requests sent again after a failure.
  std::uint64_t retries() const { return retries_; }

 private:
  Endpoint endpoint_;
  std::string client_;
  RetryPolicy policy_;
  std::mt19937_64 rng_;
  std::optional<ServerConnection> connection_;
  protocol::HelloReply hello_;
  std::uint64_t next_id_ = 1;
  std::uint64_t retries_ = 0;
};

}  // namespace mtlod::clients
