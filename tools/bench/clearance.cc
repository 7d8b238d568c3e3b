#include "clearance.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <random>
#include <stdexcept>

#include "csv.h"
#include "flags.h"
#include "parallel.h"
#include "thicket/common/esdf_query.h"
#include "thicket/common/number_text.h"
#include "thicket/common/random.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/render.h"
#include "trials.h"

namespace thicket::bench {

namespace {

// A variant that sets the two mapping changes the measurement compares and keeps new surfaces
// averaged in, as before either existed.
std::function<void(mapper::MapperOptions&)> mappingChanges(bool normal_distances,
                                                           bool crossing_sites) {
  return [=](mapper::MapperOptions& o) {
    o.tsdf.normal_distances = normal_distances;
    o.tsdf.new_surfaces_replace = false;
    o.esdf.crossing_sites = crossing_sites;
  };
}

}  // namespace

const std::vector<MappingVariant>& mappingVariants() {
  static const std::vector<MappingVariant> variants = {
      {"line_of_sight", "TSDF distances along the line of sight; sites in the surface band only",
       mappingChanges(false, false)},
      {"normal", "TSDF distances along the surface normal estimated from the depth image",
       mappingChanges(true, false)},
      {"crossing", "line of sight, and sites at the TSDF's zero crossings",
       mappingChanges(false, true)},
      {"normal_crossing", "normal distances and sites at the zero crossings",
       mappingChanges(true, true)},
      {"defaults", "normal distances, crossing sites, and new surfaces replacing free history",
       [](mapper::MapperOptions&) {}},
  };
  return variants;
}

namespace {

void addClearanceFlags(CLI::App& app, ClearanceOptions& o) {
  using cli::nonEmpty;
  const int int_max = std::numeric_limits<int>::max();
  std::string variants;
  for (const MappingVariant& v : mappingVariants()) {
    variants += "  " + v.name + ": " + v.description + "\n";
  }
  app.footer("Mapping variants (--variants):\n" + variants);
  app.add_option("--flights", o.flights, "scenario:density pairs")
      ->delimiter(',')
      ->check(nonEmpty())
      ->capture_default_str();
  app.add_option("--worlds", o.worlds, "worlds per flight, seeds B..B+N-1")
      ->check(cli::integer(1, int_max))
      ->capture_default_str();
  app.add_option("--seed-base", o.seed_base, "B")->check(cli::integer(0))->capture_default_str();
  app.add_option("--replans", o.replans, "replan limit of each flight")
      ->check(cli::integer(1, int_max))
      ->capture_default_str();
  app.add_option("--voxel-sizes", o.voxel_sizes, "[m], each in [0.02, 1]")
      ->delimiter(',')
      ->check(cli::number(0.02, 1.0))
      ->capture_default_str();
  app.add_option("--noises", o.noises, "depth noise sigma at 1 m, sigma = this * z^2")
      ->delimiter(',')
      ->check(cli::number(0))
      ->capture_default_str();
  std::vector<std::string> names;
  for (const MappingVariant& v : mappingVariants()) names.push_back(v.name);
  app.add_option("--variants", o.variants, "mapping variants (default all)")
      ->delimiter(',')
      ->check(CLI::IsMember(names));
  app.add_option("--horizon", o.horizon, "voxels and points within R of the vehicle [m]")
      ->check(cli::number(std::nextafter(0.0, 1.0)))
      ->capture_default_str();
  app.add_option("--robot-radius", o.robot_radius, "[m]")
      ->check(cli::number(0))
      ->capture_default_str();
  app.add_option("--band", o.band, "voxels and points up to R + B from an obstacle [m]")
      ->check(cli::number(0))
      ->capture_default_str();
  app.add_option("--points", o.points_per_frame, "random points per frame")
      ->check(cli::integer(1, int_max))
      ->capture_default_str();
  app.add_option("--jobs", o.jobs, "threads")->check(cli::integer(1, 1024))->capture_default_str();
  app.add_option("--worlds-dir", o.worlds_dir, "where scenario names are looked up")
      ->check(nonEmpty());
  app.add_option("--out", o.out_dir, "the output folder")->required()->check(nonEmpty());
}

struct FlightSpec {
  std::string scenario;
  double density = 0;
};

Expected<FlightSpec> parseFlight(const std::string& text) {
  const size_t colon = text.find(':');
  const std::optional<double> density =
      colon == std::string::npos ? std::nullopt : finiteNumber(text.substr(colon + 1));
  if (!density || *density < 0 || colon == 0) {
    return unexpected("flight '" + text + "' is not scenario:density");
  }
  return FlightSpec{text.substr(0, colon), *density};
}

// ---- flights ----

// One world flown once: the world and the body pose of every frame the simulator rendered.
struct Flight {
  FlightSpec spec;
  sim::World world;
  struct Frame {
    int64_t utime;
    Pose body;
  };
  std::vector<Frame> frames;
  std::vector<sim::PathSample> path;  // every executed sample, for the pose stream
};

// The simulator renders frame k at the vehicle's state after k replan periods.
constexpr int64_t kReplanPeriodUs = 1'000'000;

Flight fly(const ClearanceOptions& options, const FlightSpec& spec, int world_index) {
  RunOptions run;
  run.scenario = spec.scenario;
  run.density = spec.density;
  run.method = "local_exploration";
  run.trials = 1;
  run.seed_base = options.seed_base;
  run.replans = options.replans;
  run.worlds_dir = options.worlds_dir.empty() ? std::string(THICKET_SOURCE_DIR) + "/config/worlds"
                                              : options.worlds_dir;
  Flight flight;
  flight.spec = spec;
  flight.world = trialWorld(run, world_index);
  const TrialResult trial = runTrial(run, flight.world, world_index);
  if (trial.path.empty()) throw std::runtime_error("a flight of " + spec.scenario + " has no path");
  flight.path = trial.path;
  const int64_t start = trial.path.front().utime;
  for (const sim::PathSample& s : trial.path) {
    if ((s.utime - start) % kReplanPeriodUs == 0) {
      flight.frames.push_back({s.utime, Pose::fromYaw(s.position, s.yaw)});
    }
  }
  return flight;
}

// ---- error statistics ----

// A histogram of errors in [-kRange, kRange] m (clamped), exact count, sum and maximum.
class ErrorHistogram {
 public:
  static constexpr double kRange = 2.0;
  static constexpr double kBin = 0.0005;

  ErrorHistogram() : bins_(static_cast<size_t>(2 * kRange / kBin) + 1, 0) {}

  void add(double error, const std::function<std::string()>& where) {
    ++count_;
    sum_ += error;
    const double clamped = std::clamp(error, -kRange, kRange);
    ++bins_[static_cast<size_t>(std::floor((clamped + kRange) / kBin))];
    if (count_ == 1 || error > max_) {
      max_ = error;
      worst_ = where();
    }
  }

  void merge(const ErrorHistogram& other) {
    if (other.count_ == 0) return;
    if (count_ == 0 || other.max_ > max_) {
      max_ = other.max_;
      worst_ = other.worst_;
    }
    count_ += other.count_;
    sum_ += other.sum_;
    for (size_t i = 0; i < bins_.size(); ++i) bins_[i] += other.bins_[i];
  }

  ErrorSummary summary() const {
    ErrorSummary s;
    s.count = count_;
    if (count_ == 0) return s;
    s.mean = sum_ / static_cast<double>(count_);
    s.p99 = quantile(0.99);
    s.p999 = quantile(0.999);
    s.max = max_;
    s.worst = worst_;
    return s;
  }

 private:
  // The upper edge of the bin holding the q-quantile (never below the truth), capped by the max.
  double quantile(double q) const {
    const auto rank = static_cast<int64_t>(std::ceil(q * static_cast<double>(count_)));
    int64_t seen = 0;
    for (size_t i = 0; i < bins_.size(); ++i) {
      seen += bins_[i];
      if (seen >= rank) return std::min(max_, -kRange + static_cast<double>(i + 1) * kBin);
    }
    return max_;
  }

  std::vector<int64_t> bins_;
  int64_t count_ = 0;
  double sum_ = 0;
  double max_ = 0;
  std::string worst_;
};

// The band of true clearance above the robot radius where passages are decided: what the ESDF
// reads below the truth there narrows every gap [m].
constexpr double kPassage = 0.3;

struct Config {
  double voxel_size;
  double noise;
  const MappingVariant* variant;
};

struct Measured {
  ErrorHistogram voxels;
  ErrorHistogram points;
  ErrorHistogram margin;
  ErrorHistogram under;
  int frames = 0;
};

std::string place(const Flight& flight, size_t frame, const Eigen::Vector3d& p, double esdf,
                  double truth) {
  char text[200];
  std::snprintf(
      text, sizeof(text), "%s d%g s%llu frame %zu (%.2f, %.2f, %.2f): esdf %.3f true %.3f",
      flight.spec.scenario.c_str(), flight.spec.density,
      static_cast<unsigned long long>(flight.world.seed), frame, p.x(), p.y(), p.z(), esdf, truth);
  return text;
}

// Maps one flight under one configuration and measures after every frame.
Measured measure(const ClearanceOptions& options, const Flight& flight, const Config& config) {
  mapper::MapperOptions mapper_options;
  mapper_options.voxel_size = config.voxel_size;
  config.variant->apply(mapper_options);
  mapper::Mapper mapper(mapper_options);
  sim::DepthCameraOptions camera;
  camera.noise_stddev_at_1m = config.noise;
  const sim::DepthRenderer renderer(flight.world, camera);
  const sim::GroundTruth truth(flight.world);

  Measured measured;
  size_t next_pose = 0;
  std::vector<mapper::MapRevisionUpdate> updates;
  for (size_t k = 0; k < flight.frames.size(); ++k) {
    const Flight::Frame& frame = flight.frames[k];
    // The pose stream up to the frame, as the VIO bridge would deliver it.
    for (; next_pose < flight.path.size() && flight.path[next_pose].utime <= frame.utime;
         ++next_pose) {
      const sim::PathSample& s = flight.path[next_pose];
      mapper.addPose(s.utime, Pose::fromYaw(s.position, s.yaw));
    }
    mapper.addFrame(renderer.renderImage(frame.body, frame.utime, k));
    updates.clear();
    mapper.integrateReady(updates);
    if (updates.empty()) continue;
    ++measured.frames;

    const TsdfLayer& tsdf = mapper.tsdf();
    const EsdfLayer& esdf = mapper.esdf();
    const Eigen::Vector3d& centre = frame.body.position;
    const double r2 = options.horizon * options.horizon;
    const double near = options.robot_radius + options.band;
    // Where the planner may put the centre: the world's bounds shrunk by the robot radius (its
    // flight volume); elsewhere no sample is ever accepted.
    const auto inVolume = [&](const Eigen::Vector3d& q) {
      return (q.array() >= flight.world.bounds_min.array() + options.robot_radius).all() &&
             (q.array() <= flight.world.bounds_max.array() - options.robot_radius).all();
    };
    const VoxelIndex lo = esdf.voxelIndex((centre.array() - options.horizon).matrix());
    const VoxelIndex hi = esdf.voxelIndex((centre.array() + options.horizon).matrix());
    for (int z = lo.z(); z <= hi.z(); ++z) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int x = lo.x(); x <= hi.x(); ++x) {
          const VoxelIndex v(x, y, z);
          const Eigen::Vector3d c = esdf.voxelCenter(v);
          if ((c - centre).squaredNorm() > r2 || !inVolume(c)) continue;
          const EsdfVoxel* e = esdf.voxel(v);
          const TsdfVoxel* t = tsdf.voxel(v);
          if (e == nullptr || !e->observed || t == nullptr || !(t->weight > 0)) continue;
          const double d = truth.distance(c);
          if (!(d > 0 && d <= near)) continue;
          measured.voxels.add(e->distance - d, [&] { return place(flight, k, c, e->distance, d); });
        }
      }
    }
    // The same points for every configuration: seeded by the world and the frame only.
    std::mt19937_64 rng(mixSeed(flight.world.seed, k));
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    for (int i = 0; i < options.points_per_frame; ++i) {
      Eigen::Vector3d offset;
      do {
        offset = Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
      } while (offset.squaredNorm() > 1.0);
      const Eigen::Vector3d p = centre + options.horizon * offset;
      if (!inVolume(p)) continue;
      const EsdfSample s = sampleEsdf(esdf, p);
      if (!s.known || !tsdfObservedAround(tsdf, p)) continue;
      const double d = truth.distance(p);
      if (!(d > 0)) continue;
      const auto where = [&] { return place(flight, k, p, s.distance, d); };
      if (d >= options.robot_radius && d <= options.robot_radius + kPassage) {
        measured.under.add(d - s.distance, where);
      }
      if (d > near) continue;
      measured.points.add(s.distance - d, where);
      if (d < options.robot_radius) measured.margin.add(s.distance - options.robot_radius, where);
    }
  }
  return measured;
}

std::string csvText(const std::vector<ClearanceRow>& rows) {
  std::string text =
      "scenario,density,voxel_size,noise,variant,flights,frames,voxels,voxel_mean,voxel_p99,"
      "voxel_p999,voxel_max,points,point_mean,point_p99,point_p999,point_max,colliding_points,"
      "margin_p999,margin_max,passage_points,under_mean,under_p99,worst_voxel,worst_point,"
      "worst_margin\n";
  for (const ClearanceRow& r : rows) {
    char line[512];
    std::snprintf(line, sizeof(line),
                  "%s,%g,%g,%g,%s,%d,%d,%lld,%.4f,%.4f,%.4f,%.4f,%lld,%.4f,%.4f,%.4f,%.4f,%lld,"
                  "%.4f,%.4f,%lld,%.4f,%.4f,",
                  r.scenario.c_str(), r.density, r.voxel_size, r.noise, r.variant.c_str(),
                  r.flights, r.frames, static_cast<long long>(r.voxels.count), r.voxels.mean,
                  r.voxels.p99, r.voxels.p999, r.voxels.max, static_cast<long long>(r.points.count),
                  r.points.mean, r.points.p99, r.points.p999, r.points.max,
                  static_cast<long long>(r.margin.count), r.margin.p999, r.margin.max,
                  static_cast<long long>(r.under.count), r.under.mean, r.under.p99);
    text += line + csvCell(r.voxels.worst) + "," + csvCell(r.points.worst) + "," +
            csvCell(r.margin.worst) + "\n";
  }
  return text;
}

void printTable(const std::vector<ClearanceRow>& rows) {
  std::printf("%-9s %5s %5s %6s %-15s %6s | %8s %6s | %8s %6s %6s | %7s %6s | %8s %6s %6s\n",
              "scenario", "dens", "voxel", "noise", "variant", "frames", "voxels", "max", "points",
              "p99.9", "max", "in coll", "margin", "passage", "under", "p99");
  for (const ClearanceRow& r : rows) {
    std::printf(
        "%-9s %5g %5g %6g %-15s %6d | %8lld %6.3f | %8lld %6.3f %6.3f | %7lld %6.3f | %8lld %6.3f "
        "%6.3f\n",
        r.scenario.c_str(), r.density, r.voxel_size, r.noise, r.variant.c_str(), r.frames,
        static_cast<long long>(r.voxels.count), r.voxels.max,
        static_cast<long long>(r.points.count), r.points.p999, r.points.max,
        static_cast<long long>(r.margin.count), r.margin.max, static_cast<long long>(r.under.count),
        r.under.mean, r.under.p99);
  }
  for (const ClearanceRow& r : rows) {
    std::printf("worst point %s %g %g %s: %s\n", r.scenario.c_str(), r.voxel_size, r.noise,
                r.variant.c_str(), r.points.worst.c_str());
  }
}

}  // namespace

Expected<ClearanceOptions> parseClearanceOptions(const std::vector<std::string>& args) {
  auto options = parseCommand<ClearanceOptions>(
      "clearance",
      "thicket-bench clearance: how much clearance the ESDF promises that the world does not\n"
      "have (ESDF distance - true distance) within the planning horizon, on maps built along\n"
      "flown paths: the real graph (local_exploration) flies every world once, then its frames\n"
      "are mapped again under every voxel size, depth noise and mapping variant. Prints the\n"
      "table and writes DIR/clearance.csv.",
      args, addClearanceFlags);
  if (!options || !options->help.empty()) return options;
  for (const std::string& flight : options->flights) {
    if (auto parsed = parseFlight(flight); !parsed) return unexpected(parsed.error());
  }
  return options;
}

std::vector<ClearanceRow> measureClearance(const ClearanceOptions& options) {
  std::vector<FlightSpec> specs;
  for (const std::string& text : options.flights) specs.push_back(*parseFlight(text));
  std::vector<const MappingVariant*> variants;
  for (const MappingVariant& v : mappingVariants()) {
    if (options.variants.empty() || std::find(options.variants.begin(), options.variants.end(),
                                              v.name) != options.variants.end()) {
      variants.push_back(&v);
    }
  }
  std::vector<Config> configs;
  for (const double voxel_size : options.voxel_sizes) {
    for (const double noise : options.noises) {
      for (const MappingVariant* variant : variants)
        configs.push_back({voxel_size, noise, variant});
    }
  }

  const auto worlds = static_cast<size_t>(options.worlds);
  const size_t num_flights = specs.size() * worlds;
  std::vector<std::optional<Flight>> flights(num_flights);
  std::mutex progress;
  parallelFor(num_flights, options.jobs, [&](size_t i) {
    flights[i] = fly(options, specs[i / worlds], static_cast<int>(i % worlds));
    const std::lock_guard lock(progress);
    const Flight& f = *flights[i];
    std::fprintf(stderr, "flew %s d%g seed %llu: %zu frames\n", f.spec.scenario.c_str(),
                 f.spec.density, static_cast<unsigned long long>(f.world.seed), f.frames.size());
  });

  std::vector<Measured> measured(num_flights * configs.size());
  parallelFor(measured.size(), options.jobs, [&](size_t i) {
    measured[i] = measure(options, *flights[i / configs.size()], configs[i % configs.size()]);
  });

  std::vector<ClearanceRow> rows;
  for (size_t s = 0; s < specs.size(); ++s) {
    for (size_t c = 0; c < configs.size(); ++c) {
      Measured total;
      for (size_t w = 0; w < worlds; ++w) {
        const Measured& m = measured[(s * worlds + w) * configs.size() + c];
        total.voxels.merge(m.voxels);
        total.points.merge(m.points);
        total.margin.merge(m.margin);
        total.under.merge(m.under);
        total.frames += m.frames;
      }
      ClearanceRow row;
      row.scenario = specs[s].scenario;
      row.density = specs[s].density;
      row.voxel_size = configs[c].voxel_size;
      row.noise = configs[c].noise;
      row.variant = configs[c].variant->name;
      row.flights = options.worlds;
      row.frames = total.frames;
      row.voxels = total.voxels.summary();
      row.points = total.points.summary();
      row.margin = total.margin.summary();
      row.under = total.under.summary();
      rows.push_back(row);
    }
  }
  return rows;
}

int clearanceCommand(const std::vector<std::string>& args) {
  auto options = parseClearanceOptions(args);
  if (!options) return usageError("clearance", options.error());
  if (!options->help.empty()) {
    std::fputs(options->help.c_str(), stdout);
    return 0;
  }
  try {
    const auto started = std::chrono::steady_clock::now();
    const std::vector<ClearanceRow> rows = measureClearance(*options);
    std::filesystem::create_directories(options->out_dir);
    writeTextFile(options->out_dir + "/clearance.csv", csvText(rows));
    printTable(rows);
    std::printf("wrote %s/clearance.csv in %.0f s\n", options->out_dir.c_str(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "thicket-bench clearance: %s\n", e.what());
    return 1;
  }
  return 0;
}

}  // namespace thicket::bench
