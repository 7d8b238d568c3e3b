// The command line every thicket executable shares (cli.h, node_main.h): the LCM URL default,
// both spellings of a flag, and number checks stricter than CLI11 2.1's own conversions.
#include <gtest/gtest.h>

#include <cstdlib>

#include "thicket/common/cli.h"
#include "thicket/common/node_main.h"

namespace thicket {
namespace {

// parseNodeArgs on `words` after the program name; the exit status when it ends main.
std::optional<int> parseNode(std::vector<const char*> words, NodeArgs& args) {
  words.insert(words.begin(), "thicket-test");
  return parseNodeArgs(static_cast<int>(words.size()), words.data(), "thicket-test", "a test",
                       args);
}

TEST(Cli, DefaultUrlIsLoopbackUnlessTheEnvironmentSaysOtherwise) {
  ::unsetenv("LCM_DEFAULT_URL");
  EXPECT_EQ(defaultLcmUrl(), "udpm://239.255.76.67:7667?ttl=0");
  ::setenv("LCM_DEFAULT_URL", "memq://", 1);
  EXPECT_EQ(defaultLcmUrl(), "memq://");
  NodeArgs args;
  EXPECT_EQ(parseNode({}, args), std::nullopt);
  EXPECT_EQ(args.lcm_url, "memq://");
  ::setenv("LCM_DEFAULT_URL", "", 1);
  EXPECT_EQ(defaultLcmUrl(), kLoopbackLcmUrl);
  ::unsetenv("LCM_DEFAULT_URL");
}

TEST(Cli, NodeFlagsInBothSpellingsAndTheParamsCommand) {
  NodeArgs args;
  EXPECT_EQ(parseNode({"--lcm-url", "memq://", "--config=c.yaml"}, args), std::nullopt);
  EXPECT_EQ(args.lcm_url, "memq://");
  EXPECT_EQ(args.config_path, "c.yaml");
  EXPECT_FALSE(args.params);
  NodeArgs params;
  EXPECT_EQ(parseNode({"params"}, params), std::nullopt);
  EXPECT_TRUE(params.params);
  NodeArgs help;
  EXPECT_EQ(parseNode({"--help"}, help), 0);
}

TEST(Cli, NodeRefusesUnknownMissingOrEmptyValues) {
  for (const std::vector<const char*>& words : {std::vector<const char*>{"--config"},
                                                {"--lcm-url="},
                                                {"--config", ""},
                                                {"--rate", "4"},
                                                {"extra"}}) {
    NodeArgs args;
    EXPECT_EQ(parseNode(words, args), 2) << words.front();
  }
}

// One option of each kind on a fresh app; the message, or "" when accepted.
std::string parsed(const std::vector<std::string>& args, int64_t* integer = nullptr,
                   int64_t* seed = nullptr, double* number = nullptr,
                   std::vector<double>* list = nullptr) {
  CLI::App app("test", "test");
  int64_t integer_value = 0;
  int64_t seed_value = 0;
  double number_value = 0;
  std::vector<double> list_value;
  app.add_option("--n", integer_value)->check(cli::integer(-5, 100));
  cli::addSeed(app, seed_value);
  app.add_option("--x", number_value)->check(cli::number(0, 1));
  app.add_option("--list", list_value)->delimiter(',')->check(cli::number(0));
  const Expected<bool> result = cli::parseArgs(app, args);
  if (integer) *integer = integer_value;
  if (seed) *seed = seed_value;
  if (number) *number = number_value;
  if (list) *list = list_value;
  return result ? "" : result.error();
}

TEST(Cli, IntegersAreDecimalAndInRange) {
  int64_t n = 0;
  int64_t seed = 0;
  EXPECT_EQ(parsed({"--n", "10", "--seed=7"}, &n, &seed), "");
  EXPECT_EQ(n, 10);
  EXPECT_EQ(seed, 7);
  // CLI11 2.1 alone reads "010" as octal 8.
  EXPECT_EQ(parsed({"--n", "010"}), "--n: must be an integer in [-5, 100], not '010'");
  EXPECT_EQ(parsed({"--n=-5"}, &n), "");
  EXPECT_EQ(n, -5);
  EXPECT_EQ(parsed({"--seed", "-3"}), "--seed: must be an integer >= 0, not '-3'");
  EXPECT_EQ(parsed({"--n", "101"}), "--n: must be an integer in [-5, 100], not '101'");
  for (const char* bad : {"0x10", "+4", "1e3", "2.5", "99999999999999999999", "", " 4"}) {
    EXPECT_NE(parsed({"--seed", bad}), "") << bad;
  }
}

TEST(Cli, NumbersAreFiniteAndInRange) {
  double x = 0;
  std::vector<double> list;
  EXPECT_EQ(parsed({"--x", "0.25", "--list", "0.1,0.2"}, nullptr, nullptr, &x, &list), "");
  EXPECT_EQ(x, 0.25);
  EXPECT_EQ(list, (std::vector<double>{0.1, 0.2}));
  EXPECT_EQ(parsed({"--x", "1.5"}), "--x: must be a number in [0, 1], not '1.5'");
  EXPECT_EQ(parsed({"--list", "0.1,-1"}), "--list: must be a number >= 0, not '-1'");
  for (const char* bad : {"nan", "inf", "1e400", "0.5m", "x"}) {
    EXPECT_NE(parsed({"--x", bad}), "") << bad;
  }
}

TEST(Cli, SwitchesAreOnOrOff) {
  for (const auto& [text, expected] : {std::pair{"on", true}, std::pair{"off", false}}) {
    CLI::App app("test", "test");
    bool value = !expected;
    cli::addSwitch(app, "--light", value, "a switch");
    ASSERT_TRUE(cli::parseArgs(app, {"--light", text}));
    EXPECT_EQ(value, expected) << text;
  }
  CLI::App app("test", "test");
  bool value = false;
  cli::addSwitch(app, "--light", value, "a switch");
  const Expected<bool> refused = cli::parseArgs(app, {"--light=yes"});
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error(), "--light: must be on or off, not 'yes'");
}

TEST(Cli, UnknownFlagsAndHelp) {
  EXPECT_NE(parsed({"--bogus", "1"}).find("--bogus"), std::string::npos);
  CLI::App app("test", "test");
  const Expected<bool> help = cli::parseArgs(app, {"-h"});
  ASSERT_TRUE(help);
  EXPECT_TRUE(*help);
}

}  // namespace
}  // namespace thicket
