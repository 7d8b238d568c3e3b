// thicket-sim: the simulator process and its offline commands.
//
//   thicket-sim world  --scenario S --density D --seed N --json
//   thicket-sim render --scenario S --density D --seed N --pose x,y,z,yaw --out depth.png
//                      [--left L.png --right R.png --calib C.yaml]   (a rectified stereo pair)
//   thicket-sim run    [--lcm-url URL] [--config sim.yaml] [--lockstep]
//                      [--scenario S] [--density D] [--seed N]
//   thicket-sim params                 (every option of run's --config, with its default)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

#include "png.h"
#include "sim_node.h"
#include "thicket/common/loop.h"
#include "thicket/common/node_main.h"
#include "thicket/common/time.h"

namespace {

using thicket::sim::SimOptions;

constexpr const char* kUsage =
    "usage: thicket-sim world  --scenario S --density D --seed N --json\n"
    "       thicket-sim render --scenario S --density D --seed N --pose x,y,z,yaw --out D.png\n"
    "                          [--left L.png --right R.png --calib C.yaml]\n"
    "       thicket-sim run    [--config sim.yaml] [--lockstep] [--scenario S] [--density D]\n"
    "                          [--seed N]\n"
    "       thicket-sim params (the options of --config with defaults and documentation)\n"
    "options of every command:\n"
    "  --worlds-dir DIR  where scenario names are looked up (default: config/worlds)\n";

int fail(const std::string& message) {
  std::fprintf(stderr, "thicket-sim: %s\n", message.c_str());
  return 2;
}

// "--key value" pairs and bare "--flag"s after the command.
struct Flags {
  std::map<std::string, std::string> values;
  std::vector<std::string> errors;

  Flags(const std::vector<std::string>& args, const std::vector<std::string>& booleans) {
    for (size_t i = 0; i < args.size(); ++i) {
      const std::string& arg = args[i];
      if (arg.rfind("--", 0) != 0) {
        errors.push_back("unexpected argument '" + arg + "'");
      } else if (std::find(booleans.begin(), booleans.end(), arg) != booleans.end()) {
        values[arg] = "true";
      } else if (i + 1 < args.size()) {
        values[arg] = args[++i];
      } else {
        errors.push_back(arg + " needs a value");
      }
    }
  }
  bool has(const std::string& key) const { return values.count(key) > 0; }
  const std::string& get(const std::string& key) const { return values.at(key); }
};

bool parseNumber(const std::string& text, double& value) {
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0' && std::isfinite(value);
}

std::string defaultWorldsDir() {
  return std::string(THICKET_SOURCE_DIR) + "/config/worlds";
}

// Applies --scenario/--density/--seed/--worlds-dir and refuses flags the command does not know.
std::string applyWorldFlags(const Flags& flags, const std::vector<std::string>& allowed,
                            SimOptions& options) {
  if (!flags.errors.empty()) return flags.errors.front();
  for (const auto& [key, value] : flags.values) {
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end() && key != "--scenario" &&
        key != "--density" && key != "--seed" && key != "--worlds-dir") {
      return "unknown option " + key;
    }
  }
  double number = 0;
  if (flags.has("--scenario")) options.scenario = flags.get("--scenario");
  if (flags.has("--worlds-dir")) options.worlds_dir = flags.get("--worlds-dir");
  if (flags.has("--density")) {
    if (!parseNumber(flags.get("--density"), number) || number < 0) {
      return "--density needs a non-negative number";
    }
    options.density = number;
  }
  if (flags.has("--seed")) {
    if (!parseNumber(flags.get("--seed"), number) || number < 0 || number != std::floor(number)) {
      return "--seed needs a non-negative integer";
    }
    options.seed = static_cast<int64_t>(number);
  }
  if (options.worlds_dir.empty()) options.worlds_dir = defaultWorldsDir();
  return {};
}

thicket::Expected<thicket::sim::World> makeWorld(const SimOptions& options) {
  auto spec = thicket::sim::loadScenario(options.scenario, options.worlds_dir);
  if (!spec) return thicket::unexpected(spec.error());
  return thicket::sim::generateWorld(*spec, options.density, static_cast<uint64_t>(options.seed));
}

int worldCommand(const std::vector<std::string>& args) {
  const Flags flags(args, {"--json"});
  SimOptions options;
  if (auto error = applyWorldFlags(flags, {"--json"}, options); !error.empty()) return fail(error);
  auto world = makeWorld(options);
  if (!world) return fail(world.error());
  std::printf("%s\n", thicket::sim::worldToJson(*world).c_str());
  return 0;
}

int renderCommand(const std::vector<std::string>& args) {
  const Flags flags(args, {});
  SimOptions options;
  if (auto error =
          applyWorldFlags(flags, {"--pose", "--out", "--left", "--right", "--calib"}, options);
      !error.empty()) {
    return fail(error);
  }
  if (!flags.has("--pose") || !(flags.has("--out") || flags.has("--left"))) {
    return fail("render needs --pose and --out (or --left/--right/--calib)");
  }
  std::vector<double> pose;
  std::stringstream pose_text(flags.get("--pose"));
  for (std::string item; std::getline(pose_text, item, ',');) {
    double value = 0;
    if (!parseNumber(item, value)) return fail("--pose needs x,y,z,yaw (numbers)");
    pose.push_back(value);
  }
  if (pose.size() != 4) return fail("--pose needs exactly x,y,z,yaw");
  auto world = makeWorld(options);
  if (!world) return fail(world.error());
  const thicket::Pose body =
      thicket::Pose::fromYaw(Eigen::Vector3d(pose[0], pose[1], pose[2]), pose[3]);

  if (flags.has("--out")) {
    const thicket::sim::DepthRenderer renderer(*world, options.depth_camera);
    std::vector<float> depth;
    renderer.render(body, depth);
    const auto camera = renderer.camera();
    if (auto error =
            thicket::sim::writeDepthPng(flags.get("--out"), camera.width, camera.height, depth);
        !error.empty()) {
      return fail(error);
    }
  }
  if (flags.has("--left") || flags.has("--right") || flags.has("--calib")) {
    if (!flags.has("--left") || !flags.has("--right") || !flags.has("--calib")) {
      return fail("a stereo pair needs --left, --right and --calib");
    }
    const thicket::sim::StereoRenderer renderer(*world, options.stereo_camera);
    std::vector<uint8_t> left, right;
    renderer.render(body, left, right);
    const auto camera = renderer.camera();
    for (const auto& [flag, pixels] : {std::pair{"--left", &left}, std::pair{"--right", &right}}) {
      if (auto error =
              thicket::sim::writeGrayPng(flags.get(flag), camera.width, camera.height, *pixels);
          !error.empty()) {
        return fail(error);
      }
    }
    std::ofstream(flags.get("--calib"))
        << renderer.calibrationYaml(options.stereo_camera.calibration_id);
  }
  return 0;
}

// argv[0] is "run".
int runCommand(int argc, char** argv) {
  auto args = thicket::parseNodeArgs(argc, argv);
  if (!args) return fail(args.error());
  if (args->help) {
    std::printf("%s%s", kUsage, thicket::commonNodeFlagsHelp().c_str());
    return 0;
  }
  SimOptions options;
  if (!args->config_path.empty()) {
    try {
      options = thicket::loadParams<SimOptions>(args->config_path);
    } catch (const thicket::ParamError& e) {
      return fail(e.what());
    }
  }
  const Flags flags(args->options, {"--lockstep"});
  if (auto error = applyWorldFlags(flags, {"--lockstep"}, options); !error.empty()) {
    return fail(error);
  }
  if (flags.has("--lockstep")) options.lockstep = true;
  auto world = makeWorld(options);
  if (!world) return fail(world.error());

  return thicket::runNode("thicket-sim", args->lcm_url, [&](lcm::LCM& lcm, thicket::Loop& loop) {
    thicket::sim::SimNode node(lcm, options, std::move(*world));
    // Liveness only (wall time decides nothing a trial records): a frame the planner does not
    // close within lockstep_step_on is stepped past, and a planner that closes none for
    // lockstep_timeout ends the mission instead of hanging it.
    int64_t waited_since = thicket::steadyClockMicros();
    int64_t answered_at = waited_since;
    std::optional<int64_t> waited_for;
    int answered = 0;
    if (options.lockstep) {
      loop.addTimer(100'000, [&] {
        const int64_t now = thicket::steadyClockMicros();
        if (const int n = node.vehicle().cycle() - node.stepsOn(); n != answered) {
          answered = n;
          answered_at = now;
        }
        if (node.waitingFor() != waited_for) {
          waited_for = node.waitingFor();
          waited_since = now;
        }
        const double waited_s = static_cast<double>(now - waited_since) * 1e-6;
        if (static_cast<double>(now - answered_at) * 1e-6 > options.lockstep_timeout) {
          node.abort("no final planner status for " + std::to_string(options.lockstep_timeout) +
                     " s");
        } else if (waited_for && options.lockstep_step_on > 0 &&
                   waited_s > options.lockstep_step_on) {
          node.stepOn(waited_s);
        }
        if (node.finished()) loop.stop();
      });
    } else {
      loop.addTimer(static_cast<int64_t>(1e6 / options.rate), [&] {
        node.advance();
        if (node.finished()) loop.stop();
      });
    }
    node.start();
    loop.run();
    const auto& vehicle = node.vehicle();
    std::printf("thicket-sim: %s after %d cycles, path %.2f m, min clearance %.3f m\n",
                node.finished() ? node.endReason().c_str() : "stopped", vehicle.cycle(),
                vehicle.pathLength(), vehicle.minClearance());
    if (options.dynamic_obstacle.enabled) {
      if (const auto& obstacle = node.dynamicObstacle()) {
        std::printf("thicket-sim: the dynamic obstacle appeared at %.2f s, min clearance %.3f m\n",
                    thicket::toSeconds(obstacle->utime - vehicle.path().front().utime),
                    obstacle->min_clearance);
      } else {
        std::printf("thicket-sim: the dynamic obstacle never appeared\n");
      }
    }
    return vehicle.outcome() == thicket::sim::Outcome::kGoalReached ? 0 : 1;
  });
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "%s", kUsage);
    return 2;
  }
  const std::string command = argv[1];
  const std::vector<std::string> rest(argv + 2, argv + argc);
  if (command == "world") return worldCommand(rest);
  if (command == "render") return renderCommand(rest);
  if (command == "run") return runCommand(argc - 1, argv + 1);
  if (command == "params") {
    std::printf("%s", thicket::describeParams<SimOptions>().c_str());
    return 0;
  }
  if (command == "-h" || command == "--help") {
    std::printf("%s", kUsage);
    return 0;
  }
  return fail("unknown command '" + command + "'\n" + kUsage);
}
