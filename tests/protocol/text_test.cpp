// printable() and utf8_prefix() against expectations written out by hand from the UTF-8 rules
// (RFC 3629, Unicode table 3-7), and against nlohmann::json's own strict check.
#include <gtest/gtest.h>

#include <random>

#include "nlohmann/json.hpp"
#include "protocol/parse.hpp"
#include "protocol/replies.hpp"
#include "protocol/text.hpp"

namespace mtlod::protocol {
namespace {

const std::string kFffd = "\xEF\xBF\xBD";

TEST(Printable, ValidPrintableTextIsUnchanged) {
  for (const std::string s : {"", "plain ascii", "caf\xC3\xA9", "\xE2\x82\xAC 5", "\xF0\x9F\x90\x89 dragon",
                              "\xED\x9F\xBF", "\xEE\x80\x80", "\xF4\x8F\xBF\xBF"}) {
    EXPECT_EQ(printable(s), s);
  }
}

TEST(Printable, EachInvalidByteBecomesOneReplacement) {
  EXPECT_EQ(printable("\xff\xfe"), kFffd + kFffd);
  EXPECT_EQ(printable("a\xC3"), "a" + kFffd);                               // truncated at the end
  EXPECT_EQ(printable("\xC3(x"), kFffd + "(x");                             // bad continuation
  EXPECT_EQ(printable("\xC0\xAF"), kFffd + kFffd);                          // overlong '/'
  EXPECT_EQ(printable("\xE0\x80\xAF"), kFffd + kFffd + kFffd);              // overlong, three bytes
  EXPECT_EQ(printable("\xED\xA0\x80"), kFffd + kFffd + kFffd);              // surrogate U+D800
  EXPECT_EQ(printable("\xF4\x90\x80\x80"), kFffd + kFffd + kFffd + kFffd);  // above U+10FFFF
  EXPECT_EQ(printable("\x80z"), kFffd + "z");                               // lone continuation
}

TEST(Printable, ControlCharactersAreWrittenAsEscapes) {
  EXPECT_EQ(printable(std::string("a\nb\x00\x1b[31m\x7f", 10)), "a\\x0ab\\x00\\x1b[31m\\x7f");
}

TEST(Printable, RandomBytesAlwaysGiveTextJsonCanSerialise) {
  std::mt19937 rng(7);
  for (int i = 0; i < 2000; ++i) {
    std::string s(rng() % 40, '\0');
    for (char& c : s) c = static_cast<char>(rng());
    const std::string out = printable(s);
    EXPECT_EQ(printable(out), out);                     // idempotent: the result is already printable text
    EXPECT_NO_THROW((void)nlohmann::json(out).dump());  // strict: throws on invalid UTF-8
  }
}

TEST(Utf8Prefix, NeverEndsInsideACharacter) {
  const std::string s = "a\xC3\xA9\xE2\x82\xAC\xF0\x9F\x90\x89";  // 1 + 2 + 3 + 4 bytes
  const std::size_t expected[] = {0, 1, 1, 3, 3, 3, 6, 6, 6, 6, 10, 10};
  for (std::size_t max = 0; max <= 11; ++max) EXPECT_EQ(utf8_prefix(s, max).size(), expected[max]) << max;
}

// The path a client's bytes take to a reply: parse error, then serialisation, then a client's parse.
TEST(ClientBytes, ParseErrorsOfInvalidUtf8SerialiseAndReadBack) {
  for (const std::string request :
       {"{\"type\":\"model_info\",\"id\":1,\"model\":\"\xff\xfe\"}",
        "{\"type\":\"ping\",\"id\":\"a\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9"
        "\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\xC3\xA9\"}",
        "\x01\x02\x80"}) {
    const auto parsed = parse_request(request, Limits{});
    ASSERT_FALSE(parsed.ok());
    EXPECT_EQ(printable(parsed.error().message), parsed.error().message);
    std::string json;
    ASSERT_NO_THROW(
        json = to_json(ErrorReply{parsed.error().code, parsed.error().message}, parsed.error().request_id));
    auto back = parse_reply(json);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(std::get<ErrorReply>(back->reply).message, parsed.error().message);
  }
}

TEST(ClientBytes, AnyReplyTextSerialisesWithInvalidBytesReplaced) {
  const std::string json = to_json(ErrorReply{ErrorKind::kBadRequest, "bad \xff value"}, 3);
  auto back = parse_reply(json);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(std::get<ErrorReply>(back->reply).message, "bad " + kFffd + " value");
}

}  // namespace
}  // namespace mtlod::protocol
