// Running figures.py (posix_spawn, no shell) on the figures' data, and the files a report replaces.
#include "report_figures.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <vector>

extern char** environ;

namespace thicket::bench::report_internal {
namespace {

std::string tail(const std::string& path, size_t max_chars) {
  std::ifstream file(path, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(file)), {});
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  if (text.size() > max_chars) text = "..." + text.substr(text.size() - max_chars);
  return text;
}

const char* const kFigureFiles[] = {
    "e1_success.png",      "e1_success.csv",     "e3_path_length.png", "e3_path_length.csv",
    "e4_success.png",      "e4_success.csv",     "e4_forest.png",      "e4_forest_world.csv",
    "e4_forest_paths.csv", "e5_subsampling.png", "e5_subsampling.csv", "figures.log"};

}  // namespace

std::string drawFigures(const std::string& python, const std::string& script,
                        const std::string& out_dir, const std::string& log) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  std::vector<std::string> args = {python, script, out_dir};
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, python.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  const std::string command = python + " " + script + " " + out_dir;
  if (spawned != 0) return "cannot run " + command + ": " + std::strerror(spawned);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return "cannot wait for " + command + ": " + std::strerror(errno);
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
    std::filesystem::remove(log);
    return "";
  }
  const std::string how = WIFEXITED(status)
                              ? "exited with status " + std::to_string(WEXITSTATUS(status))
                              : "was killed by signal " + std::to_string(WTERMSIG(status));
  return command + " " + how + " (output in " + log + "):\n" + tail(log, 2000);
}

bool reportFigureFile(const std::string& name) {
  if (std::find(std::begin(kFigureFiles), std::end(kFigureFiles), name) != std::end(kFigureFiles)) {
    return true;
  }
  static const std::regex e2(R"(e2_success(_.+)?\.(png|csv))");
  return std::regex_match(name, e2);
}

}  // namespace thicket::bench::report_internal
