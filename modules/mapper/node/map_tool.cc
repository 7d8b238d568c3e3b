// thicket-map: offline map building and inspection, for people debugging maps.
//
//   thicket-map build  --scenario S --density D --seed N --views K [--voxel V] --out MAP
//   thicket-map query  MAP x,y,z [x,y,z ...]
//   thicket-map export MAP [--ply mesh.ply] [--pcd occupied.pcd]
//   thicket-map info   MAP
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "thicket/common/cli.h"
#include "thicket/common/esdf_query.h"
#include "thicket/common/node_main.h"
#include "thicket/mapper/map_io.h"
#include "thicket/mapper/mapper.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/render.h"
#include "thicket/sim/world.h"

namespace {

using thicket::mapper::SavedMap;

int fail(const std::string& message) {
  return thicket::failNode("thicket-map", message);
}

struct BuildArgs {
  std::string scenario, out;
  std::string worlds_dir = std::string(THICKET_SOURCE_DIR) + "/config/worlds";
  double density = 0;
  double voxel = 0.2;
  int64_t seed = 0;
  int views = 0;
};

void addBuildFlags(CLI::App& build, BuildArgs& args) {
  using thicket::cli::nonEmpty;
  build.add_option("--scenario", args.scenario, "paper, eth, forest50 or a scenario .yaml")
      ->required()
      ->check(nonEmpty());
  build.add_option("--density", args.density, "trees per m^2 of the obstacle region")
      ->required()
      ->check(thicket::cli::number(0));
  thicket::cli::addSeed(build, args.seed)->required();
  build
      .add_option("--views", args.views,
                  "depth images integrated, one per metre from the start towards the goal")
      ->required()
      ->check(thicket::cli::integer(1, 100000));
  build.add_option("--voxel", args.voxel, "voxel size [m]")
      ->check(thicket::cli::number(0.01, 10))
      ->capture_default_str();
  build.add_option("--worlds-dir", args.worlds_dir, "where scenario names are looked up")
      ->check(nonEmpty());
  build.add_option("--out", args.out, "the map file to write")->required()->check(nonEmpty());
}

int build(const BuildArgs& args) {
  auto spec = thicket::sim::loadScenario(args.scenario, args.worlds_dir);
  if (!spec) return fail(spec.error());
  auto world = thicket::sim::generateWorld(*spec, args.density, static_cast<uint64_t>(args.seed));
  if (!world) return fail(world.error());

  thicket::mapper::MapperOptions options;
  options.voxel_size = args.voxel;
  try {
    thicket::mapper::Mapper mapper(options);
    const thicket::sim::DepthRenderer renderer(*world, thicket::sim::DepthCameraOptions{});
    const thicket::sim::GroundTruth truth(*world);
    const Eigen::Vector3d direction = (world->goal - world->start).normalized();
    const double yaw = std::atan2(direction.y(), direction.x());
    int integrated = 0;
    for (int k = 0; k < args.views; ++k) {
      const Eigen::Vector3d position = world->start + k * direction;
      if (truth.distance(position) < world->robot_radius) {
        std::printf(
            "view %d at (%.2f, %.2f, %.2f): skipped, within the robot radius of an "
            "obstacle\n",
            k, position.x(), position.y(), position.z());
        continue;
      }
      const int64_t utime = (k + 1) * 1'000'000;
      const thicket::Pose body = thicket::Pose::fromYaw(position, yaw);
      if (const auto added = mapper.addPose(utime, body); !added.accepted()) {
        return fail(added.reason);
      }
      mapper.addFrame(renderer.renderImage(body, utime));
      std::vector<thicket::mapper::MapRevisionUpdate> updates;
      for (const auto& outcome : mapper.integrateReady(updates)) {
        if (outcome.status != thicket::mapper::FrameOutcome::Status::kIntegrated) {
          return fail("view " + std::to_string(k) + " refused: " + outcome.reason);
        }
      }
      ++integrated;
    }
    SavedMap saved;
    saved.tsdf = mapper.tsdf();
    saved.esdf = mapper.esdf();
    saved.map_id = 1;
    saved.revision = mapper.revision();
    saved.utime = mapper.utime();
    thicket::mapper::saveMap(args.out, saved);
    std::printf("integrated %d of %d views at %.3f m voxels: %zu TSDF and %zu ESDF blocks -> %s\n",
                integrated, args.views, args.voxel, saved.tsdf.numBlocks(), saved.esdf.numBlocks(),
                args.out.c_str());
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  return 0;
}

int query(const std::string& path, const std::vector<std::string>& points) {
  std::vector<Eigen::Vector3d> queries;
  for (const std::string& point : points) {
    std::stringstream text(point);
    std::vector<double> xyz;
    for (std::string part; std::getline(text, part, ',');) {
      std::string item = part;
      if (const std::string error = thicket::cli::number()(item); !error.empty()) {
        return fail("'" + point + "': a coordinate " + error);
      }
      xyz.push_back(std::stod(item));
    }
    if (xyz.size() != 3) return fail("'" + point + "' is not x,y,z");
    queries.emplace_back(xyz[0], xyz[1], xyz[2]);
  }
  auto map = thicket::mapper::loadMap(path);
  if (!map) return fail(map.error());
  for (const Eigen::Vector3d& xyz : queries) {
    const thicket::EsdfSample sample = thicket::sampleEsdf(map->esdf, xyz);
    if (sample.known) {
      std::printf("%g,%g,%g: distance %.3f m, observed\n", xyz.x(), xyz.y(), xyz.z(),
                  sample.distance);
    } else {
      std::printf("%g,%g,%g: unknown\n", xyz.x(), xyz.y(), xyz.z());
    }
  }
  return 0;
}

int exportMap(const std::string& path, const std::string& ply, const std::string& pcd) {
  if (ply.empty() && pcd.empty()) return fail("export needs --ply and/or --pcd");
  auto map = thicket::mapper::loadMap(path);
  if (!map) return fail(map.error());
  try {
    if (!ply.empty()) {
      std::printf("%zu triangles -> %s\n", thicket::mapper::exportMeshPly(map->tsdf, ply),
                  ply.c_str());
    }
    if (!pcd.empty()) {
      std::printf("%zu occupied voxels -> %s\n", thicket::mapper::exportOccupiedPcd(map->tsdf, pcd),
                  pcd.c_str());
    }
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  return 0;
}

int info(const std::string& path) {
  auto map = thicket::mapper::loadMap(path);
  if (!map) return fail(map.error());
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(INT32_MAX),
                  hi = Eigen::Vector3i::Constant(INT32_MIN);
  for (const thicket::BlockIndex& b : map->tsdf.blockIndices()) {
    lo = lo.cwiseMin(b);
    hi = hi.cwiseMax(b);
  }
  const double block = map->tsdf.blockSize();
  std::printf("map id %lld, revision %lld, newest frame at %.3f s\n",
              static_cast<long long>(map->map_id), static_cast<long long>(map->revision),
              map->utime * 1e-6);
  std::printf("voxel size %.3f m, blocks of %d^3 voxels (%.2f m)\n", map->tsdf.voxelSize(),
              thicket::kVoxelsPerSide, block);
  if (map->tsdf.numBlocks() > 0) {
    std::printf("bounds [%.2f, %.2f] x [%.2f, %.2f] x [%.2f, %.2f] m\n", lo.x() * block,
                (hi.x() + 1) * block, lo.y() * block, (hi.y() + 1) * block, lo.z() * block,
                (hi.z() + 1) * block);
  }
  std::printf("TSDF %zu blocks, %.1f MiB; ESDF %zu blocks, %.1f MiB\n", map->tsdf.numBlocks(),
              map->tsdf.memoryBytes() / 1048576.0, map->esdf.numBlocks(),
              map->esdf.memoryBytes() / 1048576.0);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("thicket-map: offline map building and inspection, for people debugging maps.",
               "thicket-map");
  app.require_subcommand(1);
  CLI::App* build_command = app.add_subcommand(
      "build", "integrate simulated depth views of a generated world into a map file");
  BuildArgs build_args;
  addBuildFlags(*build_command, build_args);

  std::string map_path;
  const auto addMap = [&](CLI::App& command) {
    command.add_option("MAP", map_path, "a map file written by build or by the mapper")
        ->required()
        ->check(thicket::cli::nonEmpty());
  };
  CLI::App* query_command =
      app.add_subcommand("query", "the ESDF's distance at points (unknown where unobserved)");
  addMap(*query_command);
  std::vector<std::string> points;
  query_command->add_option("POINTS", points, "points x,y,z [m]")->required();
  CLI::App* export_command = app.add_subcommand("export", "the map as a mesh and/or a cloud");
  addMap(*export_command);
  std::string ply, pcd;
  export_command->add_option("--ply", ply, "the TSDF's surface mesh (PLY)")
      ->check(thicket::cli::nonEmpty());
  export_command->add_option("--pcd", pcd, "the occupied voxels' centres (PCD)")
      ->check(thicket::cli::nonEmpty());
  CLI::App* info_command = app.add_subcommand("info", "what a map holds");
  addMap(*info_command);

  if (auto exit_code = thicket::cli::parse(app, argc, argv)) return *exit_code;
  if (*build_command) return build(build_args);
  if (*query_command) return query(map_path, points);
  if (*export_command) return exportMap(map_path, ply, pcd);
  return info(map_path);
}
