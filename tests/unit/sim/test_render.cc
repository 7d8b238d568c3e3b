#include "thicket/sim/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace thicket::sim {
namespace {

using std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

double deg(double degrees) {
  return degrees * pi / 180;
}

World emptyWorld(const Eigen::Vector3d& bounds_min, const Eigen::Vector3d& bounds_max) {
  World world;
  world.bounds_min = bounds_min;
  world.bounds_max = bounds_max;
  return world;
}

// Cylinders like the benchmark's: uniform axes over the whole floor, radius U[0.1, 0.5], height
// U[2, 5].
World randomForest(uint64_t seed, int count, double size) {
  World world = emptyWorld(Eigen::Vector3d::Zero(), Eigen::Vector3d(size, size, 5));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> xy(0, size), radius(0.1, 0.5), height(2, 5);
  for (int i = 0; i < count; ++i)
    world.cylinders.push_back({xy(rng), xy(rng), radius(rng), height(rng)});
  return world;
}

// The reference: the nearest of all intersections of the ray with every primitive, textbook
// formulas, no acceleration and no early outs. Valid for origins outside every solid.
double referenceRange(const World& world, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double best = kInf;
  const auto consider = [&](double t) {
    if (t >= 0 && t < best) best = t;
  };
  const Eigen::Vector3d& lo = world.bounds_min;
  const Eigen::Vector3d& hi = world.bounds_max;
  if (d.z() != 0) consider((lo.z() - o.z()) / d.z());
  for (int axis = 0; axis < 2; ++axis) {
    if (d[axis] == 0) continue;
    for (double plane : {lo[axis], hi[axis]}) {
      const double t = (plane - o[axis]) / d[axis];
      const Eigen::Vector3d p = o + t * d;
      const int other = 1 - axis;
      if (p[other] >= lo[other] && p[other] <= hi[other] && p.z() >= lo.z() && p.z() <= hi.z()) {
        consider(t);
      }
    }
  }
  for (const Cylinder& c : world.cylinders) {
    const double ox = o.x() - c.x;
    const double oy = o.y() - c.y;
    const double a = d.x() * d.x() + d.y() * d.y();
    const double b = 2 * (ox * d.x() + oy * d.y());
    const double k = ox * ox + oy * oy - c.radius * c.radius;
    const double disc = b * b - 4 * a * k;
    if (a > 1e-300 && disc >= 0) {
      for (double t : {(-b - std::sqrt(disc)) / (2 * a), (-b + std::sqrt(disc)) / (2 * a)}) {
        const double z = o.z() + t * d.z();
        if (z >= 0 && z <= c.height) consider(t);
      }
    }
    if (d.z() != 0) {
      const double t = (c.height - o.z()) / d.z();
      const double px = ox + t * d.x();
      const double py = oy + t * d.y();
      if (px * px + py * py <= c.radius * c.radius) consider(t);
    }
  }
  return best;
}

bool insideSolid(const World& world, const Eigen::Vector3d& p) {
  if (p.z() < world.bounds_min.z()) return true;
  return std::any_of(world.cylinders.begin(), world.cylinders.end(), [&](const Cylinder& c) {
    return p.z() >= 0 && p.z() <= c.height && std::hypot(p.x() - c.x, p.y() - c.y) <= c.radius;
  });
}

// A level body pose.
Pose bodyPose(const Eigen::Vector3d& position, double yaw) {
  return Pose::fromYaw(position, yaw);
}

// The reference depth image, computed ray by ray from the camera model alone.
std::vector<double> referenceDepth(const World& world, const DepthRenderer& renderer,
                                   const Pose& world_T_body) {
  const PinholeCamera camera = renderer.camera();
  const Pose world_T_camera = world_T_body * renderer.cameraInBody();
  std::vector<double> depth(camera.width * camera.height, 0.0);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d ray_camera = camera.backProject(u, v, 1.0);
      const Eigen::Vector3d dir = world_T_camera.orientation * ray_camera.normalized();
      const double range = referenceRange(world, world_T_camera.position, dir);
      if (range <= renderer.options().max_range) {
        depth[v * camera.width + u] = range / ray_camera.norm();
      }
    }
  }
  return depth;
}

// Renders and compares every pixel with the reference: equal hit/no-hit, depth to 1e-6 relative.
void expectMatchesReference(const World& world, const DepthRenderer& renderer,
                            const Pose& world_T_body, const std::string& what) {
  ASSERT_FALSE(insideSolid(world, (world_T_body * renderer.cameraInBody()).position)) << what;
  std::vector<float> depth;
  renderer.render(world_T_body, depth);
  const std::vector<double> expected = referenceDepth(world, renderer, world_T_body);
  ASSERT_EQ(depth.size(), expected.size());
  int mismatches = 0, hits = 0;
  for (size_t i = 0; i < depth.size(); ++i) {
    hits += expected[i] > 0;
    const bool ok =
        expected[i] == 0 ? depth[i] == 0 : std::abs(depth[i] - expected[i]) <= 1e-6 * expected[i];
    if (!ok && ++mismatches <= 5) {
      ADD_FAILURE() << what << ": pixel " << i << " depth " << depth[i] << ", reference "
                    << expected[i];
    }
  }
  EXPECT_EQ(mismatches, 0) << what;
  EXPECT_GT(hits, 0) << what;
}

DepthCameraOptions smallCamera(double pitch_down_deg) {
  DepthCameraOptions options;
  options.width = 161;
  options.height = 121;
  options.pitch_down_deg = pitch_down_deg;
  return options;
}

TEST(RayCaster, DepthMatchesBruteForceInDenseForests) {
  for (uint64_t seed : {1u, 2u}) {
    const World world = randomForest(seed, 300, 30);  // 0.33 trees per m^2
    std::mt19937_64 rng(100 + seed);
    std::uniform_real_distribution<double> xy(1, 29), z(0.3, 4.5);
    for (double pitch : {0.0, 12.0, 45.0, -30.0, 90.0}) {
      const DepthRenderer renderer(world, smallCamera(pitch));
      // Yaws along +x and -x cross the azimuth wrap-around of any binning; the rest are random.
      for (double yaw : {0.0, pi, -pi + 1e-9, 0.5 * pi, 2.3}) {
        Eigen::Vector3d eye;
        do {
          eye = Eigen::Vector3d(xy(rng), xy(rng), z(rng));
        } while (insideSolid(world, eye));
        std::ostringstream what;
        what << "seed " << seed << " pitch " << pitch << " yaw " << yaw << " eye "
             << eye.transpose();
        expectMatchesReference(world, renderer, bodyPose(eye, yaw), what.str());
      }
    }
  }
}

TEST(RayCaster, DepthMatchesBruteForceWithRolledCameras) {
  const World world = randomForest(3, 200, 25);
  const DepthRenderer renderer(world, smallCamera(20));
  std::mt19937_64 rng(7);
  for (int i = 0; i < 6; ++i) {
    Pose body;
    do {
      body.position = Eigen::Vector3d(std::uniform_real_distribution<double>(1, 24)(rng),
                                      std::uniform_real_distribution<double>(1, 24)(rng),
                                      std::uniform_real_distribution<double>(0.5, 4.5)(rng));
    } while (insideSolid(world, body.position));
    body.orientation = Eigen::Quaterniond::UnitRandom();
    expectMatchesReference(world, renderer, body, "rolled camera " + std::to_string(i));
  }
}

TEST(RayCaster, DepthMatchesBruteForceNearAndAboveCylinders) {
  World world = randomForest(4, 120, 20);
  world.cylinders.push_back({10, 10, 0.5, 1.0});  // a short stump to stand over
  world.cylinders.push_back({12, 10, 0.3, 3.0});
  const int stump = static_cast<int>(world.cylinders.size()) - 2;
  world.cylinders.erase(std::remove_if(world.cylinders.begin(), world.cylinders.end() - 2,
                                       [](const Cylinder& c) {
                                         return std::hypot(c.x - 11, c.y - 10) < c.radius + 1.6;
                                       }),
                        world.cylinders.end() - 2);
  const std::vector<Pose> poses = {
      bodyPose({10.1, 10.05, 1.5}, 0.3),      // over the stump, inside its footprint
      bodyPose({10.0, 10.0, 1.0001}, 2.0),    // just above the stump's cap, on its axis
      bodyPose({12.3101, 10.0, 1.5}, pi),     // 1 cm from the taller trunk, looking at it
      bodyPose({11.0, 10.0, 4.0}, 0.0),       // above both, between them
      bodyPose({10.0 - 0.5, 10.0, 1.2}, pi),  // right at the stump's edge, looking away
  };
  for (double pitch : {90.0, 60.0, 30.0, 0.0}) {
    const DepthRenderer renderer(world, smallCamera(pitch));
    for (size_t i = 0; i < poses.size(); ++i) {
      expectMatchesReference(world, renderer, poses[i],
                             "pose " + std::to_string(i) + " pitch " + std::to_string(pitch));
    }
  }
  // Looking straight down from over the stump, the image centre sees its cap.
  const DepthRenderer down(world, smallCamera(90));
  const Pose world_T_camera = poses[0] * down.cameraInBody();
  SurfaceHit hit;
  const double range = RayCaster(world).cast(
      world_T_camera.position, world_T_camera.orientation * Eigen::Vector3d::UnitZ(), 20, &hit);
  EXPECT_NEAR(range, 0.5, 1e-12);
  EXPECT_EQ(hit.surface, SurfaceHit::Surface::kCylinderCap);
  EXPECT_EQ(hit.index, stump);
}

TEST(RayCaster, ViewAndSingleRaysAgreeWithTheReferenceForRandomRays) {
  const World world = randomForest(5, 250, 30);
  const RayCaster caster(world);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> xy(0.5, 29.5), z(0.1, 6.0);
  std::normal_distribution<double> normal;
  int hits = 0;
  for (int e = 0; e < 20; ++e) {
    Eigen::Vector3d eye;
    do {
      eye = Eigen::Vector3d(xy(rng), xy(rng), z(rng));
    } while (insideSolid(world, eye));
    const double max_range = e % 2 == 0 ? 20.0 : kInf;
    const RayCaster::View view = caster.view(eye, max_range);
    for (int r = 0; r < 500; ++r) {
      Eigen::Vector3d dir(normal(rng), normal(rng), normal(rng));
      if (r % 5 == 0) dir.head<2>() *= 1e-7;                                // nearly vertical
      if (r % 50 == 0) dir = Eigen::Vector3d(0, 0, r % 100 == 0 ? -1 : 1);  // exactly vertical
      dir.normalize();
      const double reference = referenceRange(world, eye, dir);
      const double expected = reference <= max_range ? reference : RayCaster::kNoHit;
      SurfaceHit from_view, single;
      const double range_view = view.cast(dir, &from_view);
      const double range_single = caster.cast(eye, dir, max_range, &single);
      if (expected == RayCaster::kNoHit) {
        EXPECT_EQ(range_view, RayCaster::kNoHit);
        EXPECT_EQ(range_single, RayCaster::kNoHit);
        EXPECT_EQ(from_view.surface, SurfaceHit::Surface::kNone);
        continue;
      }
      ++hits;
      EXPECT_NEAR(range_view, expected, 1e-9 * expected);
      EXPECT_NEAR(range_single, expected, 1e-9 * expected);
      EXPECT_EQ(from_view.surface, single.surface);
      EXPECT_EQ(from_view.index, single.index);
      EXPECT_LT((from_view.point - (eye + range_view * dir)).norm(), 1e-9);
      // The reported surface really is at the reported point.
      const Eigen::Vector3d& p = from_view.point;
      switch (from_view.surface) {
        case SurfaceHit::Surface::kGround:
          EXPECT_NEAR(p.z(), 0, 1e-9);
          break;
        case SurfaceHit::Surface::kWall:
          EXPECT_NEAR(from_view.index < 2 ? p.x() : p.y(), from_view.index % 2 == 0 ? 0 : 30, 1e-9);
          break;
        case SurfaceHit::Surface::kCylinderSide: {
          const Cylinder& c = world.cylinders[from_view.index];
          EXPECT_NEAR(std::hypot(p.x() - c.x, p.y() - c.y), c.radius, 1e-9);
          break;
        }
        case SurfaceHit::Surface::kCylinderCap:
          EXPECT_NEAR(p.z(), world.cylinders[from_view.index].height, 1e-9);
          break;
        case SurfaceHit::Surface::kNone:
          ADD_FAILURE() << "a hit without a surface";
      }
    }
  }
  EXPECT_GT(hits, 5000);
}

TEST(RayCaster, ViewsFarFromTheWallsAgreeWithTheReference) {
  // 60 x 60 m: from the middle, the walls are out of a 20 m range but within an infinite one.
  const World world = randomForest(9, 600, 60);
  const RayCaster caster(world);
  std::mt19937_64 rng(13);
  std::normal_distribution<double> normal;
  Eigen::Vector3d eye(30, 30, 1.5);
  while (insideSolid(world, eye)) eye.x() += 0.5;
  for (double max_range : {20.0, kInf}) {
    const RayCaster::View view = caster.view(eye, max_range);
    int walls = 0;
    for (int r = 0; r < 3000; ++r) {
      const Eigen::Vector3d dir =
          Eigen::Vector3d(normal(rng), normal(rng), 0.2 * normal(rng)).normalized();
      const double reference = referenceRange(world, eye, dir);
      const double expected = reference <= max_range ? reference : RayCaster::kNoHit;
      SurfaceHit hit;
      const double range = view.cast(dir, &hit);
      if (expected == RayCaster::kNoHit) {
        EXPECT_EQ(range, RayCaster::kNoHit);
      } else {
        EXPECT_NEAR(range, expected, 1e-9 * expected);
      }
      walls += hit.surface == SurfaceHit::Surface::kWall;
    }
    EXPECT_EQ(walls > 0, max_range == kInf);
  }
}

TEST(RayCaster, ViewCastsManyRaysBitForBitAsOneByOne) {
  const World world = randomForest(10, 300, 30);
  const RayCaster::View view = RayCaster(world).view({15.2, 14.9, 1.5}, 20);
  std::mt19937_64 rng(17);
  std::normal_distribution<double> normal;
  std::vector<Eigen::Vector3d> dirs(1000);
  for (Eigen::Vector3d& dir : dirs) {
    dir = Eigen::Vector3d(normal(rng), normal(rng), 0.3 * normal(rng)).normalized();
  }
  std::vector<double> ranges(dirs.size());
  std::vector<SurfaceHit> hits(dirs.size());
  view.cast(dirs, ranges, hits);
  int hit_count = 0;
  for (size_t i = 0; i < dirs.size(); ++i) {
    SurfaceHit hit;
    ASSERT_EQ(view.cast(dirs[i], &hit), ranges[i]) << i;
    EXPECT_EQ(hit.surface, hits[i].surface);
    EXPECT_EQ(hit.index, hits[i].index);
    EXPECT_EQ(hit.point, hits[i].point);
    hit_count += ranges[i] != RayCaster::kNoHit;
  }
  EXPECT_GT(hit_count, 500);
  std::vector<double> too_few(dirs.size() - 1);
  EXPECT_THROW(view.cast(dirs, too_few), std::invalid_argument);
}

TEST(RayCaster, FansAgreeWithTheReference) {
  // Eyes anywhere, inside the walls and out, over cylinders and between them; every fan's rays
  // sweep from straight down to straight up.
  const World world = randomForest(12, 300, 30);
  const RayCaster caster(world);
  std::mt19937_64 rng(19);
  std::uniform_real_distribution<double> xy(-3, 33), z(0.1, 7.0), angle(-pi, pi);
  int hits = 0, caps = 0, walls = 0;
  for (int e = 0; e < 40; ++e) {
    Eigen::Vector3d eye;
    do {
      eye = Eigen::Vector3d(xy(rng), xy(rng), z(rng));
    } while (insideSolid(world, eye));
    const double max_range = e % 3 == 0 ? kInf : 20.0;
    const RayCaster::View view = caster.view(eye, max_range);
    for (int f = 0; f < 10; ++f) {
      const double azimuth_angle = f == 0 ? 0.0 : angle(rng);  // 0: the bins' wrap-around
      const Eigen::Vector2d azimuth(std::cos(azimuth_angle), std::sin(azimuth_angle));
      std::vector<Eigen::Vector3d> dirs;
      for (int k = 0; k <= 60; ++k) {
        const double elevation = (k / 60.0 - 0.5) * pi;
        dirs.emplace_back(std::cos(elevation) * azimuth.x(), std::cos(elevation) * azimuth.y(),
                          std::sin(elevation));
      }
      std::vector<double> ranges(dirs.size());
      std::vector<SurfaceHit> fan_hits(dirs.size());
      view.castFan(azimuth, dirs, ranges, fan_hits);
      for (size_t k = 0; k < dirs.size(); ++k) {
        const double reference = referenceRange(world, eye, dirs[k]);
        SurfaceHit single;
        const double range_single = view.cast(dirs[k], &single);
        if (reference == kInf || reference > max_range) {
          EXPECT_EQ(ranges[k], RayCaster::kNoHit);
          continue;
        }
        ++hits;
        caps += fan_hits[k].surface == SurfaceHit::Surface::kCylinderCap;
        walls += fan_hits[k].surface == SurfaceHit::Surface::kWall;
        ASSERT_NEAR(ranges[k], reference, 1e-9 * reference) << "eye " << eye.transpose();
        EXPECT_EQ(fan_hits[k].surface, single.surface);
        EXPECT_EQ(fan_hits[k].index, single.index);
        EXPECT_LT((fan_hits[k].point - (eye + range_single * dirs[k])).norm(), 1e-9);
      }
    }
  }
  EXPECT_GT(hits, 10000);
  EXPECT_GT(caps, 50);
  EXPECT_GT(walls, 200);
}

TEST(RayCaster, FansRefuseRaysOutsideThemAndBadAzimuths) {
  const World world = emptyWorld(Eigen::Vector3d::Zero(), Eigen::Vector3d(20, 20, 5));
  const RayCaster::View view = RayCaster(world).view({10, 10, 1.5}, 20);
  const Eigen::Vector2d azimuth(0.6, 0.8);
  std::vector<Eigen::Vector3d> dirs = {Eigen::Vector3d(0.6, 0.8, 0).normalized()};
  std::vector<double> ranges(1);
  EXPECT_NO_THROW(view.castFan(azimuth, dirs, ranges));
  dirs[0] = Eigen::Vector3d(-0.6, -0.8, 0);  // the opposite half-plane
  EXPECT_THROW(view.castFan(azimuth, dirs, ranges), std::invalid_argument);
  dirs[0] = Eigen::Vector3d(0.6, 0.8 + 1e-6, 0).normalized();
  EXPECT_THROW(view.castFan(azimuth, dirs, ranges), std::invalid_argument);
  dirs[0] = Eigen::Vector3d(0.6, 0.8, 0);
  EXPECT_THROW(view.castFan({0.6, 0.7}, dirs, ranges), std::invalid_argument);
  EXPECT_THROW(view.castFan({NAN, 0.8}, dirs, ranges), std::invalid_argument);
  std::vector<double> too_many(2);
  EXPECT_THROW(view.castFan(azimuth, dirs, too_many), std::invalid_argument);
  // Straight up or down is in every fan.
  dirs[0] = Eigen::Vector3d(0, 0, -1);
  view.castFan(azimuth, dirs, ranges);
  EXPECT_NEAR(ranges[0], 1.5, 1e-12);
}

TEST(RayCaster, OriginsInsideSolidsHitAtRangeZero) {
  World world = emptyWorld(Eigen::Vector3d::Zero(), Eigen::Vector3d(10, 10, 5));
  world.cylinders.push_back({5, 5, 0.5, 2.0});
  const RayCaster caster(world);
  SurfaceHit hit;
  EXPECT_EQ(caster.cast({5.2, 5.0, 1.0}, Eigen::Vector3d::UnitX(), 20, &hit), 0);
  EXPECT_EQ(hit.surface, SurfaceHit::Surface::kCylinderSide);
  EXPECT_EQ(hit.index, 0);
  EXPECT_EQ(caster.view({5, 5, 2.0}, 20).cast(Eigen::Vector3d::UnitZ(), &hit), 0);  // on the cap
  EXPECT_EQ(caster.view({1, 1, -0.1}, 20).cast(Eigen::Vector3d::UnitZ(), &hit), 0);
  EXPECT_EQ(hit.surface, SurfaceHit::Surface::kGround);
  // Just above the cap, looking up, there is nothing; looking down, the cap.
  EXPECT_EQ(caster.view({5, 5, 2.1}, 20).cast(Eigen::Vector3d::UnitZ()), RayCaster::kNoHit);
  EXPECT_NEAR(caster.view({5, 5, 2.1}, 20).cast(-Eigen::Vector3d::UnitZ()), 0.1, 1e-12);
  // A camera inside a tree sees nothing.
  const DepthRenderer renderer(world, DepthCameraOptions{});
  std::vector<float> depth;
  renderer.render(bodyPose({5, 5, 1}, 0), depth);
  EXPECT_TRUE(std::all_of(depth.begin(), depth.end(), [](float d) { return d == 0; }));
  EXPECT_THROW(caster.cast({1, 1, 1}, Eigen::Vector3d::UnitX(), -1), std::invalid_argument);
  EXPECT_THROW(caster.view({1, 1, 1}, std::nan("")), std::invalid_argument);
}

float pixel(const std::vector<float>& image, const PinholeCamera& camera, int u, int v) {
  return image[v * camera.width + u];
}

TEST(DepthRenderer, LevelCameraSeesAWallAtItsDistance) {
  const World world = emptyWorld({0, -50, 0}, {20, 50, 5});
  DepthCameraOptions options;
  options.width = 321;
  options.height = 241;
  const DepthRenderer renderer(world, options);
  const PinholeCamera camera = renderer.camera();
  std::vector<float> depth;
  renderer.render(bodyPose({13, 0, 1.5}, 0), depth);
  const int cu = camera.width / 2, cv = camera.height / 2;
  ASSERT_EQ(camera.cx, cu);
  EXPECT_NEAR(pixel(depth, camera, cu, cv), 7.0, 1e-5);
  // A wall facing the camera has the same z-depth everywhere: every pixel of it reads 7 m, up to
  // the rows that look over it (3.5 m above the eye at 7 m).
  const int top_row = static_cast<int>(std::ceil(cv - 3.5 / 7.0 * camera.fy));
  EXPECT_EQ(pixel(depth, camera, cu, top_row - 1), 0.0f);
  for (int v = top_row; v <= cv; v += 4) {
    for (int u = 0; u < camera.width; u += 10) {
      EXPECT_NEAR(pixel(depth, camera, u, v), 7.0, 1e-5) << u << ", " << v;
    }
  }
}

TEST(DepthRenderer, PitchedCameraSeesTheGroundAtHeightOverSine) {
  const World world = emptyWorld({-100, -100, 0}, {100, 100, 5});
  DepthCameraOptions options;
  options.width = 161;
  options.height = 121;
  options.pitch_down_deg = 30;
  const DepthRenderer renderer(world, options);
  const PinholeCamera camera = renderer.camera();
  std::vector<float> depth;
  const double h = 1.5;
  renderer.render(bodyPose({0, 0, h}, 0.4), depth);
  const int cu = camera.width / 2;
  EXPECT_NEAR(pixel(depth, camera, cu, camera.height / 2), h / std::sin(deg(30)), 1e-5);
  int checked = 0;
  for (int v = 0; v < camera.height; ++v) {
    const double below_axis = std::atan((v - camera.cy) / camera.fy);
    const double below_horizon = deg(30) + below_axis;
    const double range = h / std::sin(below_horizon);
    const bool seen = below_horizon > 0 && range <= options.max_range;
    const double expected = seen ? range * std::cos(below_axis) : 0.0;
    EXPECT_NEAR(pixel(depth, camera, cu, v), expected, 1e-5 * (1 + expected)) << "row " << v;
    checked += expected > 0;
  }
  EXPECT_GT(checked, 50);
}

TEST(DepthRenderer, CylinderStraightAheadAtDistanceMinusRadius) {
  World world = emptyWorld({0, 0, 0}, {30, 30, 5});
  world.cylinders.push_back({8, 5, 0.4, 3.0});
  DepthCameraOptions options;
  options.width = 161;
  options.height = 121;
  const DepthRenderer renderer(world, options);
  std::vector<float> depth;
  renderer.render(bodyPose({5, 5, 1.5}, 0), depth);
  EXPECT_NEAR(pixel(depth, renderer.camera(), 80, 60), 3.0 - 0.4, 1e-5);
}

TEST(DepthRenderer, MountPositionAndPitchAreApplied) {
  World world = emptyWorld({0, -50, 0}, {20, 50, 5});
  DepthCameraOptions options;
  options.width = 161;
  options.height = 121;
  options.position_in_body = Eigen::Vector3d(0.5, 0, 0.2);
  const DepthRenderer renderer(world, options);
  const Pose mount = renderer.cameraInBody();
  EXPECT_LT((mount.position - options.position_in_body).norm(), 1e-12);
  std::vector<float> depth;
  renderer.render(bodyPose({13, 0, 1.3}, 0), depth);
  EXPECT_NEAR(pixel(depth, renderer.camera(), 80, 60), 6.5, 1e-5);
}

TEST(DepthRenderer, ReturnsBeyondMaxRangeAreZero) {
  const World world = emptyWorld({0, -100, 0}, {30, 100, 5});
  DepthCameraOptions options;
  options.width = 161;
  options.height = 121;
  const Pose body = bodyPose({5, 0, 1.5}, 0);  // the wall is 25 m ahead
  std::vector<float> depth;
  DepthRenderer(world, options).render(body, depth);
  for (int u = 0; u < 161; ++u) EXPECT_EQ(depth[60 * 161 + u], 0.0f) << u;  // the level row
  options.max_range = 30;
  DepthRenderer(world, options).render(body, depth);
  EXPECT_NEAR(depth[60 * 161 + 80], 25.0, 1e-4);
}

TEST(DepthRenderer, NoiseIsDeterministicPerSeedAndScalesWithDepthSquared) {
  const World world = randomForest(6, 60, 30);
  DepthCameraOptions options;
  const Pose body = bodyPose({2, 15, 1.5}, 0.1);
  std::vector<float> truth, same_truth;
  const DepthRenderer noiseless(world, options);
  noiseless.render(body, truth);
  noiseless.render(body, same_truth, 1234);
  EXPECT_EQ(truth, same_truth);  // noise off: the seed changes nothing

  options.noise_stddev_at_1m = 0.01;
  const DepthRenderer noisy(world, options);
  std::vector<float> a, b, c;
  noisy.render(body, a, 77);
  noisy.render(body, b, 77);
  noisy.render(body, c, 78);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  double sum = 0, sum_sq = 0;
  int n = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    EXPECT_EQ(truth[i] == 0, a[i] == 0);
    if (truth[i] == 0) continue;
    const double z = truth[i];
    const double normalized = (a[i] - z) / (z * z);
    sum += normalized;
    sum_sq += normalized * normalized;
    ++n;
  }
  ASSERT_GT(n, 30000);
  const double mean = sum / n;
  const double stddev = std::sqrt(sum_sq / n - mean * mean);
  EXPECT_NEAR(stddev, 0.01, 0.001);
  EXPECT_NEAR(mean, 0, 0.0005);
}

TEST(DepthRenderer, RejectsImpossibleOptions) {
  const World world = randomForest(1, 1, 10);
  DepthCameraOptions options;
  options.width = 0;
  EXPECT_THROW(DepthRenderer(world, options), std::invalid_argument);
  options = {};
  options.horizontal_fov_deg = 180;
  EXPECT_THROW(DepthRenderer(world, options), std::invalid_argument);
  options = {};
  options.max_range = 0;
  EXPECT_THROW(DepthRenderer(world, options), std::invalid_argument);
  options = {};
  options.noise_stddev_at_1m = -1;
  EXPECT_THROW(DepthRenderer(world, options), std::invalid_argument);
}

// --- Stereo ---

World stereoForest() {
  World world = randomForest(8, 200, 30);
  world.cylinders.erase(std::remove_if(world.cylinders.begin(), world.cylinders.end(),
                                       [](const Cylinder& c) {
                                         return std::hypot(c.x - 3, c.y - 15) < c.radius + 1.0;
                                       }),
                        world.cylinders.end());
  return world;
}

double interpolateRow(const std::vector<uint8_t>& image, const PinholeCamera& camera, double u,
                      int v) {
  const int u0 = static_cast<int>(std::floor(u));
  const double a = u - u0;
  return (1 - a) * image[v * camera.width + u0] + a * image[v * camera.width + u0 + 1];
}

TEST(StereoRenderer, RightCameraSitsOneBaselineAlongTheLeftOpticalX) {
  const StereoRenderer renderer(stereoForest(), StereoCameraOptions{});
  const Pose left_T_right = renderer.leftInBody().inverse() * renderer.rightInBody();
  EXPECT_LT((left_T_right.position - Eigen::Vector3d(0.11, 0, 0)).norm(), 1e-12);
  EXPECT_LT(left_T_right.orientation.angularDistance(Eigen::Quaterniond::Identity()), 1e-12);
  EXPECT_EQ(renderer.baseline(), 0.11);
}

TEST(StereoRenderer, BothCamerasSeeTheSameTextureAtTheSamePoint) {
  const World world = stereoForest();
  StereoCameraOptions options;
  options.pitch_down_deg = 10;
  const StereoRenderer renderer(world, options);
  const PinholeCamera camera = renderer.camera();
  const Pose body = bodyPose({3, 15, 1.5}, 0.05);
  const Pose world_T_left = body * renderer.leftInBody();
  const Pose world_T_right = body * renderer.rightInBody();
  std::vector<uint8_t> left, right;
  renderer.render(body, left, right);

  const RayCaster caster(world);
  const RayCaster::View left_view = caster.view(world_T_left.position, options.max_range);
  const RayCaster::View right_view = caster.view(world_T_right.position, options.max_range);
  const double b_fx = options.baseline * camera.fx;
  int visible = 0;
  double error_sum = 0, shifted_error_sum = 0;
  for (int v = 2; v < camera.height - 2; v += 7) {
    for (int u = 2; u < camera.width - 2; u += 7) {
      const Eigen::Vector3d ray_left = camera.backProject(u, v, 1.0);
      SurfaceHit hit_left;
      const double range_left =
          left_view.cast(world_T_left.orientation * ray_left.normalized(), &hit_left);
      if (range_left == RayCaster::kNoHit) {
        EXPECT_EQ(left[v * camera.width + u], StereoRenderer::kSkyIntensity);
        continue;
      }
      const double z = range_left / ray_left.norm();
      // The point projects onto the same row of the right image, fx * B / z to the left.
      const Eigen::Vector3d in_right = world_T_right.inverse().transform(hit_left.point);
      const auto uv_right = camera.project(in_right);
      ASSERT_TRUE(uv_right.has_value());
      EXPECT_NEAR(uv_right->y(), v, 1e-6);
      EXPECT_NEAR(uv_right->x(), u - b_fx / z, 1e-6);
      if (uv_right->x() < 1 || uv_right->x() > camera.width - 5) continue;
      // Visible from the right camera: its ray towards the point hits that very point.
      const Eigen::Vector3d to_point = hit_left.point - world_T_right.position;
      SurfaceHit hit_right;
      const double range_right = right_view.cast(to_point.normalized(), &hit_right);
      if (!(std::abs(range_right - to_point.norm()) <= 1e-6 * to_point.norm())) continue;
      ++visible;
      EXPECT_EQ(hit_right.surface, hit_left.surface);
      EXPECT_EQ(hit_right.index, hit_left.index);
      const double footprint = range_left / camera.fx;
      EXPECT_NEAR(renderer.surfaceIntensity(hit_left, footprint),
                  renderer.surfaceIntensity(hit_right, footprint), 1e-6);
      // The rendered right image agrees at the matching position, and much better than a few
      // pixels off it (sampling makes single pixels differ a little).
      const double gray_left = left[v * camera.width + u];
      error_sum += std::abs(interpolateRow(right, camera, uv_right->x(), v) - gray_left);
      shifted_error_sum +=
          std::abs(interpolateRow(right, camera, uv_right->x() + 3, v) - gray_left);
    }
  }
  ASSERT_GT(visible, 3000);
  const double mean_error = error_sum / visible;
  const double mean_shifted_error = shifted_error_sum / visible;
  EXPECT_LT(mean_error, 2.0);
  EXPECT_LT(mean_error, 0.2 * mean_shifted_error);
}

// The two cameras render side by side on two threads: the right image is the one the left camera
// renders from the right camera's pose, pixel for pixel.
TEST(StereoRenderer, TheRightImageIsTheLeftCamerasFromTheRightPose) {
  const StereoRenderer renderer(stereoForest(), StereoCameraOptions{});
  for (const Pose& body : {bodyPose({3, 15, 1.5}, 0.05), bodyPose({8, 4, 2.0}, -0.7)}) {
    std::vector<uint8_t> left, right, moved_left, moved_right;
    renderer.render(body, left, right);
    const Pose moved = body * renderer.rightInBody() * renderer.leftInBody().inverse();
    renderer.render(moved, moved_left, moved_right);
    EXPECT_TRUE(moved_left == right);
    EXPECT_FALSE(left == right);
  }
}

TEST(StereoRenderer, MostSurfacePixelsAreTextured) {
  const World world = stereoForest();
  const StereoRenderer renderer(world, StereoCameraOptions{});
  const PinholeCamera camera = renderer.camera();
  const Pose body = bodyPose({3, 15, 1.5}, -0.1);
  std::vector<uint8_t> left, right;
  renderer.render(body, left, right);
  // Which pixels see a surface, from the same caster.
  const Pose world_T_left = body * renderer.leftInBody();
  const RayCaster::View view = RayCaster(world).view(world_T_left.position, 20);
  std::vector<bool> hit(left.size());
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d dir =
          world_T_left.orientation * camera.backProject(u, v, 1).normalized();
      hit[v * camera.width + u] = view.cast(dir) != RayCaster::kNoHit;
    }
  }
  int surface = 0, textured = 0;
  for (int v = 1; v < camera.height - 1; ++v) {
    for (int u = 1; u < camera.width - 1; ++u) {
      const int i = v * camera.width + u;
      if (!hit[i]) continue;
      ++surface;
      const int gx = std::abs(left[i + 1] - left[i - 1]);
      const int gy = std::abs(left[i + camera.width] - left[i - camera.width]);
      textured += std::max(gx, gy) >= 3;
    }
  }
  ASSERT_GT(surface, camera.width * camera.height / 2);
  EXPECT_GT(textured, 0.8 * surface) << textured << " of " << surface;
}

TEST(StereoRenderer, TextureIsFilteredToThePixelFootprint) {
  // Over many ground points, the texture keeps the ground's mean gray level at every footprint
  // and loses contrast as the footprint grows; a footprint as large as the texture's period
  // averages it all away.
  const StereoRenderer renderer(stereoForest(), StereoCameraOptions{});
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> xy(0, 30);
  std::vector<Eigen::Vector3d> points(4000);
  for (Eigen::Vector3d& p : points) p = Eigen::Vector3d(xy(rng), xy(rng), 0);
  double previous_stddev = kInf;
  for (double footprint : {0.01, 0.03, 0.1, 0.3, 1.0}) {
    double sum = 0, sum_sq = 0;
    for (const Eigen::Vector3d& p : points) {
      const double gray =
          renderer.surfaceIntensity({SurfaceHit::Surface::kGround, -1, p}, footprint);
      sum += gray;
      sum_sq += gray * gray;
    }
    const double mean = sum / points.size();
    const double stddev = std::sqrt(sum_sq / points.size() - mean * mean);
    EXPECT_NEAR(mean, 105, 3) << footprint;
    EXPECT_LT(stddev, previous_stddev) << footprint;
    previous_stddev = stddev;
  }
  EXPECT_GT(previous_stddev, 0.5);
  const double flat = renderer.surfaceIntensity({SurfaceHit::Surface::kGround, -1, points[0]}, 20);
  for (const Eigen::Vector3d& p : points) {
    ASSERT_NEAR(renderer.surfaceIntensity({SurfaceHit::Surface::kGround, -1, p}, 20), flat, 1e-4);
  }
  EXPECT_NEAR(flat, 105, 3);
  EXPECT_THROW(renderer.surfaceIntensity({}, 0.01), std::invalid_argument);
}

// The texture changes continuously with the footprint, also where the mip level changes: the two
// cameras see a surface point with slightly different footprints, and a step where the level
// switches would show in one image and not in the other. Over ground points and footprints 1 %
// apart from 1 cm to 1 m, no step exceeds a few gray levels (filtering from the nearer level
// alone steps by up to 30).
TEST(StereoRenderer, TextureChangesSmoothlyWithTheFootprint) {
  const StereoRenderer renderer(stereoForest(), StereoCameraOptions{});
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> xy(0, 30);
  double largest_step = 0, total_change = 0;
  for (int i = 0; i < 500; ++i) {
    const SurfaceHit hit{SurfaceHit::Surface::kGround, -1, Eigen::Vector3d(xy(rng), xy(rng), 0)};
    double previous = renderer.surfaceIntensity(hit, 0.01);
    for (double footprint = 0.0101; footprint < 1; footprint *= 1.01) {
      const double gray = renderer.surfaceIntensity(hit, footprint);
      largest_step = std::max(largest_step, std::abs(gray - previous));
      total_change += std::abs(gray - previous);
      previous = gray;
    }
  }
  // Measured: 2.5 (trilinear everywhere: 0.6, the nearer level alone: 32); the texture does
  // change over the sweep, by 23000 in all.
  EXPECT_LT(largest_step, 5.0);
  EXPECT_GT(total_change, 5000);
}

// The texture at the centre of a finest-level texel is the value noise it is made of (seven
// octaves of smoothstep-interpolated lattice values drawn by the lowbias32 hash, cells of 2 to 128
// texels of 1 cm, 60 gray levels per unit of noise, the ground's mean 105 and its own offset in
// the tile), here as a function of the point: the int16_t texels keep it within 1/128 gray level.
TEST(StereoRenderer, TextureIsTheValueNoiseWithinItsQuantization) {
  const auto lowbias32 = [](uint32_t h) {
    h = (h ^ (h >> 16)) * 0x7feb352dU;
    h = (h ^ (h >> 15)) * 0x846ca68bU;
    return h ^ (h >> 16);
  };
  const auto smooth = [](double t) { return t * t * (3 - 2 * t); };
  // The value noise at tile coordinates (x, y) [texels].
  const auto noise = [&](double x, double y) {
    double sum = 0;
    for (uint32_t octave = 0; octave < 7; ++octave) {
      const double cell = 2 << octave;
      const uint32_t cells = 1024 / (2 << octave);
      const double gx = x / cell, gy = y / cell;
      const uint32_t cx = static_cast<uint32_t>(gx), cy = static_cast<uint32_t>(gy);
      const auto lattice = [&](uint32_t i, uint32_t j) {
        return lowbias32((octave << 20) | ((j % cells) << 10) | (i % cells)) * 0x1.0p-32 - 0.5;
      };
      const double sx = smooth(gx - cx), sy = smooth(gy - cy);
      const double bottom = lattice(cx, cy) + sx * (lattice(cx + 1, cy) - lattice(cx, cy));
      const double top = lattice(cx, cy + 1) + sx * (lattice(cx + 1, cy + 1) - lattice(cx, cy + 1));
      sum += bottom + sy * (top - bottom);
    }
    return sum;
  };
  const StereoRenderer renderer(stereoForest(), StereoCameraOptions{});
  // The ground's offset in the tile, from its surface kind (1) and index (-1).
  const uint32_t seed = lowbias32((1u << 24) ^ 0xffffffffU);
  const double offset_x = seed & 1023, offset_y = (seed >> 10) & 1023;
  std::mt19937_64 rng(31);
  std::uniform_int_distribution<int> texel(0, 1023);
  double largest_error = 0;
  for (int i = 0; i < 2000; ++i) {
    const double x = texel(rng) + 0.5, y = texel(rng) + 0.5;
    const Eigen::Vector3d p((x - offset_x) / 100, (y - offset_y) / 100, 0);
    const double gray = renderer.surfaceIntensity({SurfaceHit::Surface::kGround, -1, p}, 0.001);
    largest_error = std::max(largest_error, std::abs(gray - (105 + 60 * noise(x, y))));
  }
  EXPECT_LT(largest_error, 1.0 / 128 + 1e-3);
}

TEST(StereoRenderer, RenderingIsDeterministic) {
  const StereoRenderer renderer(stereoForest(), StereoCameraOptions{});
  const Pose body = bodyPose({3, 15, 1.5}, 0.3);
  std::vector<uint8_t> left_a, right_a, left_b, right_b;
  renderer.render(body, left_a, right_a);
  renderer.render(body, left_b, right_b);
  EXPECT_EQ(left_a, left_b);
  EXPECT_EQ(right_a, right_b);
  EXPECT_NE(left_a, right_a);
  ASSERT_EQ(left_a.size(), 752u * 480u);

  std::vector<float> depth_a, depth_b;
  const DepthRenderer depth(stereoForest(), DepthCameraOptions{});
  depth.render(body, depth_a);
  depth.render(body, depth_b);
  EXPECT_EQ(depth_a, depth_b);
}

// The numbers of an opencv-matrix node `name` in the YAML text.
std::vector<double> matrixData(const std::string& yaml, const std::string& name) {
  const size_t node = yaml.find("\n" + name + ": !!opencv-matrix");
  if (node == std::string::npos) return {};
  const size_t open = yaml.find('[', node);
  const size_t close = yaml.find(']', open);
  std::string data = yaml.substr(open + 1, close - open - 1);
  std::replace(data.begin(), data.end(), ',', ' ');
  std::istringstream in(data);
  std::vector<double> values;
  for (double x; in >> x;) values.push_back(x);
  return values;
}

TEST(StereoRenderer, CalibrationYamlDescribesTheRectifiedPair) {
  StereoCameraOptions options;
  options.baseline = 0.12;
  const StereoRenderer renderer(stereoForest(), options);
  const std::string yaml = renderer.calibrationYaml("sim_stereo");
  EXPECT_EQ(yaml.rfind("%YAML:1.0\n", 0), 0u);
  EXPECT_NE(yaml.find("calibration_id: \"sim_stereo\""), std::string::npos);
  EXPECT_NE(yaml.find("image_width: 752\n"), std::string::npos);
  EXPECT_NE(yaml.find("image_height: 480\n"), std::string::npos);
  const double fx = 376.0;  // 752 / 2 / tan(45°)
  for (const char* name : {"camera_matrix_left", "camera_matrix_right"}) {
    const std::vector<double> k = matrixData(yaml, name);
    ASSERT_EQ(k.size(), 9u) << name;
    EXPECT_NEAR(k[0], fx, 1e-9);
    EXPECT_NEAR(k[2], 375.5, 1e-12);
    EXPECT_NEAR(k[4], fx, 1e-9);
    EXPECT_NEAR(k[5], 239.5, 1e-12);
    EXPECT_EQ(k[8], 1.0);
  }
  EXPECT_EQ(matrixData(yaml, "distortion_left"), std::vector<double>(5, 0.0));
  EXPECT_EQ(matrixData(yaml, "distortion_right"), std::vector<double>(5, 0.0));
  EXPECT_EQ(matrixData(yaml, "R"), (std::vector<double>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
  EXPECT_EQ(matrixData(yaml, "T"), (std::vector<double>{-0.12, 0, 0}));
  EXPECT_THROW(renderer.calibrationYaml(""), std::invalid_argument);
  EXPECT_THROW(renderer.calibrationYaml("a\"b"), std::invalid_argument);
}

}  // namespace
}  // namespace thicket::sim
