#include <gtest/gtest.h>

#include <cstdlib>

#include "thicket/common/node_main.h"

namespace thicket {
namespace {

Expected<NodeArgs> parse(std::vector<const char*> argv) {
  argv.insert(argv.begin(), "thicket-test");
  return parseNodeArgs(static_cast<int>(argv.size()), argv.data());
}

TEST(NodeMain, DefaultUrlIsLoopbackUnlessTheEnvironmentSaysOtherwise) {
  ::unsetenv("LCM_DEFAULT_URL");
  EXPECT_EQ(defaultLcmUrl(), "udpm://239.255.76.67:7667?ttl=0");
  ::setenv("LCM_DEFAULT_URL", "memq://", 1);
  EXPECT_EQ(defaultLcmUrl(), "memq://");
  EXPECT_EQ(parse({})->lcm_url, "memq://");
  ::setenv("LCM_DEFAULT_URL", "", 1);
  EXPECT_EQ(defaultLcmUrl(), kLoopbackLcmUrl);
  ::unsetenv("LCM_DEFAULT_URL");
}

TEST(NodeMain, ParsesCommonFlagsInBothFormsAndKeepsTheRest) {
  auto args = parse({"--lcm-url", "memq://", "--rate", "4", "--config=c.yaml", "-h", "x"});
  ASSERT_TRUE(args) << args.error();
  EXPECT_EQ(args->lcm_url, "memq://");
  EXPECT_EQ(args->config_path, "c.yaml");
  EXPECT_TRUE(args->help);
  EXPECT_EQ(args->options, (std::vector<std::string>{"--rate", "4", "x"}));
}

TEST(NodeMain, RefusesMissingOrEmptyValues) {
  auto missing = parse({"--config"});
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error(), "--config needs a value");
  auto empty = parse({"--lcm-url="});
  ASSERT_FALSE(empty);
  EXPECT_EQ(empty.error(), "--lcm-url needs a non-empty value");
}

}  // namespace
}  // namespace thicket
