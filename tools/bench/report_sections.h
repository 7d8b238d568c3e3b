// The sections of summary.md, and the Report they write figures' data and placeholders into.
#pragma once

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "report_inputs.h"
#include "trials.h"

namespace thicket::bench::report_internal {

// What the sections share: the folder, the figures whose data they wrote, their image
// placeholders, and the problems they met.
struct Report {
  std::string out_dir;
  std::string figures_dir;
  std::vector<std::string> problems;  // what could not be read or drawn; returned
  std::vector<std::string> figures;   // the PNGs figures.py is to draw (file names)

  void figureData(const std::string& figure, const std::string& name, const std::string& text) {
    writeTextFile(figures_dir + "/" + name, text);
    if (std::find(figures.begin(), figures.end(), figure) == figures.end()) {
      figures.push_back(figure);
    }
  }

  // A placeholder for the figure's image link; the link replaces it once figures.py has run.
  std::map<std::string, std::string> captions;
  std::string image(const std::string& figure, const std::string& caption) {
    captions[figure] = caption;
    return marker(figure);
  }
  static std::string marker(const std::string& figure) { return "<<figure " + figure + ">>\n\n"; }
};

std::string overviewSection(const std::vector<Trial>& trials, const std::vector<RunLogRow>& runs,
                            bool has_e5, size_t e5_rows);

std::string throughputSection(const std::vector<Trial>& trials, const std::vector<RunLogRow>& runs);

// Collisions of the conservative methods in every experiment and scenario (the target is zero;
// E6's count the dynamic obstacle too), and every such trial by key with its executed clearance,
// so a regression names the worlds to replay.
std::string safetySection(const std::vector<Trial>& trials);

std::string e1Section(Report& report, const std::vector<Trial>& trials);

// Every world (scenario, density, seed) once, whichever trials flew it: the oracle depends on
// the world and the planning radius, which every method shares.
std::string worldsSection(const std::vector<Trial>& trials);

// E2 on every scenario it was flown on, each on its own.
std::string e2Section(Report& report, const std::vector<Trial>& trials);

// E3 on the paper's world (its claim) with the figure; other scenarios' E2 trials each get a
// table of their own below it. Then frontier_memory's paths against both of the claim's methods,
// per scenario, where it was flown.
std::string e3Section(Report& report, const std::vector<Trial>& trials);

std::string e4Section(Report& report, const std::vector<Trial>& trials,
                      const std::string& worlds_dir);

// E6, a path blocked in flight: per method, whether the dynamic obstacle appeared, whether the
// vehicle came within the robot radius of it, how close it came, and how many planner cycles
// found the committed trajectory blocked. One table per scenario and density flown.
std::string e6Section(Report& report, const std::vector<Trial>& trials,
                      const std::string& worlds_dir);

std::string t1Section(const std::vector<Trial>& trials);

std::string e5Section(Report& report, const std::vector<E5Row>& rows);

}  // namespace thicket::bench::report_internal
