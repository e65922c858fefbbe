// The access-token table (server/auth.hpp): the file format, what each token grants, and that only
// an exact token matches. How long a comparison takes is measured nowhere here: timing belongs in
// benchmarks, not in tests that must pass on a loaded machine.
#include "server/auth.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "tests/core/test_meshes.hpp"

namespace mtlod::server {
namespace {

constexpr char kLab[] = "3f6a1c0e9b8d7f2a5c4e6b1d0a9f8e7c";
constexpr char kDemo[] = "demo-token-2024.bunny_only~x";

TEST(TokenTable, EachTokenGrantsItsModelsAndNoneGrantsAnother) {
  const std::string text = std::string("# the lab sees everything\n") + kLab + "   # lab\n\n  " + kDemo +
                           " bunny  dragon-871k # demo\n";
  auto table = TokenTable::parse(text, "tokens.txt");
  ASSERT_TRUE(table.ok()) << table.error().message;
  EXPECT_EQ(table->size(), 2u);

  const Grant* lab = table->find(kLab);
  ASSERT_NE(lab, nullptr);
  EXPECT_EQ(lab->line, 2u);
  EXPECT_TRUE(lab->models.empty());  // no names: every model
  EXPECT_TRUE(lab->sees("bunny"));
  EXPECT_TRUE(lab->sees("anything"));

  const Grant* demo = table->find(kDemo);
  ASSERT_NE(demo, nullptr);
  EXPECT_EQ(demo->line, 4u);
  EXPECT_EQ(demo->models, (std::vector<std::string>{"bunny", "dragon-871k"}));  // the comment is no model
  EXPECT_TRUE(demo->sees("bunny"));
  EXPECT_FALSE(demo->sees("bunny2"));
  EXPECT_FALSE(demo->sees("Bunny"));
  EXPECT_EQ(table->listed_models(), (std::vector<std::string>{"bunny", "dragon-871k"}));
}

TEST(TokenTable, OnlyTheExactTokenMatches) {
  auto table = TokenTable::parse(std::string(kLab) + "\n", "tokens.txt");
  ASSERT_TRUE(table.ok()) << table.error().message;
  const std::string token = kLab;
  EXPECT_NE(table->find(token), nullptr);
  // Prefixes, extensions, one changed character, another case, blanks around it: all refused.
  EXPECT_EQ(table->find(""), nullptr);
  EXPECT_EQ(table->find(token.substr(0, token.size() - 1)), nullptr);
  EXPECT_EQ(table->find(token + "0"), nullptr);
  EXPECT_EQ(table->find(" " + token), nullptr);
  EXPECT_EQ(table->find(token + "\n"), nullptr);
  for (std::size_t i = 0; i < token.size(); ++i) {
    std::string changed = token;
    changed[i] = changed[i] == '0' ? '1' : '0';
    EXPECT_EQ(table->find(changed), nullptr) << "character " << i;
  }
  std::string upper = token;
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  EXPECT_EQ(table->find(upper), nullptr);
  // A token of the table's length but another alphabet, and a very long one.
  EXPECT_EQ(table->find(std::string(token.size(), '\xff')), nullptr);
  EXPECT_EQ(table->find(std::string(100000, 'a')), nullptr);
}

TEST(TokenTable, BadLinesAreErrorsNamingTheLineButNotTheToken) {
  struct Case {
    std::string text;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"short-token\n", "tokens.txt:1: a token is 16 to 256 characters"},
      {"# comment\n" + std::string(257, 'a') + "\n", "tokens.txt:2: a token is 16 to 256 characters"},
      {"abcdefghijklmnop/q\n", "tokens.txt:1: a token is 16 to 256 characters from A-Z a-z 0-9 - . _ ~"},
      {"abcdefghijklmnopq+r\n", "tokens.txt:1:"},
      {std::string(kLab) + "\n" + kDemo + "\n" + kLab + " bunny\n", "tokens.txt:3: this token is already"},
  };
  for (const Case& c : cases) {
    auto table = TokenTable::parse(c.text, "tokens.txt");
    ASSERT_FALSE(table.ok()) << c.text;
    EXPECT_NE(table.error().message.find(c.message), std::string::npos) << table.error().message;
    EXPECT_EQ(table.error().message.find("short-token"), std::string::npos) << table.error().message;
    EXPECT_EQ(table.error().message.find(kLab), std::string::npos) << table.error().message;
  }
}

TEST(TokenTable, LoadNamesTheFileAndRefusesAnEmptyOne) {
  const auto dir = test::scratch_dir("auth");
  auto missing = TokenTable::load(dir / "no-such-file");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("no-such-file: cannot read"), std::string::npos);

  std::ofstream(dir / "empty") << "# nobody yet\n\n";
  auto empty = TokenTable::load(dir / "empty");
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error().message.find("no tokens"), std::string::npos) << empty.error().message;

  std::ofstream(dir / "one") << kDemo << " bunny\n";
  auto one = TokenTable::load(dir / "one");
  ASSERT_TRUE(one.ok()) << one.error().message;
  ASSERT_NE(one->find(kDemo), nullptr);
  EXPECT_TRUE(one->find(kDemo)->sees("bunny"));
}

}  // namespace
}  // namespace mtlod::server
