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
#include <optional>

#include "png.h"
#include "sim_node.h"
#include "thicket/common/cli.h"
#include "thicket/common/loop.h"
#include "thicket/common/node_main.h"
#include "thicket/common/time.h"

namespace {

using thicket::sim::SimOptions;

constexpr const char* kProgram = "thicket-sim";

int fail(const std::string& message) {
  return thicket::failNode(kProgram, message);
}

// --scenario, --density, --seed and --worlds-dir, which every command that builds a world takes;
// given, they override run's --config.
struct WorldFlags {
  std::optional<std::string> scenario, worlds_dir;
  std::optional<double> density;
  std::optional<int64_t> seed;

  void add(CLI::App& command) {
    command.add_option("--scenario", scenario, "paper, eth, forest50 or a scenario .yaml")
        ->check(thicket::cli::nonEmpty());
    command.add_option("--density", density, "trees per m^2 of the obstacle region")
        ->check(thicket::cli::number(0));
    thicket::cli::addSeed(command, seed);
    command
        .add_option("--worlds-dir", worlds_dir,
                    "where scenario names are looked up (default: the source tree's config/worlds)")
        ->check(thicket::cli::nonEmpty());
  }

  void apply(SimOptions& options) const {
    options.scenario = scenario.value_or(options.scenario);
    options.density = density.value_or(options.density);
    options.seed = seed.value_or(options.seed);
    options.worlds_dir = worlds_dir.value_or(options.worlds_dir);
    if (options.worlds_dir.empty()) {
      options.worlds_dir = std::string(THICKET_SOURCE_DIR) + "/config/worlds";
    }
  }
};

thicket::Expected<thicket::sim::World> makeWorld(const SimOptions& options) {
  auto spec = thicket::sim::loadScenario(options.scenario, options.worlds_dir);
  if (!spec) return thicket::unexpected(spec.error());
  return thicket::sim::generateWorld(*spec, options.density, static_cast<uint64_t>(options.seed));
}

int worldCommand(const WorldFlags& flags) {
  SimOptions options;
  flags.apply(options);
  auto world = makeWorld(options);
  if (!world) return fail(world.error());
  std::printf("%s\n", thicket::sim::worldToJson(*world).c_str());
  return 0;
}

struct RenderArgs {
  std::vector<double> pose;
  std::string out, left, right, calib;
};

void addRenderFlags(CLI::App& render, RenderArgs& args) {
  using thicket::cli::nonEmpty;
  render.add_option("--pose", args.pose, "the body's pose x,y,z,yaw [m, m, m, rad]")
      ->delimiter(',')
      ->expected(4)
      ->check(thicket::cli::number())
      ->required();
  render.add_option("--out", args.out, "depth image (16-bit PNG, mm)")->check(nonEmpty());
  CLI::Option* left =
      render.add_option("--left", args.left, "left image of a rectified pair")->check(nonEmpty());
  CLI::Option* right = render.add_option("--right", args.right, "right image")->check(nonEmpty());
  CLI::Option* calib =
      render.add_option("--calib", args.calib, "the pair's calibration (YAML)")->check(nonEmpty());
  left->needs(right)->needs(calib);
  right->needs(left);
  calib->needs(left);
}

int renderCommand(const WorldFlags& flags, const RenderArgs& args) {
  if (args.out.empty() && args.left.empty()) {
    return fail("render needs --out and/or --left, --right and --calib");
  }
  SimOptions options;
  flags.apply(options);
  auto world = makeWorld(options);
  if (!world) return fail(world.error());
  const thicket::Pose body = thicket::Pose::fromYaw(
      Eigen::Vector3d(args.pose[0], args.pose[1], args.pose[2]), args.pose[3]);

  if (!args.out.empty()) {
    const thicket::sim::DepthRenderer renderer(*world, options.depth_camera);
    std::vector<float> depth;
    renderer.render(body, depth);
    const auto camera = renderer.camera();
    if (auto error = thicket::sim::writeDepthPng(args.out, camera.width, camera.height, depth);
        !error.empty()) {
      return fail(error);
    }
  }
  if (!args.left.empty()) {
    const thicket::sim::StereoRenderer renderer(*world, options.stereo_camera);
    std::vector<uint8_t> left, right;
    renderer.render(body, left, right);
    const auto camera = renderer.camera();
    for (const auto& [path, pixels] :
         {std::pair{&args.left, &left}, std::pair{&args.right, &right}}) {
      if (auto error = thicket::sim::writeGrayPng(*path, camera.width, camera.height, *pixels);
          !error.empty()) {
        return fail(error);
      }
    }
    std::ofstream(args.calib) << renderer.calibrationYaml(options.stereo_camera.calibration_id);
  }
  return 0;
}

int runCommand(const thicket::NodeArgs& args, const WorldFlags& flags, bool lockstep) {
  SimOptions options;
  if (!args.config_path.empty()) {
    try {
      options = thicket::loadParams<SimOptions>(args.config_path);
    } catch (const thicket::ParamError& e) {
      return fail(e.what());
    }
  }
  flags.apply(options);
  options.lockstep = options.lockstep || lockstep;
  auto world = makeWorld(options);
  if (!world) return fail(world.error());

  return thicket::runNode(kProgram, args.lcm_url, [&](lcm::LCM& lcm, thicket::Loop& loop) {
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
  CLI::App app(
      "thicket-sim: the simulated world, vehicle and sensors. `run` is the simulator process of\n"
      "the graph; `world` and `render` work offline.",
      kProgram);
  app.require_subcommand(1);
  WorldFlags world_flags, render_flags, run_flags;
  CLI::App* world = app.add_subcommand("world", "print a generated world as JSON");
  world_flags.add(*world);
  bool json = true;
  world->add_flag("--json", json, "JSON (the only format; accepted for scripts that say it)");
  CLI::App* render =
      app.add_subcommand("render", "render a depth image and/or a rectified stereo pair");
  render_flags.add(*render);
  RenderArgs render_args;
  addRenderFlags(*render, render_args);
  CLI::App* run = app.add_subcommand("run", "the simulator process (SIM_*, STEREO, CAMERA_DEPTH)");
  thicket::NodeArgs node_args;
  thicket::cli::addNodeFlags(*run, node_args);
  run_flags.add(*run);
  bool lockstep = false;
  run->add_flag("--lockstep", lockstep,
                "advance one frame per final planner status, not at --config's rate");
  app.add_subcommand("params", "print every option of run's --config with its default");
  if (auto exit_code = thicket::cli::parse(app, argc, argv)) return *exit_code;
  if (*world) return worldCommand(world_flags);
  if (*render) return renderCommand(render_flags, render_args);
  if (*run) return runCommand(node_args, run_flags, lockstep);
  std::printf("%s", thicket::describeParams<SimOptions>().c_str());
  return 0;
}
