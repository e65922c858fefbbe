// --log-format json against a running server: every line it writes is one JSON object with a time
// and a level, an extraction line carries the reply's own numbers as members, and client bytes
// quoted in a message (quotes, backslashes, control and invalid UTF-8) cannot break a line.
#include <gtest/gtest.h>
#include <signal.h>

#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "clients/common/server_connection.hpp"
#include "nlohmann/json.hpp"
#include "protocol/frame.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"

namespace mtlod {
namespace {

TEST(LogFormat, JsonLinesAreObjectsWithTheExtractionsFields) {
  const auto dir = test::scratch_dir("log-format");
  const auto bunny = test::models_dir() / "bunny.ply";
  if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no " << bunny;
  test::ServerProcess server(
      {"--mesh", bunny.string(), "--cache-dir", dir.string(), "--log-format", "json", "--log-level", "debug"},
      dir);
  ASSERT_TRUE(server.running()) << server.log();

  protocol::MeshReply mesh;
  {
    auto c = clients::ServerConnection::open("127.0.0.1", server.port());
    ASSERT_TRUE(c.ok()) << c.error().message;
    auto info = c->call(protocol::ModelInfo{"bunny"}, 2);
    ASSERT_TRUE(info.ok()) << info.error().message;
    const auto& model = std::get<protocol::ModelInfoReply>(info->header.reply);
    auto reply = c->call(test::framing_extract("bunny", model, {128, 128}, 1.0), 3);
    ASSERT_TRUE(reply.ok() && std::holds_alternative<protocol::MeshReply>(reply->header.reply))
        << reply->json;
    mesh = std::get<protocol::MeshReply>(reply->header.reply);
    // A model name with a quote, a backslash and a control byte, quoted back in the unknown_model
    // error that the debug level logs; then raw invalid UTF-8, quoted in a bad_json error.
    for (const char* json : {R"({"type":"model_info","id":4,"model":"a\"b\\c\u0001d"})",
                             "{\"type\":\"model_info\",\"id\":5,\"model\":\"\xff\xfe\"}"}) {
      std::vector<std::uint8_t> frame;
      protocol::append_frame(json, {}, frame);
      ASSERT_TRUE(c->send_raw(frame).ok());
      ASSERT_TRUE(c->receive().ok());
    }
  }
  server.stop(SIGTERM);

  std::istringstream log(server.log());
  std::string line;
  int lines = 0, extractions = 0, quoted = 0;
  while (std::getline(log, line)) {
    ++lines;
    const auto object = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    ASSERT_TRUE(object.is_object()) << "not a JSON object: " << line;
    ASSERT_TRUE(object.contains("time") && object["time"].is_string()) << line;
    ASSERT_TRUE(object.contains("level") && object["level"].is_string()) << line;
    if (object.contains("type") && object["type"] == "extract") {
      ++extractions;
      EXPECT_EQ(object["id"], 3);
      EXPECT_EQ(object["model"], "bunny");
      EXPECT_EQ(object["triangles"], mesh.triangles);
      EXPECT_EQ(object["bytes"], mesh.bytes);
      EXPECT_NEAR(object["max_error"].get<double>(), mesh.max_error, 1e-4 * mesh.max_error + 1e-12);
      EXPECT_EQ(object["us"]["total"], mesh.timings.total_us);
      EXPECT_EQ(object["us"]["refine"], mesh.timings.refine_us);
      continue;
    }
    ASSERT_TRUE(object.contains("msg") && object["msg"].is_string()) << line;
    const std::string msg = object["msg"];
    // printable(): control bytes as the four characters \x01, invalid bytes as U+FFFD.
    if (msg.find("error unknown_model") != std::string::npos) {
      ++quoted;
      EXPECT_NE(msg.find(R"(a"b\c\x01d)"), std::string::npos) << msg;
    }
    if (msg.find("error bad_json") != std::string::npos) {
      ++quoted;
      EXPECT_NE(msg.find("\xEF\xBF\xBD"), std::string::npos) << msg;
    }
  }
  EXPECT_GT(lines, 3);
  EXPECT_EQ(extractions, 1);
  EXPECT_EQ(quoted, 2) << server.log();
}

}  // namespace
}  // namespace mtlod
