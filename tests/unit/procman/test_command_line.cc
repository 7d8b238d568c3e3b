// Exec strings split as a procman deputy does it: no shell, quotes, escapes, assignments and
// variable expansion from a given environment.
#include <gtest/gtest.h>

#include <cstdlib>

#include "thicket/procman/command_line.h"

namespace thicket::procman {
namespace {

using Argv = std::vector<std::string>;
using Assignments = std::vector<std::pair<std::string, std::string>>;

const Environment kEnv = {{"HOME", "/home/robot"}, {"SPACED", "a b"}, {"EMPTY", ""}};

CommandLine split(const std::string& exec, const Environment& env = kEnv) {
  auto result = splitCommandLine(exec, env);
  EXPECT_TRUE(result.ok()) << exec << ": " << result.error();
  return result.ok() ? *result : CommandLine{};
}

TEST(CommandLine, WhitespaceSeparatesWords) {
  EXPECT_EQ(split("prog a  b\tc\n d ").argv, (Argv{"prog", "a", "b", "c", "d"}));
  EXPECT_EQ(split("  prog").argv, (Argv{"prog"}));
  EXPECT_TRUE(split("prog").assignments.empty());
}

TEST(CommandLine, QuotesGroupAndJoin) {
  EXPECT_EQ(split("echo 'a b' \"c d\"").argv, (Argv{"echo", "a b", "c d"}));
  EXPECT_EQ(split("echo x'a b'y\"c\"z").argv, (Argv{"echo", "xa bycz"}));
  EXPECT_EQ(split("echo '' \"\"").argv, (Argv{"echo", "", ""}));
  EXPECT_EQ(split("echo \"it's\" 'say \"hi\"'").argv, (Argv{"echo", "it's", "say \"hi\""}));
}

TEST(CommandLine, BackslashEscapes) {
  EXPECT_EQ(split("echo a\\ b").argv, (Argv{"echo", "a b"}));
  EXPECT_EQ(split("echo \\'x\\\" \\\\").argv, (Argv{"echo", "'x\"", "\\"}));
  EXPECT_EQ(split("echo \"a\\\"b\"").argv, (Argv{"echo", "a\"b"}));
  EXPECT_EQ(split("echo 'a\\b'").argv, (Argv{"echo", "a\\b"})) << "literal in single quotes";
  EXPECT_EQ(split("echo \\$HOME").argv, (Argv{"echo", "$HOME"}));
  EXPECT_EQ(split("echo end\\").argv, (Argv{"echo", "end\\"})) << "a trailing backslash stays";
}

TEST(CommandLine, LeadingAssignmentsBecomeEnvironment) {
  const CommandLine c = split("A=1 B_2=\"x y\" C= prog D=4 --e=f");
  EXPECT_EQ(c.assignments, (Assignments{{"A", "1"}, {"B_2", "x y"}, {"C", ""}}));
  EXPECT_EQ(c.argv, (Argv{"prog", "D=4", "--e=f"}));
  // Not assignments: a quoted or escaped name, an invalid name, no name.
  EXPECT_EQ(split("'A'=1 prog").argv, (Argv{"A=1", "prog"}));
  EXPECT_EQ(split("A\\=1 prog").argv, (Argv{"A=1", "prog"}));
  EXPECT_EQ(split("1A=1 prog").argv, (Argv{"1A=1", "prog"}));
  EXPECT_EQ(split("=1 prog").argv, (Argv{"=1", "prog"}));
  EXPECT_EQ(split("A=b=c prog").assignments, (Assignments{{"A", "b=c"}}));
}

TEST(CommandLine, VariablesExpand) {
  EXPECT_EQ(split("ls $HOME ${HOME}/x a${HOME}b").argv,
            (Argv{"ls", "/home/robot", "/home/robot/x", "a/home/robotb"}));
  EXPECT_EQ(split("echo \"$HOME/${SPACED}\"").argv, (Argv{"echo", "/home/robot/a b"}));
  EXPECT_EQ(split("echo $SPACED").argv, (Argv{"echo", "a b"})) << "values are not split";
  EXPECT_EQ(split("echo x$EMPTY.").argv, (Argv{"echo", "x."}));
  EXPECT_EQ(split("P=$HOME/bin prog").assignments, (Assignments{{"P", "/home/robot/bin"}}));
  EXPECT_EQ(split("echo $HOMEX $HOME.x").argv, (Argv{"echo", "$HOMEX", "/home/robot.x"}));
}

TEST(CommandLine, UndefinedAndMalformedReferencesStayLiteral) {
  EXPECT_EQ(split("echo $NOPE ${NOPE} \"$NOPE\"").argv,
            (Argv{"echo", "$NOPE", "${NOPE}", "$NOPE"}));
  EXPECT_EQ(split("echo $ $1 ${ ${HOME ${-x} a$").argv,
            (Argv{"echo", "$", "$1", "${", "${HOME", "${-x}", "a$"}));
}

TEST(CommandLine, NoExpansionInSingleQuotes) {
  EXPECT_EQ(split("echo '$HOME ${HOME}'").argv, (Argv{"echo", "$HOME ${HOME}"}));
}

TEST(CommandLine, AssignmentsDoNotFeedExpansion) {
  const CommandLine c = split("HOME=/tmp X=$HOME prog $HOME");
  EXPECT_EQ(c.assignments, (Assignments{{"HOME", "/tmp"}, {"X", "/home/robot"}}));
  EXPECT_EQ(c.argv, (Argv{"prog", "/home/robot"}));
}

TEST(CommandLine, Errors) {
  for (const char* exec : {"", "   \t ", "A=1", "A=1 B=2  "}) {
    auto result = splitCommandLine(exec, kEnv);
    ASSERT_FALSE(result.ok()) << "'" << exec << "'";
    EXPECT_NE(result.error().find("empty command"), std::string::npos) << result.error();
  }
  auto single = splitCommandLine("echo 'abc", kEnv);
  ASSERT_FALSE(single.ok());
  EXPECT_EQ(single.error(), "unterminated single quote starting at column 6");
  auto dbl = splitCommandLine("echo \"a\\\"", kEnv);
  ASSERT_FALSE(dbl.ok());
  EXPECT_EQ(dbl.error(), "unterminated double quote starting at column 6");
}

TEST(CommandLine, ChildEnvironmentAppliesAssignments) {
  const CommandLine c = split("HOME=/tmp NEW=1 NEW=2 prog");
  const std::vector<std::string> env = childEnvironment(kEnv, c);
  EXPECT_EQ(env, (std::vector<std::string>{"EMPTY=", "HOME=/tmp", "NEW=2", "SPACED=a b"}));
}

TEST(CommandLine, CurrentEnvironmentReadsEnviron) {
  ::setenv("THICKET_COMMAND_LINE_TEST", "v=1", 1);
  const Environment env = currentEnvironment();
  ASSERT_EQ(env.count("THICKET_COMMAND_LINE_TEST"), 1u);
  EXPECT_EQ(env.at("THICKET_COMMAND_LINE_TEST"), "v=1");
  EXPECT_EQ(split("echo $THICKET_COMMAND_LINE_TEST", env).argv, (Argv{"echo", "v=1"}));
}

}  // namespace
}  // namespace thicket::procman
