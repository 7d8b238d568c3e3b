#include "subsampling.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <numbers>
#include <random>
#include <set>
#include <stdexcept>

#include <thicket/map_update_t.hpp>

#include "flags.h"
#include "parallel.h"
#include "thicket/common/map_update.h"
#include "thicket/common/node.h"
#include "thicket/common/statistics.h"
#include "thicket/explorer/gain.h"
#include "trials.h"

namespace thicket::bench {
namespace {

// Fractions below this would need strides beyond any frustum (and near int overflow).
constexpr double kMinFraction = 1e-6;

std::string defaultWorldsDir() {
  return std::string(THICKET_SOURCE_DIR) + "/config/worlds";
}

// ---- flags ----

// --density and --fractions take any finite number: their ranges are checked with the other
// options (checkSubsamplingOptions, checkFractions), also for options built in code.
void addSubsamplingFlags(CLI::App& app, SubsamplingOptions& o) {
  using cli::nonEmpty;
  const int int_max = std::numeric_limits<int>::max();
  app.footer(
      "Prints the table and writes DIR/e5_subsampling.csv:\n"
      "fraction,stride,poses,mean_abs_error,p95_abs_error,max_abs_error,median_us,speedup");
  app.add_option("--maps", o.maps, "flights whose maps are used")
      ->check(cli::integer(1, int_max))
      ->capture_default_str();
  app.add_option("--poses", o.poses, "camera poses, spread evenly over the maps")
      ->check(cli::integer(1, int_max))
      ->capture_default_str();
  app.add_option("--fractions", o.fractions,
                 "comma-separated fractions in (0, 1], each checking every round(1/fraction)-th "
                 "point")
      ->delimiter(',')
      ->check(cli::number())
      ->capture_default_str();
  app.add_option("--scenario", o.scenario, "a scenario name in the worlds dir or a .yaml path")
      ->check(nonEmpty())
      ->capture_default_str();
  app.add_option("--density", o.density, "cylinders per m^2 of the obstacle region")
      ->check(cli::number())
      ->capture_default_str();
  app.add_option("--seed-base", o.seed_base, "the world seed of map 0, and the seed of the poses")
      ->check(cli::integer(0))
      ->capture_default_str();
  app.add_option("--replans", o.replans, "replan limit of each flight")
      ->check(cli::integer(1, int_max))
      ->capture_default_str();
  app.add_option("--jobs", o.jobs,
                 "flights run on J threads; the times are measured on one thread after the "
                 "flights")
      ->check(cli::integer(1, 1024))
      ->capture_default_str();
  app.add_option("--worlds-dir", o.worlds_dir,
                 "where scenario names are looked up (default: the source tree's config/worlds)")
      ->check(nonEmpty());
  app.add_option("--out", o.out_dir, "the output folder")->required()->check(nonEmpty());
}

// Why `fractions` cannot be measured, or nothing.
std::optional<std::string> checkFractions(const std::vector<double>& fractions) {
  if (fractions.empty()) return "no fractions given";
  std::map<int, double> by_stride;
  for (double f : fractions) {
    if (!(std::isfinite(f) && f >= kMinFraction && f <= 1.0)) {
      return "fraction " + formatNumber("%g", f) + " is not in [" +
             formatNumber("%g", kMinFraction) + ", 1]";
    }
    const auto [it, added] = by_stride.emplace(strideOfFraction(f), f);
    if (!added) {
      return "fractions " + formatNumber("%g", it->second) + " and " + formatNumber("%g", f) +
             " both give stride " + std::to_string(it->first);
    }
  }
  return std::nullopt;
}

// ---- the flown maps ----

// The benchmark's observer of a trial: applies the mapper's MAP_TSDF updates to a mirror that
// outlives the trial. It never publishes (no MAP_REQUEST of its own), so the trial flies exactly
// as it would without it; the explorer's start-up request brings the full snapshot that the
// mirror needs after the first delta, and any later snapshot the explorer asks for heals a gap
// here too.
class TsdfRecorder : public Node {
 public:
  TsdfRecorder(lcm::LCM& lcm, std::shared_ptr<MapMirror<TsdfVoxel>> mirror)
      : Node("e5_tsdf_recorder", lcm), mirror_(std::move(mirror)) {
    // A full snapshot arrives as many parts at once.
    subscribe<map_update_t>(
        "MAP_TSDF",
        [this](const map_update_t& msg, const MessageInfo&) {
          const auto result = mirror_->apply(msg);
          if (result.outcome == MapMirror<TsdfVoxel>::Outcome::kRefused) {
            reportBadMessage("MAP_TSDF", result.reason);
          }
        },
        1000);
  }

 private:
  std::shared_ptr<MapMirror<TsdfVoxel>> mirror_;
};

RunOptions flightOptions(const SubsamplingOptions& options) {
  RunOptions run;
  run.scenario = options.scenario;
  run.density = options.density;
  run.method = "local_exploration";
  run.trials = options.maps;
  run.seed_base = options.seed_base;
  run.replans = options.replans;
  run.worlds_dir = options.worlds_dir.empty() ? defaultWorldsDir() : options.worlds_dir;
  return run;
}

// "map 1/4 seed 1: goal reached, 87.5 m, 117 replans, 812 TSDF blocks, 4.1 s"
std::string progressLine(int map, int maps, const Expected<FlownMap>& flown, double seconds) {
  std::string line = "map " + std::to_string(map) + "/" + std::to_string(maps) + ": ";
  if (!flown) return line + flown.error() + "\n";
  char numbers[160];
  std::snprintf(numbers, sizeof(numbers),
                "seed %llu: %s, %zu path samples, %zu TSDF blocks, %.1f s",
                static_cast<unsigned long long>(flown->seed), flown->end_reason.c_str(),
                flown->path.size(), flown->tsdf->numBlocks(), seconds);
  return line + numbers + "\n";
}

// Every map, flown on options.jobs threads, in map order.
std::vector<Expected<FlownMap>> flyAll(const SubsamplingOptions& options) {
  std::vector<std::optional<Expected<FlownMap>>> slots(static_cast<size_t>(options.maps));
  std::mutex progress;
  parallelFor(slots.size(), options.jobs, [&](size_t slot) {
    const int map = static_cast<int>(slot);
    const auto started = std::chrono::steady_clock::now();
    Expected<FlownMap> flown = flyMap(options, map);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    const std::lock_guard lock(progress);
    std::fputs(progressLine(map, options.maps, flown, seconds).c_str(), stderr);
    slots[slot].emplace(std::move(flown));
  });
  std::vector<Expected<FlownMap>> maps;
  for (auto& slot : slots) maps.push_back(std::move(*slot));
  return maps;
}

// ---- output ----

std::string csvText(const std::vector<SubsamplingRow>& rows) {
  std::string text =
      "fraction,stride,poses,mean_abs_error,p95_abs_error,max_abs_error,median_us,speedup\n";
  char line[256];
  for (const SubsamplingRow& r : rows) {
    std::snprintf(line, sizeof(line), "%g,%d,%d,%.6f,%.6f,%.6f,%.3f,%.3f\n", r.fraction, r.stride,
                  r.poses, r.mean_abs_error, r.p95_abs_error, r.max_abs_error, r.median_us,
                  r.speedup);
    text += line;
  }
  return text;
}

std::string csvPath(const SubsamplingOptions& options) {
  return options.out_dir + "/e5_subsampling.csv";
}

void printTable(const SubsamplingOptions& options, const std::vector<SubsamplingRow>& rows,
                double seconds) {
  std::printf("E5 subsampling: %s, density %g, %d maps (seeds %lld..%lld, %d replans), %d poses\n",
              options.scenario.c_str(), options.density, options.maps,
              static_cast<long long>(options.seed_base),
              static_cast<long long>(options.seed_base + options.maps - 1), options.replans,
              options.poses);
  std::printf("%9s %7s %15s %14s %14s %10s %8s\n", "fraction", "stride", "mean |error|",
              "p95 |error|", "max |error|", "median us", "speedup");
  for (const SubsamplingRow& r : rows) {
    std::printf("%9g %7d %15.5f %14.5f %14.5f %10.2f %8.2f\n", r.fraction, r.stride,
                r.mean_abs_error, r.p95_abs_error, r.max_abs_error, r.median_us, r.speedup);
  }
  std::printf("wrote %s in %.1f s\n", csvPath(options).c_str(), seconds);
}

int failUsage(const std::string& message) {
  return usageError("subsampling", message);
}

}  // namespace

int strideOfFraction(double fraction) {
  return static_cast<int>(std::lround(1.0 / fraction));
}

std::optional<std::string> checkSubsamplingOptions(const SubsamplingOptions& options) {
  if (options.maps < 1) return "the number of maps must be at least 1";
  if (options.poses < 1) return "the number of poses must be at least 1";
  if (auto error = checkFractions(options.fractions)) return error;
  if (options.scenario.empty()) return "no scenario given";
  if (!(std::isfinite(options.density) && options.density >= 0)) {
    return "the density must be a non-negative number, not " + formatNumber("%g", options.density);
  }
  if (options.seed_base < 0) return "the seed base must be >= 0";
  if (options.replans < 1) return "the replan limit must be at least 1";
  if (options.jobs < 1) return "the number of jobs must be at least 1";
  if (options.out_dir.empty()) return "no output folder given (--out DIR)";
  return std::nullopt;
}

Expected<SubsamplingOptions> parseSubsamplingOptions(const std::vector<std::string>& args) {
  auto options = parseCommand<SubsamplingOptions>(
      "subsampling",
      "thicket-bench subsampling: experiment E5, the exploration gain's error and speed-up when\n"
      "only a fraction of the frustum points is checked. Flies N maps with the real graph\n"
      "(local_exploration; map i on the world of seed B+i), draws camera poses near the flown\n"
      "paths (up to 1 m sideways, 0.5 m up or down, any heading) and compares every fraction's\n"
      "gain with the exact one (fraction 1).",
      args, addSubsamplingFlags);
  if (!options || !options->help.empty()) return options;
  if (auto error = checkSubsamplingOptions(*options)) return unexpected(*error);
  return options;
}

Expected<FlownMap> flyMap(const SubsamplingOptions& options, int map) {
  const RunOptions run = flightOptions(options);
  const uint64_t seed = static_cast<uint64_t>(options.seed_base) + static_cast<uint64_t>(map);
  const std::string which = "map " + std::to_string(map) + " (seed " + std::to_string(seed) + ")";
  try {
    auto mirror = std::make_shared<MapMirror<TsdfVoxel>>();
    const sim::World world = trialWorld(run, map);
    const TrialResult trial = runTrial(run, world, map, [mirror](lcm::LCM& lcm) {
      return std::make_unique<TsdfRecorder>(lcm, mirror);
    });
    if (mirror->layer() == nullptr || mirror->needsSnapshot()) {
      return unexpected(which + ": the mirror of the mapper's TSDF is incomplete (" +
                        mirror->snapshotReason() + ")");
    }
    if (trial.path.empty()) return unexpected(which + ": the flight has no path");
    FlownMap flown;
    flown.seed = seed;
    flown.end_reason = trial.end_reason;
    // The layer lives as long as the mirror that holds it.
    flown.tsdf = std::shared_ptr<const TsdfLayer>(mirror, mirror->layer());
    flown.path = trial.path;
    flown.bounds_min = world.bounds_min;
    flown.bounds_max = world.bounds_max;
    return flown;
  } catch (const std::exception& e) {
    return unexpected(which + ": " + e.what());
  }
}

std::vector<GainPose> drawGainPoses(const std::vector<FlownMap>& maps, int count, uint64_t seed) {
  for (const FlownMap& map : maps) {
    if (map.path.empty()) throw std::invalid_argument("drawGainPoses: a map has no path");
  }
  if (maps.empty() && count > 0) throw std::invalid_argument("drawGainPoses: no maps");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lateral(-1.0, 1.0), vertical(-0.5, 0.5),
      yaw(-std::numbers::pi, std::numbers::pi);
  std::vector<GainPose> poses;
  for (int n = 0; n < count; ++n) {
    const int m = n % static_cast<int>(maps.size());
    const FlownMap& map = maps[static_cast<size_t>(m)];
    std::uniform_int_distribution<size_t> sample(0, map.path.size() - 1);
    // Redrawn until inside: the path is inside the bounds, so some draw always is.
    while (true) {
      const sim::PathSample& s = map.path[sample(rng)];
      const Eigen::Vector3d side(-std::sin(s.yaw), std::cos(s.yaw), 0.0);
      const Eigen::Vector3d p =
          s.position + lateral(rng) * side + vertical(rng) * Eigen::Vector3d::UnitZ();
      const double heading = yaw(rng);
      if ((p.array() >= map.bounds_min.array()).all() &&
          (p.array() <= map.bounds_max.array()).all()) {
        poses.push_back({m, explorer::ExplorationGain::cameraAt(p, heading)});
        break;
      }
    }
  }
  return poses;
}

Expected<std::vector<SubsamplingRow>> measureSubsampling(const std::vector<const TsdfLayer*>& maps,
                                                         const std::vector<GainPose>& poses,
                                                         const std::vector<double>& fractions) {
  if (auto error = checkFractions(fractions)) return unexpected(*error);
  if (poses.empty()) return unexpected("no poses to evaluate");
  if (maps.empty() || std::count(maps.begin(), maps.end(), nullptr) > 0) {
    return unexpected("a map is missing");
  }
  // Stride 1 first: the exact gain and the reference time.
  std::set<int> distinct = {1};
  for (double f : fractions) distinct.insert(strideOfFraction(f));
  const std::vector<int> strides(distinct.begin(), distinct.end());
  const size_t k_strides = strides.size();

  std::vector<std::vector<double>> errors(k_strides), micros(k_strides);
  std::vector<double> values(k_strides);
  try {
    const explorer::ExplorationGain gain(explorer::GainOptions{}, maps.front()->voxelSize());
    for (size_t n = 0; n < poses.size(); ++n) {
      const GainPose& pose = poses[n];
      if (pose.map < 0 || static_cast<size_t>(pose.map) >= maps.size()) {
        return unexpected("pose " + std::to_string(n) + " is on map " + std::to_string(pose.map) +
                          " of " + std::to_string(maps.size()));
      }
      const TsdfLayer& tsdf = *maps[static_cast<size_t>(pose.map)];
      // Interleaved, starting at a different stride for each pose: load and the caches the
      // previous evaluation warmed affect every stride alike.
      for (size_t i = 0; i < k_strides; ++i) {
        const size_t s = (n + i) % k_strides;
        const auto started = std::chrono::steady_clock::now();
        const explorer::Gain g = gain.unknownFraction(tsdf, pose.world_T_camera, strides[s]);
        const auto stopped = std::chrono::steady_clock::now();
        micros[s].push_back(std::chrono::duration<double, std::micro>(stopped - started).count());
        values[s] = g.unknown_fraction;
      }
      for (size_t s = 0; s < k_strides; ++s) errors[s].push_back(std::abs(values[s] - values[0]));
    }
  } catch (const std::exception& e) {
    return unexpected(std::string("cannot evaluate the gain: ") + e.what());
  }

  const double exact_us = median(micros[0]);
  std::vector<SubsamplingRow> rows;
  for (size_t s = 0; s < k_strides; ++s) {
    const bool listed = std::any_of(fractions.begin(), fractions.end(),
                                    [&](double f) { return strideOfFraction(f) == strides[s]; });
    if (!listed) continue;
    SubsamplingRow row;
    row.stride = strides[s];
    row.fraction = 1.0 / strides[s];
    row.poses = static_cast<int>(poses.size());
    double sum = 0;
    for (double e : errors[s]) sum += e;
    row.mean_abs_error = sum / static_cast<double>(errors[s].size());
    row.p95_abs_error = quantile(errors[s], 0.95);
    row.max_abs_error = *std::max_element(errors[s].begin(), errors[s].end());
    row.median_us = median(micros[s]);
    row.speedup = row.median_us > 0 ? exact_us / row.median_us : 0;
    rows.push_back(row);
  }
  // By fraction, smallest first.
  std::reverse(rows.begin(), rows.end());
  return rows;
}

Expected<std::vector<SubsamplingRow>> runSubsampling(const SubsamplingOptions& options) {
  if (auto error = checkSubsamplingOptions(options)) return unexpected(*error);
  const std::string worlds_dir =
      options.worlds_dir.empty() ? defaultWorldsDir() : options.worlds_dir;
  if (auto spec = sim::loadScenario(options.scenario, worlds_dir); !spec) {
    return unexpected(spec.error());
  }
  std::error_code error;
  std::filesystem::create_directories(options.out_dir, error);
  if (error) return unexpected("cannot create " + options.out_dir + ": " + error.message());

  std::vector<FlownMap> maps;
  for (Expected<FlownMap>& flown : flyAll(options)) {
    if (!flown) return unexpected(flown.error());
    maps.push_back(std::move(*flown));
  }
  const std::vector<GainPose> poses =
      drawGainPoses(maps, options.poses, static_cast<uint64_t>(options.seed_base));
  std::vector<const TsdfLayer*> layers;
  for (const FlownMap& map : maps) layers.push_back(map.tsdf.get());
  auto rows = measureSubsampling(layers, poses, options.fractions);
  if (!rows) return rows;

  std::ofstream file(csvPath(options), std::ios::binary);
  file << csvText(*rows);
  file.close();
  if (!file) return unexpected("cannot write " + csvPath(options));
  return rows;
}

int subsamplingCommand(const std::vector<std::string>& args) {
  auto options = parseSubsamplingOptions(args);
  if (!options) return failUsage(options.error());
  if (!options->help.empty()) {
    std::fputs(options->help.c_str(), stdout);
    return 0;
  }
  const std::string worlds_dir =
      options->worlds_dir.empty() ? defaultWorldsDir() : options->worlds_dir;
  if (auto spec = sim::loadScenario(options->scenario, worlds_dir); !spec) {
    return failUsage(spec.error());
  }
  const auto started = std::chrono::steady_clock::now();
  const auto rows = runSubsampling(*options);
  if (!rows) {
    std::fprintf(stderr, "thicket-bench subsampling: %s\n", rows.error().c_str());
    return 1;
  }
  printTable(*options, *rows,
             std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count());
  return 0;
}

}  // namespace thicket::bench
