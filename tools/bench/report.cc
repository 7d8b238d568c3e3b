// writeReport: summary.md and the figures of an output folder, from its trials and logs; and
// `thicket-bench report`, which writes them again.
#include "report.h"

#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "flags.h"
#include "report_figures.h"
#include "report_inputs.h"
#include "report_sections.h"
#include "thicket/common/subprocess.h"
#include "trials.h"

namespace thicket::bench {

using namespace report_internal;

std::string writeReport(const std::string& out_dir, const ReportOptions& options) {
  const std::string source = THICKET_SOURCE_DIR;
  const std::string worlds_dir =
      options.worlds_dir.empty() ? source + "/config/worlds" : options.worlds_dir;
  const std::string script =
      options.figures_script.empty() ? source + "/tools/bench/figures.py" : options.figures_script;
  Report report;
  report.out_dir = out_dir;
  report.figures_dir = out_dir + "/figures";
  std::vector<Trial> trials;
  try {
    trials = readTrials(out_dir + "/trials.csv");
  } catch (const std::exception& e) {
    return e.what();
  }
  std::vector<RunLogRow> runs;
  std::vector<E5Row> e5;
  bool has_e5 = false;
  try {
    if (std::filesystem::exists(out_dir + "/run_log.csv"))
      runs = readRunLog(out_dir + "/run_log.csv");
  } catch (const std::exception& e) {
    report.problems.push_back(e.what());
  }
  try {
    if (std::filesystem::exists(out_dir + "/e5_subsampling.csv")) {
      e5 = readE5(out_dir + "/e5_subsampling.csv");
      has_e5 = true;
    }
  } catch (const std::exception& e) {
    report.problems.push_back(e.what());
  }

  try {
    // This report's figures and their data replace any earlier report's.
    std::filesystem::create_directories(report.figures_dir);
    for (const auto& entry : std::filesystem::directory_iterator(report.figures_dir)) {
      if (reportFigureFile(entry.path().filename().string())) std::filesystem::remove(entry);
    }
    // The sections write the figures' data and leave a placeholder for each image.
    // (One statement each: the sections' side effects happen in the order of the summary.)
    std::string text = "# thicket benchmark report\n\n";
    text += overviewSection(trials, runs, has_e5, e5.size());
    text += throughputSection(trials, runs);
    text += safetySection(trials);
    text += worldsSection(trials);
    text += e1Section(report, trials);
    text += e2Section(report, trials);
    text += e3Section(report, trials);
    text += e4Section(report, trials, worlds_dir);
    text += t1Section(trials);
    text += e5Section(report, e5);
    text += e6Section(report, trials, worlds_dir);
    if (!report.figures.empty()) {
      const std::string error =
          runProgram({options.python, script, out_dir}, report.figures_dir + "/figures.log");
      if (!error.empty()) report.problems.push_back("figures: " + error);
    }
    for (const auto& [figure, caption] : report.captions) {
      const std::string marker = Report::marker(figure);
      const std::string link = std::filesystem::exists(report.figures_dir + "/" + figure)
                                   ? "![" + caption + "](figures/" + figure + ")\n\n"
                                   : "(Figure " + figure + " was not drawn: see Problems.)\n\n";
      for (size_t at = text.find(marker); at != std::string::npos; at = text.find(marker, at)) {
        text.replace(at, marker.size(), link);
        at += link.size();
      }
    }
    if (!report.problems.empty()) {
      text += "## Problems\n\n";
      for (const std::string& problem : report.problems) {
        text += "```\n" + problem + "\n```\n\n";
      }
    }
    writeTextFile(out_dir + "/summary.md", text);
  } catch (const std::exception& e) {
    report.problems.push_back(e.what());
  }
  std::string error;
  for (const std::string& problem : report.problems) error += (error.empty() ? "" : "\n") + problem;
  return error;
}

namespace {

struct ReportCommandOptions {
  std::string dir;
  std::string help;
};

constexpr const char* kReportHelp =
    "thicket-bench report: writes DIR/summary.md and DIR/figures/ again from DIR/trials.csv\n"
    "(and DIR/run_log.csv, DIR/e5_subsampling.csv and the E4 path files in DIR/paths/ when\n"
    "present), as experiment and merge do at their end: a report after a change of the\n"
    "statistics, from trials that did not change. Flies nothing.";

}  // namespace

int reportCommand(const std::vector<std::string>& args) {
  const std::string command = "report";
  const auto parsed = parseCommand<ReportCommandOptions>(
      command, kReportHelp, args, [](CLI::App& app, ReportCommandOptions& o) {
        app.add_option("DIR", o.dir, "an output folder of thicket-bench experiment or merge")
            ->required()
            ->check(CLI::ExistingDirectory);
      });
  if (!parsed) return usageError(command, parsed.error());
  if (!parsed->help.empty()) {
    std::fputs(parsed->help.c_str(), stdout);
    return 0;
  }
  const std::string error = writeReport(parsed->dir);
  if (!error.empty()) {
    warn(command, error);
    return 1;
  }
  std::printf("%s/summary.md written\n", parsed->dir.c_str());
  return 0;
}

}  // namespace thicket::bench
