#include "thicket/procman/sheet.h"

#include <unistd.h>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace {

using thicket::procman::formatSheet;
using thicket::procman::loadSheet;
using thicket::procman::parseSheet;
using thicket::procman::Sheet;
using thicket::procman::SheetAction;
using thicket::procman::SheetCommand;
using thicket::procman::SheetTarget;

using Kind = SheetAction::Kind;
using WaitFor = SheetAction::WaitFor;
using Target = SheetTarget::Kind;

// A bring-up sheet using every construct of the grammar.
const char* const kRichSheet = R"pmd(# Forest demo bring-up.
script "early" {            # scripts may name what comes later
    stop cmd "mapper" wait "stopped";
}
cmd "lcm-logger" {
    exec = "lcm-logger \"/data/sim log\" --tag=a\b\\c\td\n";  # escapes
    host = "base";
    auto_respawn = "TRUE";
}
group "sim" {
    cmd "simulator" {
        exec="thicket-sim --world forest.yaml";deputy="sim-box";
        stop_signal = 15;
        stop_time_allowed = 3;
    }
    group "sensors" {
        cmd "stereo" { exec = "thicket-stereo-depth"; deputy = "sim-box"; auto_respawn = "Yes"; }
        cmd "vio" { exec = "thicket-vio-bridge"; host = "sim-box"; auto_respawn = "no"; }
    }
}
group "planning" {
    cmd "mapper" { exec = "thicket-mapper"; deputy = "planner"; auto_respawn = "false"; }
    group "spare" { }
}
group "sim" {   # the same group again: adds to it
    cmd "explorer" { exec = "thicket-explorer"; deputy = "planner"; stop_time_allowed = 0; }
}
script "bringup" {
    start cmd "lcm-logger";
    start group "sim/sensors" wait "running";
    wait ms 500;
    start group "sim" wait "running";
    wait cmd "simulator" status "running";
    restart cmd "vio";
    run_script "planning";
    wait group "planning" status "stopped";
}
script "planning" {
    start cmd "mapper" wait "stopped";
    stop everything;
    restart everything wait "running";
    stop group "planning/spare" wait "stopped";
    restart group "sim/sensors";
    run_script "early";
}
)pmd";

Sheet parseOk(const std::string& text) {
  const auto sheet = parseSheet(text, "test.pmd");
  EXPECT_TRUE(sheet.ok()) << sheet.error();
  return sheet.ok() ? *sheet : Sheet{};
}

// The error message, or a note that there was none.
std::string errorOf(const std::string& text) {
  const auto sheet = parseSheet(text, "t.pmd");
  return sheet.ok() ? "(parsed)" : sheet.error();
}

// A sheet with its line and column fields cleared, for comparing content.
Sheet withoutPositions(Sheet sheet) {
  for (SheetCommand& command : sheet.commands) command.line = 0;
  for (auto& script : sheet.scripts) {
    script.line = 0;
    for (SheetAction& action : script.actions) action.line = action.column = 0;
  }
  return sheet;
}

std::vector<std::string> ids(const std::vector<const SheetCommand*>& commands) {
  std::vector<std::string> out;
  for (const SheetCommand* command : commands) out.push_back(command->id);
  return out;
}

// A minimal valid command around one attribute line, for attribute errors.
std::string commandWith(const std::string& attributes) {
  return "cmd \"c\" {\n" + attributes + "\n}\n";
}

TEST(Sheet, ParsesCommandsWithEveryAttributeAndBothDeputySpellings) {
  const Sheet sheet = parseOk(kRichSheet);
  ASSERT_EQ(sheet.commands.size(), 6u);

  const SheetCommand& logger = sheet.commands[0];
  EXPECT_EQ(logger.id, "lcm-logger");
  EXPECT_EQ(logger.group, "");
  EXPECT_EQ(logger.exec, "lcm-logger \"/data/sim log\" --tag=ab\\c\td\n");
  EXPECT_EQ(logger.deputy, "base");  // spelled `host`
  EXPECT_TRUE(logger.auto_respawn);  // "TRUE"
  EXPECT_EQ(logger.stop_signal, 2);
  EXPECT_EQ(logger.stop_time_allowed, 7);
  EXPECT_EQ(logger.line, 5);

  const SheetCommand& simulator = sheet.commands[1];
  EXPECT_EQ(simulator.id, "simulator");
  EXPECT_EQ(simulator.group, "sim");
  EXPECT_EQ(simulator.exec, "thicket-sim --world forest.yaml");
  EXPECT_EQ(simulator.deputy, "sim-box");  // spelled `deputy`
  EXPECT_FALSE(simulator.auto_respawn);
  EXPECT_EQ(simulator.stop_signal, 15);
  EXPECT_EQ(simulator.stop_time_allowed, 3);
  EXPECT_EQ(simulator.line, 11);

  EXPECT_EQ(sheet.commands[2].id, "stereo");
  EXPECT_EQ(sheet.commands[2].group, "sim/sensors");
  EXPECT_TRUE(sheet.commands[2].auto_respawn);  // "Yes"
  EXPECT_EQ(sheet.commands[3].id, "vio");
  EXPECT_EQ(sheet.commands[3].group, "sim/sensors");
  EXPECT_EQ(sheet.commands[3].deputy, "sim-box");
  EXPECT_FALSE(sheet.commands[3].auto_respawn);  // "no"
  EXPECT_EQ(sheet.commands[4].id, "mapper");
  EXPECT_EQ(sheet.commands[4].group, "planning");
  EXPECT_FALSE(sheet.commands[4].auto_respawn);  // "false"
  EXPECT_EQ(sheet.commands[5].id, "explorer");
  EXPECT_EQ(sheet.commands[5].group, "sim");  // the second "sim" block merged into the first
  EXPECT_EQ(sheet.commands[5].stop_time_allowed, 0);

  EXPECT_EQ(sheet.groups,
            (std::vector<std::string>{"sim", "sim/sensors", "planning", "planning/spare"}));
  ASSERT_NE(sheet.command("vio"), nullptr);
  EXPECT_EQ(sheet.command("vio")->exec, "thicket-vio-bridge");
  EXPECT_EQ(sheet.command("sensors"), nullptr);
}

TEST(Sheet, ParsesEveryActionForm) {
  const Sheet sheet = parseOk(kRichSheet);
  ASSERT_EQ(sheet.scripts.size(), 3u);
  EXPECT_EQ(sheet.scripts[0].name, "early");
  EXPECT_EQ(sheet.scripts[0].line, 2);
  ASSERT_EQ(sheet.script("bringup"), &sheet.scripts[1]);
  EXPECT_EQ(sheet.script("missing"), nullptr);

  const auto& bringup = sheet.scripts[1].actions;
  ASSERT_EQ(bringup.size(), 8u);
  EXPECT_EQ(bringup[0].kind, Kind::kStart);
  EXPECT_EQ(bringup[0].target, (SheetTarget{Target::kCommand, "lcm-logger"}));
  EXPECT_EQ(bringup[0].wait, WaitFor::kNothing);
  EXPECT_EQ(bringup[0].line, 29);
  EXPECT_EQ(bringup[0].column, 5);
  EXPECT_EQ(bringup[1].kind, Kind::kStart);
  EXPECT_EQ(bringup[1].target, (SheetTarget{Target::kGroup, "sim/sensors"}));
  EXPECT_EQ(bringup[1].wait, WaitFor::kRunning);
  EXPECT_EQ(bringup[2].kind, Kind::kWaitMs);
  EXPECT_EQ(bringup[2].ms, 500);
  EXPECT_EQ(bringup[4].kind, Kind::kWaitStatus);
  EXPECT_EQ(bringup[4].target, (SheetTarget{Target::kCommand, "simulator"}));
  EXPECT_EQ(bringup[4].wait, WaitFor::kRunning);
  EXPECT_EQ(bringup[5].kind, Kind::kRestart);
  EXPECT_EQ(bringup[5].wait, WaitFor::kNothing);
  EXPECT_EQ(bringup[6].kind, Kind::kRunScript);
  EXPECT_EQ(bringup[6].script, "planning");
  EXPECT_EQ(bringup[7].kind, Kind::kWaitStatus);
  EXPECT_EQ(bringup[7].target, (SheetTarget{Target::kGroup, "planning"}));
  EXPECT_EQ(bringup[7].wait, WaitFor::kStopped);

  const auto& planning = sheet.scripts[2].actions;
  ASSERT_EQ(planning.size(), 6u);
  EXPECT_EQ(planning[0].kind, Kind::kStart);
  EXPECT_EQ(planning[0].wait, WaitFor::kStopped);
  EXPECT_EQ(planning[1].kind, Kind::kStop);
  EXPECT_EQ(planning[1].target, (SheetTarget{Target::kEverything, ""}));
  EXPECT_EQ(planning[2].kind, Kind::kRestart);
  EXPECT_EQ(planning[2].target.kind, Target::kEverything);
  EXPECT_EQ(planning[2].wait, WaitFor::kRunning);
  EXPECT_EQ(planning[3].kind, Kind::kStop);
  EXPECT_EQ(planning[3].target, (SheetTarget{Target::kGroup, "planning/spare"}));
  EXPECT_EQ(planning[3].wait, WaitFor::kStopped);
  EXPECT_EQ(planning[4].kind, Kind::kRestart);
  EXPECT_EQ(planning[5].script, "early");
}

TEST(Sheet, EmptyTextAndCommentsOnlyAreAnEmptySheet) {
  EXPECT_EQ(parseOk(""), Sheet{});
  EXPECT_EQ(parseOk("  # nothing here\n\t\r\n# cmd \"x\" {\n"), Sheet{});
}

TEST(Sheet, CommandsInGroupCoverSubgroupsInSheetOrder) {
  const Sheet sheet = parseOk(kRichSheet);
  EXPECT_EQ(ids(sheet.commandsInGroup("sim")),
            (std::vector<std::string>{"simulator", "stereo", "vio", "explorer"}));
  EXPECT_EQ(ids(sheet.commandsInGroup("sim/sensors")), (std::vector<std::string>{"stereo", "vio"}));
  EXPECT_EQ(ids(sheet.commandsInGroup("planning")), (std::vector<std::string>{"mapper"}));
  EXPECT_TRUE(sheet.commandsInGroup("planning/spare").empty());
  EXPECT_TRUE(sheet.commandsInGroup("si").empty());  // a prefix of a name is not a group
  EXPECT_TRUE(sheet.commandsInGroup("sensors").empty());
  EXPECT_EQ(sheet.commandsInGroup("").size(), 6u);
}

TEST(Sheet, FormatRoundTripsARichSheet) {
  const Sheet original = parseOk(kRichSheet);
  const std::string text = formatSheet(original);
  const Sheet reparsed = parseOk(text);
  EXPECT_EQ(withoutPositions(reparsed), withoutPositions(original)) << text;
  EXPECT_EQ(formatSheet(reparsed), text);  // canonical: formatting is idempotent

  EXPECT_NE(text.find(R"(exec = "lcm-logger \"/data/sim log\" --tag=ab\\c\td\n";)"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find(R"(deputy = "base";)"), std::string::npos) << text;
  EXPECT_EQ(text.find("host ="), std::string::npos) << text;
  EXPECT_NE(text.find("    group \"sensors\" {\n        cmd \"stereo\" {"), std::string::npos)
      << text;
}

TEST(Sheet, FormatWritesTheCanonicalText) {
  const Sheet sheet = parseOk(R"(
    group "a" { group "b" { cmd "x" { host = "h"; exec = "run\\me"; stop_signal = 9; } } }
    cmd "y" { exec = "y"; deputy = "h"; auto_respawn = "yes"; }
    script "s" { start group "a/b" wait "running"; wait ms 10; run_script "s2"; }
    script "s2" { wait cmd "y" status "stopped"; }
  )");
  EXPECT_EQ(formatSheet(sheet), R"(group "a" {
    group "b" {
        cmd "x" {
            exec = "run\\me";
            deputy = "h";
            stop_signal = 9;
        }
    }
}

cmd "y" {
    exec = "y";
    deputy = "h";
    auto_respawn = "true";
}

script "s" {
    start group "a/b" wait "running";
    wait ms 10;
    run_script "s2";
}

script "s2" {
    wait cmd "y" status "stopped";
}
)");
}

TEST(Sheet, FormatKeepsCommandOrderAcrossSplitGroups) {
  Sheet sheet;
  sheet.groups = {"a", "a/b", "empty"};
  const auto add = [&](const std::string& id, const std::string& group) {
    SheetCommand command;
    command.id = id;
    command.group = group;
    command.exec = id;
    command.deputy = "d";
    sheet.commands.push_back(command);
  };
  add("one", "a/b");
  add("two", "");
  add("three", "a");
  add("four", "a/b");
  const Sheet reparsed = parseOk(formatSheet(sheet));
  EXPECT_EQ(withoutPositions(reparsed), sheet) << formatSheet(sheet);
}

TEST(Sheet, LoadReadsAFileAndNamesItInErrors) {
  const std::string path = ::testing::TempDir() + "/sheet_" + std::to_string(::getpid()) + ".pmd";
  {
    std::ofstream file(path);
    file << "cmd \"a\" { exec = \"a\"; deputy = \"d\"; }\ncmd \"b\" { exce = \"b\"; }\n";
  }
  const auto sheet = loadSheet(path);
  ASSERT_FALSE(sheet.ok());
  EXPECT_EQ(sheet.error(), path +
                               ":2:11: unknown attribute 'exce' (known: exec, host, deputy, "
                               "auto_respawn, stop_signal, stop_time_allowed)");
  {
    std::ofstream file(path);
    file << "cmd \"a\" { exec = \"a\"; deputy = \"d\"; }\n";
  }
  const auto fixed = loadSheet(path);
  ASSERT_TRUE(fixed.ok()) << fixed.error();
  EXPECT_EQ(fixed->commands.size(), 1u);
  ::unlink(path.c_str());
}

TEST(Sheet, LoadRefusesAMissingFile) {
  const std::string path = ::testing::TempDir() + "/no_such_dir/missing.pmd";
  const auto sheet = loadSheet(path);
  ASSERT_FALSE(sheet.ok());
  EXPECT_EQ(sheet.error(), path + ": cannot read");
}

TEST(SheetErrors, Attributes) {
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\"; deputy = \"d\";\n  exce = \"x\";")),
            "t.pmd:3:3: unknown attribute 'exce' (known: exec, host, deputy, auto_respawn, "
            "stop_signal, stop_time_allowed)");
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\"; deputy = \"d\"; exec = \"y\";")),
            "t.pmd:2:29: duplicate attribute 'exec' (already given at line 2)");
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\";\n  host = \"a\";\n  deputy = \"b\";")),
            "t.pmd:4:3: both 'host' and 'deputy' given; they are two spellings of the same "
            "attribute, keep one");
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\"; deputy = \"d\"; stop_signal = \"9\";")),
            "t.pmd:2:43: attribute 'stop_signal' takes an integer, got string \"9\"");
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\"; deputy = \"d\"; stop_time_allowed = \"5\";")),
            "t.pmd:2:49: attribute 'stop_time_allowed' takes an integer, got string \"5\"");
  EXPECT_EQ(errorOf(commandWith("  exec = 5; deputy = \"d\";")),
            "t.pmd:2:10: attribute 'exec' takes a string, got integer 5");
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\"; deputy = \"d\"; auto_respawn = 1;")),
            "t.pmd:2:44: attribute 'auto_respawn' takes a string, got integer 1");
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\"; deputy = \"d\"; stop_signal = 0;")),
            "t.pmd:2:43: stop_signal 0 is out of range (1..64)");
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\"; deputy = \"d\"; stop_signal = 65;")),
            "t.pmd:2:43: stop_signal 65 is out of range (1..64)");
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\"; deputy = \"d\"; stop_time_allowed = 2147483648;")),
            "t.pmd:2:49: stop_time_allowed 2147483648 is out of range (0..2147483647 seconds)");
  EXPECT_EQ(errorOf(commandWith("  exec = \"x\"; deputy = \"d\"; stop_signal = 64;")), "(parsed)");
}

TEST(SheetErrors, MissingRequiredAttributePointsAtTheCommand) {
  EXPECT_EQ(errorOf("\n  cmd \"cam\" {\n    deputy = \"d\";\n  }\n"),
            "t.pmd:2:3: command \"cam\" has no 'exec' attribute");
  EXPECT_EQ(errorOf("group \"g\" {\n cmd \"cam\" { exec = \"x\"; }\n}"),
            "t.pmd:2:2: command \"cam\" has no 'deputy' (or 'host') attribute");
}

TEST(SheetErrors, CommandIds) {
  EXPECT_EQ(errorOf("cmd \"a\" { exec = \"x\"; deputy = \"d\"; }\n"
                    "group \"g\" {\n"
                    "  group \"h\" { cmd \"a\" { exec = \"y\"; deputy = \"d\"; } }\n"
                    "}\n"),
            "t.pmd:3:19: duplicate command id \"a\" (first defined at line 1; ids are global to "
            "the sheet)");
  EXPECT_EQ(errorOf("cmd \"sim/cam\" { exec = \"x\"; deputy = \"d\"; }"),
            "t.pmd:1:5: command id \"sim/cam\" contains '/' (a command's group comes from the "
            "enclosing group blocks)");
  EXPECT_EQ(errorOf("group \"g\" {\n  cmd \"\" { exec = \"x\"; deputy = \"d\"; }\n}"),
            "t.pmd:2:7: empty command id");
}

TEST(SheetErrors, MessagesShowNamesShortAndWithoutControlCharacters) {
  const std::string huge = "sim/" + std::string(2 << 20, 'x');
  EXPECT_EQ(errorOf("cmd \"" + huge + "\" { exec = \"x\"; deputy = \"d\"; }"),
            "t.pmd:1:5: command id \"sim/" + std::string(56, 'x') +
                "... (2097156 bytes)\" contains '/' (a command's group comes from the enclosing "
                "group blocks)");
  EXPECT_EQ(errorOf("cmd \"a/\x1b[2J\" { exec = \"x\"; deputy = \"d\"; }"),
            "t.pmd:1:5: command id \"a/\\x1b[2J\" contains '/' (a command's group comes from the "
            "enclosing group blocks)");
}

TEST(SheetErrors, GroupNames) {
  EXPECT_EQ(errorOf("group \"a/b\" { }"),
            "t.pmd:1:7: group name \"a/b\" contains '/' (write nested group blocks for a "
            "subgroup)");
  EXPECT_EQ(errorOf("group \"a\" {\n    group \"\" { }\n}"), "t.pmd:2:11: empty group name");
}

TEST(SheetErrors, GroupsNestAtMostAHundredDeep) {
  std::string deep;
  for (int i = 0; i < 101; ++i) deep += "group \"g\" {\n";
  deep += std::string(101, '}');
  EXPECT_EQ(errorOf(deep), "t.pmd:101:1: groups nest too deeply (at most 100 levels)");
  std::string allowed;
  for (int i = 0; i < 100; ++i) allowed += "group \"g\" {\n";
  allowed += std::string(100, '}');
  EXPECT_EQ(errorOf(allowed), "(parsed)");
}

TEST(SheetErrors, Scripts) {
  EXPECT_EQ(errorOf("script \"s\" { }\n\nscript \"s\" { }"),
            "t.pmd:3:8: duplicate script name \"s\" (first defined at line 1)");
  EXPECT_EQ(errorOf("script \"\" { }"), "t.pmd:1:8: empty script name");
  EXPECT_EQ(errorOf("script \"s\" {\n  wait cmd \"a\" status \"done\";\n}"),
            "t.pmd:2:23: expected \"running\" or \"stopped\", got string \"done\"");
  EXPECT_EQ(errorOf("script \"s\" {\n  start cmd \"a\" wait running;\n}"),
            "t.pmd:2:22: expected \"running\" or \"stopped\", got 'running'");
  EXPECT_EQ(errorOf("script \"s\" {\n  wait everything status \"running\";\n}"),
            "t.pmd:2:8: expected 'ms', 'cmd' or 'group' after 'wait', got 'everything'");
  EXPECT_EQ(errorOf("script \"s\" {\n  launch everything;\n}"),
            "t.pmd:2:3: expected an action ('start', 'stop', 'restart', 'wait' or 'run_script') "
            "or '}' closing script \"s\", got 'launch'");
  EXPECT_EQ(errorOf("script \"s\" { stop host \"a\"; }"),
            "t.pmd:1:19: expected 'everything', 'cmd' or 'group' after 'stop', got 'host'");
}

TEST(SheetErrors, UnknownNamesInScripts) {
  const std::string commands =
      "group \"outer\" {\n"
      "  group \"inner\" { cmd \"a\" { exec = \"x\"; deputy = \"d\"; } }\n"
      "}\n";
  EXPECT_EQ(errorOf(commands + "script \"s\" {\n  start cmd \"b\";\n}"),
            "t.pmd:5:13: script \"s\" names unknown command \"b\"");
  EXPECT_EQ(errorOf(commands + "script \"s\" {\n  wait cmd \"b\" status \"running\";\n}"),
            "t.pmd:5:12: script \"s\" names unknown command \"b\"");
  EXPECT_EQ(errorOf(commands + "script \"s\" {\n  stop group \"inner\";\n}"),
            "t.pmd:5:14: script \"s\" names unknown group \"inner\" (groups are named by their "
            "full path, e.g. \"outer/inner\")");
  EXPECT_EQ(errorOf(commands + "script \"s\" {\n  stop group \"other\";\n}"),
            "t.pmd:5:14: script \"s\" names unknown group \"other\"");
  EXPECT_EQ(errorOf(commands + "script \"s\" {\n  stop group \"outer/inner\";\n}"), "(parsed)");
  EXPECT_EQ(errorOf(commands + "script \"s\" {\n  run_script \"t\";\n}"),
            "t.pmd:5:14: script \"s\" runs unknown script \"t\"");
}

TEST(SheetErrors, ScriptsThatRunThemselves) {
  EXPECT_EQ(errorOf("script \"s\" {\n  wait ms 1;\n  run_script \"s\";\n}"),
            "t.pmd:3:14: script \"s\" would run itself: s -> s");
  // "top" only reaches the cycle; it is reported at the run_script that closes it.
  EXPECT_EQ(errorOf("script \"top\" { run_script \"a\"; }\n"
                    "script \"a\" { run_script \"b\"; }\n"
                    "script \"b\" { run_script \"c\"; }\n"
                    "script \"c\" { wait ms 5; run_script \"a\"; }\n"),
            "t.pmd:4:36: script \"a\" would run itself: a -> b -> c -> a");
  // Running a script twice, or two scripts running the same one, is no cycle.
  EXPECT_EQ(errorOf("script \"a\" { run_script \"c\"; run_script \"c\"; }\n"
                    "script \"b\" { run_script \"c\"; run_script \"a\"; }\n"
                    "script \"c\" { wait ms 1; }\n"),
            "(parsed)");
}

TEST(SheetErrors, Syntax) {
  EXPECT_EQ(errorOf("cmd \"a\" {\n  exec = \"x\"\n  deputy = \"d\";\n}"),
            "t.pmd:3:3: expected ';' after the value of 'exec', got 'deputy'");
  EXPECT_EQ(errorOf("cmd \"a\" { exec \"x\"; }"),
            "t.pmd:1:16: expected '=' after 'exec', got string \"x\"");
  EXPECT_EQ(errorOf("cmd a { }"),
            "t.pmd:1:5: expected the command id (a string) after 'cmd', "
            "got 'a'");
  EXPECT_EQ(errorOf("cmd \"a\" { exec = ; }"),
            "t.pmd:1:18: expected a string or an integer as the value of 'exec', got ';'");
  EXPECT_EQ(errorOf("\n\ncommand \"a\" { }"),
            "t.pmd:3:1: expected 'cmd', 'group' or 'script', got 'command'");
  EXPECT_EQ(errorOf("group \"g\" {\n  script \"s\" { }\n}"),
            "t.pmd:2:3: expected 'cmd', 'group' or '}' closing group \"g\" (opened at line 1), "
            "got 'script'");
  EXPECT_EQ(errorOf("script \"s\" { wait ms -5; }"), "t.pmd:1:22: unexpected character '-'");
}

TEST(SheetErrors, UnexpectedEndOfFile) {
  EXPECT_EQ(errorOf("group \"g\" {\n  cmd \"a\" { exec = \"x\"; deputy = \"d\"; }\n"),
            "t.pmd:3:1: unexpected end of file, expected 'cmd', 'group' or '}' closing group "
            "\"g\" (opened at line 1)");
  EXPECT_EQ(errorOf("cmd \"a\" { exec ="),
            "t.pmd:1:17: unexpected end of file, expected a "
            "string or an integer as the value of 'exec'");
  EXPECT_EQ(errorOf("script \"s\" { start cmd \"a\" wait"),
            "t.pmd:1:32: unexpected end of file, expected \"running\" or \"stopped\"");
}

TEST(SheetErrors, Lexical) {
  EXPECT_EQ(errorOf("cmd \"a\" {\n  exec = \"x;\n  deputy = \"d\";\n}"),
            "t.pmd:2:10: unterminated string: it runs into the end of the line (write a newline "
            "as \\n)");
  EXPECT_EQ(errorOf("cmd \"a\" {\n  exec = \"x\\\n\";\n}"),  // backslash, then a raw newline
            "t.pmd:2:10: unterminated string: it runs into the end of the line (write a newline "
            "as \\n)");
  EXPECT_EQ(errorOf("cmd \"a\" { exec = \"x"),
            "t.pmd:1:18: unterminated string: the file ends before its closing '\"'");
  EXPECT_EQ(errorOf("cmd \"a\" { exec = \"x\\"),
            "t.pmd:1:18: unterminated string: the file ends before its closing '\"'");
  EXPECT_EQ(errorOf("script \"s\" {\n  wait ms 9223372036854775808;\n}"),
            "t.pmd:2:11: integer 9223372036854775808 is too large (at most "
            "9223372036854775807)");
  EXPECT_EQ(errorOf("cmd \"a\" {\n\texec = 'x';\n}"), "t.pmd:2:9: unexpected character '''");
  // Columns count characters, not bytes: a curly quote is one.
  EXPECT_EQ(errorOf("# \xc3\xa9t\xc3\xa9\ncmd \xe2\x80\x9c"
                    "a\xe2\x80\x9d { }"),
            "t.pmd:2:5: unexpected character '\xe2\x80\x9c'");
  EXPECT_EQ(errorOf("cmd \"\xc3\xa9\" { exec = \"x\"; deputy = \"d\"; } @"),
            "t.pmd:1:39: unexpected character '@'");
  EXPECT_EQ(errorOf("cmd \"a\" {\x01}"), "t.pmd:1:10: unexpected character 0x01");
}

TEST(SheetErrors, IntegersUpToTheLimitAreAccepted) {
  const Sheet sheet = parseOk("script \"s\" { wait ms 9223372036854775807; wait ms 0; }");
  ASSERT_EQ(sheet.scripts.size(), 1u);
  ASSERT_EQ(sheet.scripts[0].actions.size(), 2u);
  EXPECT_EQ(sheet.scripts[0].actions[0].ms, INT64_MAX);
  EXPECT_EQ(sheet.scripts[0].actions[1].ms, 0);
}

}  // namespace

namespace thicket::procman {
namespace {

// The sheets thicket ships parse, run programs that the build makes (from build/, in the source
// directory that builds them) or LCM's tools (lcm-logplayer), and have the scripts an operator
// presses.
TEST(ShippedSheets, ParseAndNameWhatExists) {
  const std::string root = THICKET_SOURCE_DIR;
  const std::vector<std::pair<std::string, std::vector<std::string>>> sheets = {
      {"sim.pmd", {"graph", "fly", "stop"}},
      {"sim_stereo.pmd", {"graph", "fly", "stop"}},
      {"vehicle.pmd", {"bringup", "land", "shutdown"}},
      {"replay.pmd", {"replay", "stop"}}};
  for (const auto& [file, scripts] : sheets) {
    const auto sheet = loadSheet(root + "/config/" + file);
    ASSERT_TRUE(sheet) << sheet.error();
    for (const std::string& script : scripts) EXPECT_NE(sheet->script(script), nullptr) << file;
    for (const SheetCommand& c : sheet->commands) {
      const std::string program = c.exec.substr(0, c.exec.find(' '));
      EXPECT_TRUE(program.rfind("build/", 0) == 0 || program.rfind("lcm-", 0) == 0)
          << file << ": " << c.exec;
      if (program.rfind("build/", 0) == 0) {
        const std::string source = root + "/" + program.substr(6);
        const std::string dir = source.substr(0, source.rfind('/'));
        EXPECT_EQ(::access((dir + "/CMakeLists.txt").c_str(), F_OK), 0)
            << file << ": nothing builds " << program;
      }
    }
  }
}

}  // namespace
}  // namespace thicket::procman
