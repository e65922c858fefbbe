// mtlod-load: a load tester for mtlod-server. Closed loop: N connections, each sends its
// next request when the previous reply is in. Open loop (--rate): requests are due on a fixed
// schedule whatever the server does, and latency counts from the due time, so queueing shows.
// Each connection has a sending and a receiving thread; replies come back in request order.
// When a connection drops or its server drains (`shutting_down`), the stream reconnects with
// backoff and sends its unanswered requests again, so a failover shows as latency and retries,
// not as lost requests; --reconnect-after recycles connections so a load balancer can rebalance.
#include <cstdio>
#include <string>

#include "CLI/CLI.hpp"
#include "clients/load/load_options.hpp"
#include "clients/load/load_report.hpp"
#include "clients/load/load_run.hpp"
#include "fmt/format.h"

namespace {

int fail(const std::string& message) {
  fmt::print(stderr, "mtlod-load: {}\n", message);
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace mtlod;
  CLI::App app{
      "mtlod-load: load test for mtlod-server: closed loop (N connections, each waits for its reply) "
      "or open loop (--rate: a fixed arrival schedule, latency from each request's due time)."};
  clients::LoadOptions options;
  clients::ExtractFlags flags;
  clients::add_load_flags(app, options, flags);
  CLI11_PARSE(app, argc, argv);

  auto requests = clients::complete_load_options(options, flags);
  if (!requests) return fail(requests.error().message);
  clients::LoadTotals totals;
  auto end = clients::run_load(options, *requests, flags, totals);
  if (!end) return fail(end.error().message);
  if (auto reported = clients::report_load(options, flags, totals, *end); !reported)
    return fail(reported.error().message);
  return totals.ok > 0 && totals.decode_errors == 0 ? 0 : 1;
}
