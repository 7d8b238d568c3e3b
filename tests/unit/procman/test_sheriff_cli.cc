// thicket-sheriff run as a user would, on memq:// (no deputies, nothing leaves the process):
// refused command lines and sheets exit 2, the console answers, quit and scripts end it.
#include <unistd.h>

#include <fstream>
#include <regex>
#include <string>

#include <gtest/gtest.h>

#include "cli.h"

namespace {

using thicket::testing::CliResult;
using thicket::testing::runCommand;

const std::string kSheriff = THICKET_SHERIFF;

std::string writeFile(const std::string& name, const std::string& text) {
  const std::string path =
      ::testing::TempDir() + "/sheriff_cli_" + std::to_string(::getpid()) + "_" + name;
  std::ofstream(path) << text;
  return path;
}

const char* kSheet = R"(# a sheet for the CLI tests
group "sim" {
  cmd "world" { exec = "sleep 100"; deputy = "alpha"; }
  group "inner" { cmd "echo" { exec = "echo hi"; host = "alpha"; } }
}
cmd "solo" { exec = "true"; deputy = "beta"; }
script "pause" { wait ms 1; }
script "up" { start group "sim" wait "running"; }
)";

std::string sheet() {
  static const std::string path = writeFile("good.pmd", kSheet);
  return path;
}

bool contains(const CliResult& result, const std::string& text) {
  return result.output.find(text) != std::string::npos;
}

TEST(SheriffCli, BadCommandLinesExitTwoWithAHint) {
  const std::vector<std::string> bad = {
      "",                                // no sheet
      "--bogus " + sheet(),              // unknown option
      "-x " + sheet(),                   // unknown short option
      "--wait-timeout abc " + sheet(),   // not a number
      "--wait-timeout -1 " + sheet(),    // negative
      "--status-period",                 // no value
      "-u",                              // no value
      "--lone-ranger=yes " + sheet(),    // a flag with a value
      "--exit-after-script " + sheet(),  // no script to exit after
      sheet() + " up extra",             // too many arguments
      "-o " + sheet() + " up",           // an observer runs no script
      "-l -o " + sheet(),                // both modes
  };
  for (const std::string& args : bad) {
    const CliResult result = runCommand(kSheriff + " " + args + " </dev/null");
    EXPECT_EQ(result.status, 2) << args << "\n" << result.output;
    EXPECT_TRUE(contains(result, "Run with --help")) << args << "\n" << result.output;
  }
}

TEST(SheriffCli, HelpExitsZero) {
  for (const char* flag : {"-h", "--help"}) {
    const CliResult result = runCommand(kSheriff + " " + flag);
    EXPECT_EQ(result.status, 0) << result.output;
    EXPECT_TRUE(contains(result, "--wait-timeout")) << result.output;
  }
}

// Written for the real parser's "<path>:<line>:<column>: <what>" errors.
TEST(SheriffCli, AMalformedSheetExitsTwoWithLineAndColumn) {
  const std::string path = writeFile("bad.pmd",
                                     "cmd \"x\" {\n"
                                     "  exec = \"true\";\n"
                                     "  deputy = \"alpha\" $\n"
                                     "}\n");
  const CliResult result = runCommand(kSheriff + " -u memq:// " + path + " </dev/null");
  EXPECT_EQ(result.status, 2) << result.output;
  EXPECT_TRUE(std::regex_search(
      result.output,
      std::regex(std::regex_replace(path, std::regex("[.]"), "\\.") + ":3:[0-9]+: ")))
      << result.output;

  const CliResult missing = runCommand(kSheriff + " -u memq:// /nonexistent/x.pmd </dev/null");
  EXPECT_EQ(missing.status, 2) << missing.output;
  EXPECT_TRUE(contains(missing, "/nonexistent/x.pmd")) << missing.output;
}

TEST(SheriffCli, AnUnknownScriptExitsTwo) {
  const CliResult result = runCommand(kSheriff + " -u memq:// " + sheet() + " nope </dev/null");
  EXPECT_EQ(result.status, 2) << result.output;
  EXPECT_TRUE(contains(result, "no script 'nope'")) << result.output;
}

TEST(SheriffCli, AnswersConsoleCommandsAndQuits) {
  const CliResult result = runCommand(
      "printf 'help\\nstatus\\nstart cmd world\\nstart nope\\nfrobnicate\\nrun nope\\nquit\\n' | " +
      kSheriff + " -u memq:// --status-period 0 " + sheet());
  EXPECT_EQ(result.status, 0) << result.output;
  EXPECT_TRUE(contains(result, "start|stop|restart cmd NAME")) << result.output;  // help
  EXPECT_TRUE(std::regex_search(result.output, std::regex("sim/world +alpha.* +Unknown")))
      << result.output;  // status
  EXPECT_TRUE(contains(result, "deputy 'alpha': not heard from")) << result.output;
  EXPECT_TRUE(contains(result, "[sheriff] start cmd 'world'")) << result.output;
  EXPECT_TRUE(contains(result, "no command or group 'nope'")) << result.output;
  EXPECT_TRUE(contains(result, "unknown command 'frobnicate'")) << result.output;
  EXPECT_TRUE(contains(result, "cannot run script: no script 'nope'")) << result.output;
  EXPECT_TRUE(contains(result, "quit requested")) << result.output;
}

TEST(SheriffCli, EndOfInputDoesNotQuitAndTheScriptEndsIt) {
  const CliResult result =
      runCommand(kSheriff + " -u memq:// --exit-after-script " + sheet() + " pause </dev/null");
  EXPECT_EQ(result.status, 0) << result.output;
  EXPECT_TRUE(contains(result, "stdin closed; still running")) << result.output;
  EXPECT_TRUE(contains(result, "script 'pause' completed")) << result.output;
}

TEST(SheriffCli, AWaitThatTimesOutExitsOne) {
  // No deputy answers on memq://, so the wait for "running" cannot be satisfied.
  const CliResult result =
      runCommand(kSheriff + " -u memq:// --exit-after-script --wait-timeout 0.2 " + sheet() +
                 " up </dev/null");
  EXPECT_EQ(result.status, 1) << result.output;
  EXPECT_TRUE(contains(result, "timed out after 0.2 s waiting for group 'sim' to be running"))
      << result.output;
}

TEST(SheriffCli, AnObserverNeedsNoSheetAndRefusesToAct) {
  const CliResult result = runCommand("printf 'start everything\\nrun pause\\nquit\\n' | " +
                                      kSheriff + " -o -u memq:// --status-period 0 " + sheet());
  EXPECT_EQ(result.status, 0) << result.output;
  EXPECT_TRUE(contains(result, "observer mode sends no orders")) << result.output;
  EXPECT_TRUE(contains(result, "an observer cannot run scripts")) << result.output;
  const CliResult bare = runCommand("echo quit | " + kSheriff + " -o -u memq://");
  EXPECT_EQ(bare.status, 0) << bare.output;
}

}  // namespace
