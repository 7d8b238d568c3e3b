// thicket-map: offline map building and inspection, for people debugging maps.
//
//   thicket-map build  --scenario S --density D --seed N --views K [--voxel V] --out MAP
//   thicket-map query  MAP x,y,z [x,y,z ...]
//   thicket-map export MAP [--ply mesh.ply] [--pcd occupied.pcd]
//   thicket-map info   MAP
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "thicket/common/esdf_query.h"
#include "thicket/mapper/map_io.h"
#include "thicket/mapper/mapper.h"
#include "thicket/sim/ground_truth.h"
#include "thicket/sim/render.h"
#include "thicket/sim/world.h"

namespace {

using thicket::mapper::SavedMap;

constexpr const char* kUsage =
    "usage: thicket-map build  --scenario S --density D --seed N --views K [--voxel V]\n"
    "                          [--worlds-dir DIR] --out MAP\n"
    "       thicket-map query  MAP x,y,z [x,y,z ...]\n"
    "       thicket-map export MAP [--ply mesh.ply] [--pcd occupied.pcd]\n"
    "       thicket-map info   MAP\n";

int fail(const std::string& message) {
  std::fprintf(stderr, "thicket-map: %s\n", message.c_str());
  return 2;
}

// "--key value" pairs; anything else is an error.
thicket::Expected<std::map<std::string, std::string>> parseFlags(
    const std::vector<std::string>& args) {
  std::map<std::string, std::string> flags;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i].rfind("--", 0) != 0)
      return thicket::unexpected("unexpected argument '" + args[i] + "'");
    if (i + 1 >= args.size()) return thicket::unexpected(args[i] + " needs a value");
    flags[args[i]] = args[i + 1];
    ++i;
  }
  return flags;
}

thicket::Expected<double> number(const std::string& text, const std::string& what) {
  try {
    size_t used = 0;
    const double value = std::stod(text, &used);
    if (used == text.size() && std::isfinite(value)) return value;
  } catch (const std::exception&) {
  }
  return thicket::unexpected(what + " '" + text + "' is not a number");
}

int build(const std::vector<std::string>& args) {
  auto flags = parseFlags(args);
  if (!flags) return fail(flags.error());
  for (const auto& [key, value] : *flags) {
    if (key != "--scenario" && key != "--density" && key != "--seed" && key != "--views" &&
        key != "--voxel" && key != "--worlds-dir" && key != "--out") {
      return fail("unknown option " + key);
    }
  }
  for (const char* required : {"--scenario", "--density", "--seed", "--views", "--out"}) {
    if (!flags->count(required)) return fail(std::string("build needs ") + required);
  }
  auto density = number(flags->at("--density"), "--density");
  auto seed = number(flags->at("--seed"), "--seed");
  auto views = number(flags->at("--views"), "--views");
  auto voxel = number(flags->count("--voxel") ? flags->at("--voxel") : "0.2", "--voxel");
  for (const auto* value : {&density, &seed, &views, &voxel}) {
    if (!*value) return fail(value->error());
  }
  if (*views < 1 || *views != std::floor(*views)) return fail("--views must be a positive integer");
  if (*seed < 0 || *seed != std::floor(*seed)) return fail("--seed must be a non-negative integer");
  const std::string worlds_dir = flags->count("--worlds-dir")
                                     ? flags->at("--worlds-dir")
                                     : std::string(THICKET_SOURCE_DIR) + "/config/worlds";
  auto spec = thicket::sim::loadScenario(flags->at("--scenario"), worlds_dir);
  if (!spec) return fail(spec.error());
  auto world = thicket::sim::generateWorld(*spec, *density, static_cast<uint64_t>(*seed));
  if (!world) return fail(world.error());

  thicket::mapper::MapperOptions options;
  options.voxel_size = *voxel;
  try {
    thicket::mapper::Mapper mapper(options);
    const thicket::sim::DepthRenderer renderer(*world, thicket::sim::DepthCameraOptions{});
    const thicket::sim::GroundTruth truth(*world);
    const Eigen::Vector3d direction = (world->goal - world->start).normalized();
    const double yaw = std::atan2(direction.y(), direction.x());
    int integrated = 0;
    for (int k = 0; k < static_cast<int>(*views); ++k) {
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
    thicket::mapper::saveMap(flags->at("--out"), saved);
    std::printf("integrated %d of %d views at %.3f m voxels: %zu TSDF and %zu ESDF blocks -> %s\n",
                integrated, static_cast<int>(*views), *voxel, saved.tsdf.numBlocks(),
                saved.esdf.numBlocks(), flags->at("--out").c_str());
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  return 0;
}

thicket::Expected<SavedMap> load(const std::vector<std::string>& args) {
  if (args.empty()) return thicket::unexpected("which map? (a MAP file written by build)");
  return thicket::mapper::loadMap(args[0]);
}

int query(const std::vector<std::string>& args) {
  auto map = load(args);
  if (!map) return fail(map.error());
  if (args.size() < 2) return fail("query needs points x,y,z");
  for (size_t i = 1; i < args.size(); ++i) {
    std::stringstream text(args[i]);
    std::vector<double> xyz;
    for (std::string part; std::getline(text, part, ',');) {
      auto value = number(part, "coordinate");
      if (!value) return fail(value.error() + " in '" + args[i] + "'");
      xyz.push_back(*value);
    }
    if (xyz.size() != 3) return fail("'" + args[i] + "' is not x,y,z");
    const thicket::EsdfSample sample = thicket::sampleEsdf(map->esdf, {xyz[0], xyz[1], xyz[2]});
    if (sample.known) {
      std::printf("%g,%g,%g: distance %.3f m, observed\n", xyz[0], xyz[1], xyz[2], sample.distance);
    } else {
      std::printf("%g,%g,%g: unknown\n", xyz[0], xyz[1], xyz[2]);
    }
  }
  return 0;
}

int exportMap(const std::vector<std::string>& args) {
  auto map = load(args);
  if (!map) return fail(map.error());
  auto flags = parseFlags({args.begin() + 1, args.end()});
  if (!flags) return fail(flags.error());
  if (flags->empty()) return fail("export needs --ply and/or --pcd");
  try {
    for (const auto& [key, path] : *flags) {
      if (key == "--ply") {
        std::printf("%zu triangles -> %s\n", thicket::mapper::exportMeshPly(map->tsdf, path),
                    path.c_str());
      } else if (key == "--pcd") {
        std::printf("%zu occupied voxels -> %s\n",
                    thicket::mapper::exportOccupiedPcd(map->tsdf, path), path.c_str());
      } else {
        return fail("unknown option " + key);
      }
    }
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  return 0;
}

int info(const std::vector<std::string>& args) {
  auto map = load(args);
  if (!map) return fail(map.error());
  if (args.size() > 1) return fail("info takes only the map");
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
  if (argc < 2) {
    std::fprintf(stderr, "%s", kUsage);
    return 2;
  }
  const std::string command = argv[1];
  const std::vector<std::string> args(argv + 2, argv + argc);
  if (command == "build") return build(args);
  if (command == "query") return query(args);
  if (command == "export") return exportMap(args);
  if (command == "info") return info(args);
  if (command == "-h" || command == "--help") {
    std::printf("%s", kUsage);
    return 0;
  }
  return fail("unknown command '" + command + "'\n" + kUsage);
}
