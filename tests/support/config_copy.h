// A copy of the simulated graph's option files (config/sim) with one option of the planner's
// trajectory optimization changed, for tests of --config.
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace thicket::testing {

/// Copies config/sim into dir (created) and adds loco_option ("key: value") to the planner's
/// loco block of its local_planner.yaml; returns dir.
inline std::string configCopy(const std::string& dir, const std::string& loco_option) {
  const std::string source = std::string(THICKET_SOURCE_DIR) + "/config/sim";
  std::filesystem::create_directories(dir);
  for (const auto& entry : std::filesystem::directory_iterator(source))
    std::filesystem::copy_file(entry.path(), dir + "/" + entry.path().filename().string());
  std::ifstream shipped(source + "/local_planner.yaml");
  std::stringstream text;
  text << shipped.rdbuf();
  std::string yaml = text.str();
  // Into the shipped planner.loco block, or a new one.
  const std::string block = "\nplanner:\n", loco = "\nplanner:\n  loco:\n";
  const size_t planner = yaml.find(block);
  EXPECT_NE(planner, std::string::npos) << "config/sim/local_planner.yaml has no planner block";
  if (const size_t at = yaml.find(loco); at != std::string::npos) {
    yaml.insert(at + loco.size(), "    " + loco_option + "\n");
  } else if (planner != std::string::npos) {
    yaml.insert(planner + block.size(), "  loco:\n    " + loco_option + "\n");
  }
  std::ofstream(dir + "/local_planner.yaml") << yaml;
  return dir;
}

}  // namespace thicket::testing
