// thicket-mapper's node in a memq:// composite: frames wait for their pose, mirrors follow the
// map through deltas and snapshots, bad input is refused with a reason and never reaches the map.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include <gtest/gtest.h>

#include <thicket/map_update_t.hpp>
#include <thicket/module_timing_t.hpp>

#include "mapper_node.h"
#include "thicket/common/depth_image.h"
#include "thicket/common/loop.h"
#include "thicket/common/map_update.h"
#include "thicket/mapper/map_io.h"
#include "thicket/sim/render.h"

namespace thicket::mapper {
namespace {

sim::World smallForest() {
  sim::World world;
  world.bounds_min = Eigen::Vector3d(0, 0, 0);
  world.bounds_max = Eigen::Vector3d(20, 12, 5);
  world.cylinders = {{6, 5, 0.4, 4}, {8, 8, 0.3, 3}, {10, 4, 0.5, 5}, {12, 7, 0.3, 2.5}};
  return world;
}

Pose bodyAt(double s) {
  return Pose::fromYaw(Eigen::Vector3d(1 + s, 6, 1.5), 0.0);
}

// A depth frame seen from bodyAt(s), time-stamped utime.
depth_image_t frameAt(const sim::DepthRenderer& renderer, double s, int64_t utime) {
  return encodeDepthImage(renderer.renderImage(bodyAt(s), utime));
}

odometry_t poseMsg(int64_t utime, const Pose& pose) {
  odometry_t msg{};
  msg.utime = utime;
  poseToArrays(pose, msg.position, msg.orientation);
  msg.quality = odometry_t::QUALITY_GOOD;
  return msg;
}

// Everything a planner-side observer sees: mirrors of both layers (asking for snapshots when they
// need them) and the mapper's statuses.
class Observer : public Node {
 public:
  explicit Observer(lcm::LCM& lcm) : Node("observer", lcm) {
    subscribe<map_update_t>(
        "MAP_TSDF", [this](const map_update_t& m, const MessageInfo&) { onUpdate(tsdf, m); }, 1000);
    subscribe<map_update_t>(
        "MAP_ESDF", [this](const map_update_t& m, const MessageInfo&) { onUpdate(esdf, m); }, 1000);
    subscribe<mapper_status_t>(
        "MAPPER_STATUS",
        [this](const mapper_status_t& m, const MessageInfo&) { statuses.push_back(m); }, 1000);
    subscribe<module_timing_t>(
        "MODULE_TIMING",
        [this](const module_timing_t& m, const MessageInfo&) { timings.push_back(m); }, 1000);
  }
  template <class Voxel>
  void onUpdate(MapMirror<Voxel>& mirror, const map_update_t& msg) {
    if (mirror.apply(msg).outcome == MapMirror<Voxel>::Outcome::kNeedSnapshot &&
        !requested[msg.layer]) {
      requested[msg.layer] = true;  // once; the test checks that one request heals it
      publish("MAP_REQUEST", mirror.request(msg.utime, "observer"));
    }
  }
  const mapper_status_t* last(int8_t result) const {
    for (auto it = statuses.rbegin(); it != statuses.rend(); ++it) {
      if (it->result == result) return &*it;
    }
    return nullptr;
  }
  MapMirror<TsdfVoxel> tsdf;
  MapMirror<EsdfVoxel> esdf;
  bool requested[2] = {false, false};
  std::vector<mapper_status_t> statuses;
  std::vector<module_timing_t> timings;
};

MapperNodeOptions nodeOptions() {
  MapperNodeOptions options;
  options.map_id = 42;
  return options;
}

sim::DepthCameraOptions smallCamera() {
  sim::DepthCameraOptions camera;
  camera.width = 160;
  camera.height = 120;
  return camera;
}

// The mapper with a sensor rig and an observer on one memq:// LCM.
class MapperNodeTest : public ::testing::Test {
 protected:
  lcm::LCM lcm{"memq://"};
  Loop loop{lcm};
  const sim::DepthRenderer renderer{smallForest(), smallCamera()};
  MapperNode mapper{lcm, nodeOptions(), 42};
  Observer observer{lcm};
  Node sensors{"sensors", lcm};
};

TEST_F(MapperNodeTest, FramesWaitForTheirPoseAndMirrorsFollowTheMap) {
  // The frame at 1 s arrives before any pose: it waits.
  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 0, 1'000'000));
  loop.drain();
  ASSERT_NE(observer.last(mapper_status_t::RESULT_PENDING), nullptr);
  EXPECT_EQ(mapper.mapper().revision(), 0);
  // Poses at 20 Hz up to 0.95 s are not enough; the one at 1.0 s is.
  for (int64_t t = 0; t <= 950'000; t += 50'000) {
    sensors.publish("STATE_ESTIMATE", poseMsg(t, bodyAt(t * 1e-6)));
  }
  loop.drain();
  EXPECT_EQ(mapper.mapper().revision(), 0);
  sensors.publish("STATE_ESTIMATE", poseMsg(1'000'000, bodyAt(1.0)));
  loop.drain();
  EXPECT_EQ(mapper.mapper().revision(), 1);
  ASSERT_NE(observer.last(mapper_status_t::RESULT_INTEGRATED), nullptr);
  EXPECT_EQ(observer.last(mapper_status_t::RESULT_INTEGRATED)->utime, 1'000'000);

  // More frames, each after its pose; the mirrors joined at revision 1 without a snapshot, asked
  // for one, and follow every delta since.
  for (int k = 2; k <= 6; ++k) {
    const int64_t t = k * 1'000'000;
    for (int64_t p = t - 950'000; p <= t; p += 50'000) {
      sensors.publish("STATE_ESTIMATE", poseMsg(p, bodyAt(p * 1e-6)));
    }
    sensors.publish("CAMERA_DEPTH", frameAt(renderer, k, t));
    loop.drain();
  }
  EXPECT_EQ(mapper.mapper().revision(), 6);
  ASSERT_NE(observer.tsdf.layer(), nullptr);
  ASSERT_NE(observer.esdf.layer(), nullptr);
  EXPECT_EQ(observer.tsdf.revision(), 6);
  EXPECT_EQ(observer.esdf.revision(), 6);
  EXPECT_TRUE(identicalLayers(*observer.tsdf.layer(), mapper.mapper().tsdf()));
  EXPECT_TRUE(identicalLayers(*observer.esdf.layer(), mapper.mapper().esdf()));
  EXPECT_GT(mapper.mapper().esdf().numBlocks(), 0u);
  ASSERT_NE(observer.last(mapper_status_t::RESULT_SNAPSHOT_SENT), nullptr);
  ASSERT_EQ(observer.timings.size(), 6u);
  EXPECT_EQ(observer.timings.back().stages,
            (std::vector<std::string>{"tsdf_insert", "esdf_update"}));
  EXPECT_EQ(observer.timings.back().sequence, 6);
  EXPECT_EQ(mapper.badMessageCount(), 0);
}

// One frame or one pose stamped 11 days ahead wedged the mapper for the rest of the mission
// ("not after the previous"). Now each costs at most ten inputs, and mapping resumes.
TEST_F(MapperNodeTest, AFarFutureFrameOrPoseCostsAtMostTenInputsThenMappingResumes) {
  constexpr int64_t kFuture = 1'000'000'000'000;
  int64_t next_pose = 0;
  const auto posesUpTo = [&](int64_t t) {
    for (; next_pose <= t; next_pose += 50'000) {
      sensors.publish("STATE_ESTIMATE", poseMsg(next_pose, bodyAt(next_pose * 1e-6)));
    }
  };
  // Twelve frames 0.1 s apart after `start`, each after its poses; statuses from here on.
  const auto flyTwelveFramesAfter = [&](int64_t start) {
    loop.drain();
    observer.statuses.clear();
    for (int k = 1; k <= 12; ++k) {
      const int64_t t = start + k * 100'000;
      posesUpTo(t);
      sensors.publish("CAMERA_DEPTH", frameAt(renderer, t * 1e-6, t));
      loop.drain();
    }
  };
  const auto count = [&](int8_t result) {
    return std::count_if(observer.statuses.begin(), observer.statuses.end(),
                         [&](const mapper_status_t& s) { return s.result == result; });
  };
  posesUpTo(1'000'000);
  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 0.5, 500'000));
  loop.drain();
  ASSERT_EQ(mapper.mapper().revision(), 1);

  // A frame from the future: it waits for a pose that never comes, and later frames are earlier.
  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 0.6, kFuture));
  flyTwelveFramesAfter(1'000'000);
  EXPECT_EQ(count(mapper_status_t::RESULT_REANCHORED), 1);
  const mapper_status_t* reanchored = observer.last(mapper_status_t::RESULT_REANCHORED);
  ASSERT_NE(reanchored, nullptr);
  EXPECT_EQ(reanchored->utime, 2'000'000);
  EXPECT_NE(reanchored->reason.find("frames: clock reset: 10 consecutive frames"),
            std::string::npos)
      << reanchored->reason;
  // 9 refused, the future frame dropped, frames 10-12 integrated.
  EXPECT_EQ(count(mapper_status_t::RESULT_REFUSED), 10);
  EXPECT_EQ(count(mapper_status_t::RESULT_INTEGRATED), 3);
  EXPECT_EQ(mapper.mapper().revision(), 4);
  EXPECT_EQ(mapper.mapper().pendingFrames(), 0u);

  // A pose from the future: later poses are earlier, and frames between find no pose to pair.
  sensors.publish("STATE_ESTIMATE", poseMsg(kFuture, bodyAt(2.2)));
  flyTwelveFramesAfter(2'200'000);
  reanchored = observer.last(mapper_status_t::RESULT_REANCHORED);
  ASSERT_NE(reanchored, nullptr);
  EXPECT_NE(reanchored->reason.find("poses: clock reset: 10 consecutive poses"), std::string::npos)
      << reanchored->reason;
  EXPECT_GT(mapper.mapper().revision(), 4 + 3);  // mapping resumed within the twelve frames
  EXPECT_EQ(mapper.mapper().pendingFrames(), 0u);
}

TEST_F(MapperNodeTest, BadInputIsRefusedWithAReasonAndNeverReachesTheMap) {
  for (int64_t t = 0; t <= 1'000'000; t += 50'000) {
    sensors.publish("STATE_ESTIMATE", poseMsg(t, bodyAt(t * 1e-6)));
  }
  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 0.5, 500'000));
  loop.drain();
  ASSERT_EQ(mapper.mapper().revision(), 1);
  const TsdfLayer tsdf_before = mapper.mapper().tsdf();

  const auto expectRefused = [&](const std::string& what, const std::string& reason_part) {
    loop.drain();
    const mapper_status_t* status = observer.last(mapper_status_t::RESULT_REFUSED);
    ASSERT_NE(status, nullptr) << what;
    EXPECT_NE(status->reason.find(reason_part), std::string::npos)
        << what << ": the reason was '" << status->reason << "'";
    observer.statuses.clear();
    EXPECT_EQ(mapper.mapper().revision(), 1) << what;
    EXPECT_TRUE(identicalLayers(mapper.mapper().tsdf(), tsdf_before)) << what;
  };

  depth_image_t negative_depth = frameAt(renderer, 0.6, 600'000);
  {
    DepthImage image = *decodeDepthImage(negative_depth);
    image.depth[100] = -1.0f;
    negative_depth =
        encodeDepthImage(image, depth_image_t::DEPTH_FLOAT32_M, depth_image_t::COMPRESSION_NONE);
  }
  sensors.publish("CAMERA_DEPTH", negative_depth);
  expectRefused("negative depth", "1 pixels are negative");

  depth_image_t wrong_size = frameAt(renderer, 0.6, 600'000);
  wrong_size.width = 10;
  sensors.publish("CAMERA_DEPTH", wrong_size);
  expectRefused("wrong size", "bad depth frame");

  depth_image_t unknown_encoding = frameAt(renderer, 0.6, 600'000);
  unknown_encoding.depth_encoding = 9;
  sensors.publish("CAMERA_DEPTH", unknown_encoding);
  expectRefused("unknown encoding", "encoding");

  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 0.4, 400'000));
  expectRefused("time going backwards", "is before the previous frame's");

  odometry_t nan_pose = poseMsg(1'050'000, bodyAt(1.05));
  nan_pose.position[1] = NAN;
  sensors.publish("STATE_ESTIMATE", nan_pose);
  expectRefused("NaN pose", "pose refused");

  odometry_t not_unit = poseMsg(1'050'000, bodyAt(1.05));
  not_unit.orientation[0] = 0.5;
  sensors.publish("STATE_ESTIMATE", not_unit);
  expectRefused("non-unit quaternion", "pose refused");

  sensors.publish("STATE_ESTIMATE", poseMsg(900'000, bodyAt(0.9)));
  expectRefused("pose time going backwards",
                "refused: utime 0.900000 s is before the previous pose's");

  odometry_t lost = poseMsg(1'050'000, bodyAt(1.05));
  lost.quality = odometry_t::QUALITY_LOST;
  sensors.publish("STATE_ESTIMATE", lost);
  expectRefused("lost estimator", "lost");

  // The pose stream stops for 2 s: a frame inside the gap can never get a pose.
  sensors.publish("STATE_ESTIMATE", poseMsg(3'000'000, bodyAt(3.0)));
  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 2.0, 2'000'000));
  expectRefused("frame inside a pose gap", "no pose at the frame's time");

  map_request_t bad_layer{};
  bad_layer.layer = 5;
  sensors.publish("MAP_REQUEST", bad_layer);
  expectRefused("unknown layer", "unknown layer");

  // After all that, a good frame still integrates.
  sensors.publish("STATE_ESTIMATE", poseMsg(3'050'000, bodyAt(3.05)));
  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 3.02, 3'020'000));
  loop.drain();
  EXPECT_EQ(mapper.mapper().revision(), 2);
  EXPECT_EQ(mapper.framesRefused(), 5);
  EXPECT_EQ(mapper.mapper().framesRefused(), 2);  // the others never decoded
}

// A flood of snapshot requests at one revision gets two snapshots per layer (one for every mirror
// that asked, one repeat for a mirror that lost it) and one refusal status; the next revision is
// served again.
TEST_F(MapperNodeTest, SnapshotRequestsAreLimitedPerRevision) {
  sensors.publish("STATE_ESTIMATE", poseMsg(1'000'000, bodyAt(0)));
  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 0, 1'000'000));
  loop.drain();
  ASSERT_EQ(mapper.mapper().revision(), 1);
  int snapshots = 0;
  Node counter("counter", lcm);
  counter.subscribe<map_update_t>(
      "MAP_ESDF",
      [&](const map_update_t& m, const MessageInfo&) {
        if (m.full_snapshot && m.part_index == 0) ++snapshots;
      },
      1000);
  map_request_t request{};
  request.layer = map_update_t::LAYER_ESDF;
  request.requester = "flood";
  const size_t statuses_before = observer.statuses.size();
  for (int i = 0; i < 100; ++i) {
    request.utime = 1'000'000 + i;
    sensors.publish("MAP_REQUEST", request);
    loop.drain();
  }
  // The observer's mirror asked for revision 1 when it started: the flood gets the repeat only.
  EXPECT_EQ(snapshots, 1);
  EXPECT_EQ(mapper.requestsRefused(), 99);
  int refusals = 0;
  for (size_t i = statuses_before; i < observer.statuses.size(); ++i) {
    if (observer.statuses[i].result == mapper_status_t::RESULT_REFUSED) {
      ++refusals;
      EXPECT_NE(observer.statuses[i].reason.find("went out 2 times already"), std::string::npos)
          << observer.statuses[i].reason;
    }
  }
  EXPECT_EQ(refusals, 1);

  sensors.publish("STATE_ESTIMATE", poseMsg(1'500'000, bodyAt(0.5)));
  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 0.5, 1'500'000));
  loop.drain();
  sensors.publish("MAP_REQUEST", request);
  loop.drain();
  EXPECT_EQ(snapshots, 2);  // revision 2's
}

// A map saved when a node stops is where the next node, told to load it, continues: same layers
// and revision, mirrors of the new map catch up through a snapshot, and the first frame's ESDF
// equals one computed from scratch on the continued TSDF.
TEST_F(MapperNodeTest, SavedMapsAreContinuedByTheNextRun) {
  for (int k = 0; k < 3; ++k) {
    const int64_t t = 1'000'000 + k * 500'000;
    sensors.publish("STATE_ESTIMATE", poseMsg(t, bodyAt(k * 0.5)));
    sensors.publish("CAMERA_DEPTH", frameAt(renderer, k * 0.5, t));
    loop.drain();
  }
  ASSERT_EQ(mapper.mapper().revision(), 3);
  EXPECT_EQ(mapper.saveIfConfigured(), "");  // not configured: nothing written

  const std::string path = ::testing::TempDir() + "/mapper_node_continued.map";
  MapperNodeOptions saving = nodeOptions();
  saving.save_map = path;
  {
    MapperNode stopping(lcm, saving, 42);
    EXPECT_EQ(stopping.saveIfConfigured(), path);
    const auto empty = loadMap(path);
    ASSERT_TRUE(static_cast<bool>(empty)) << empty.error();
    EXPECT_EQ(empty->revision, 0);
    EXPECT_EQ(empty->tsdf.numBlocks(), 0u);
  }
  saveMap(path, mapper.mapper().tsdf(), mapper.mapper().esdf(), {42, 3, 2'000'000, {}});

  MapperNodeOptions loading = nodeOptions();
  loading.map_id = 43;
  loading.load_map = path;
  lcm::LCM lcm2("memq://");
  Loop loop2(lcm2);
  MapperNode next(lcm2, loading, 43);
  Observer observer2(lcm2);
  Node sensors2("sensors", lcm2);
  EXPECT_EQ(next.mapper().revision(), 3);
  EXPECT_TRUE(identicalLayers(next.mapper().tsdf(), mapper.mapper().tsdf()));
  EXPECT_TRUE(identicalLayers(next.mapper().esdf(), mapper.mapper().esdf()));

  // The next flight's clock starts over; its first frame continues the map at revision 4.
  sensors2.publish("STATE_ESTIMATE", poseMsg(100'000, bodyAt(1.5)));
  sensors2.publish("CAMERA_DEPTH", frameAt(renderer, 1.5, 100'000));
  loop2.drain();
  ASSERT_EQ(next.mapper().revision(), 4);
  ASSERT_NE(observer2.tsdf.layer(), nullptr);
  EXPECT_EQ(observer2.tsdf.revision(), 4);
  EXPECT_EQ(observer2.esdf.revision(), 4);
  EXPECT_TRUE(identicalLayers(*observer2.tsdf.layer(), next.mapper().tsdf()));
  EXPECT_TRUE(identicalLayers(*observer2.esdf.layer(), next.mapper().esdf()));
  for (const BlockIndex& b : mapper.mapper().tsdf().blockIndices()) {
    EXPECT_NE(next.mapper().tsdf().block(b), nullptr);
  }
  EXPECT_FALSE(identicalLayers(next.mapper().tsdf(), mapper.mapper().tsdf()));
  EsdfIntegrator scratch(next.mapper().options().esdf);
  scratch.setInitialPosition(bodyAt(1.5).position);
  EsdfLayer expected(next.mapper().options().voxel_size);
  scratch.recompute(next.mapper().tsdf(), bodyAt(1.5).position, expected);
  EXPECT_TRUE(identicalLayers(expected, next.mapper().esdf()));

  // What cannot be continued is refused at start, with the reason.
  auto refusal = [&](const MapperNodeOptions& options) {
    try {
      MapperNode refused(lcm2, options, 44);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  MapperNodeOptions missing = loading;
  missing.load_map = path + ".missing";
  EXPECT_NE(refusal(missing).find("cannot read"), std::string::npos) << refusal(missing);
  MapperNodeOptions coarser = loading;
  coarser.mapper.voxel_size = 0.4;
  EXPECT_NE(refusal(coarser).find("voxels"), std::string::npos) << refusal(coarser);
  std::remove(path.c_str());
}

// Crash recovery: a mapper with a checkpoint saves its map every checkpoint_period of message
// time; one started after a crash (the file is still there) continues that flight's map under a
// new map id, keeps the flight's start (no clear sphere opens where the vehicle now is), and its
// mirrors catch up by a snapshot. A checkpoint of another flight is dropped at the first
// message; a clean stop removes the file.
TEST(MapperNode, ARestartedMapperContinuesItsCheckpoint) {
  const std::string path = ::testing::TempDir() + "/mapper_node.checkpoint";
  std::remove(path.c_str());
  MapperNodeOptions options = nodeOptions();
  options.checkpoint = path;
  options.checkpoint_period = 1.0;
  const sim::DepthRenderer renderer(smallForest(), smallCamera());
  TsdfLayer before(1.0);
  {
    lcm::LCM lcm("memq://");
    Loop loop(lcm);
    MapperNode mapper(lcm, options, 42);
    Node sensors("sensors", lcm);
    for (int k = 0; k < 4; ++k) {  // 1.0, 1.4, 1.8, 2.2 s: checkpoints at 1.0 and 2.2 s
      const int64_t t = 1'000'000 + k * 400'000;
      sensors.publish("STATE_ESTIMATE", poseMsg(t, bodyAt(k * 0.4)));
      sensors.publish("CAMERA_DEPTH", frameAt(renderer, k * 0.4, t));
      loop.drain();
      const auto saved = loadMap(path);
      ASSERT_TRUE(saved.ok()) << saved.error();
      EXPECT_EQ(saved->revision, k == 3 ? 4 : 1) << k;
    }
    before = mapper.mapper().tsdf();
    EXPECT_FALSE(std::filesystem::exists(path + ".part"));
  }  // a crash: the node is gone without removeCheckpoint()

  const auto saved = loadMap(path);
  ASSERT_TRUE(saved.ok()) << saved.error();
  ASSERT_TRUE(saved->start.has_value());
  EXPECT_EQ(*saved->start, bodyAt(0).position);
  EXPECT_EQ(saved->utime, 2'200'000);

  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  Observer observer(lcm);
  MapperNode respawned(lcm, options, 42);
  Node sensors("sensors", lcm);
  loop.drain();
  EXPECT_EQ(respawned.mapId(), 43);
  EXPECT_EQ(respawned.mapper().revision(), 4);
  EXPECT_TRUE(identicalLayers(respawned.mapper().tsdf(), before));
  ASSERT_TRUE(respawned.mapper().start().has_value());
  EXPECT_EQ(*respawned.mapper().start(), bodyAt(0).position);
  const mapper_status_t* restored = observer.last(mapper_status_t::RESULT_RESTORED);
  ASSERT_NE(restored, nullptr);
  EXPECT_NE(restored->reason.find("continued the checkpoint"), std::string::npos)
      << restored->reason;

  // The flight goes on: revision 5 on top of the continued map, and a mirror that joins now
  // gets all of it through one snapshot.
  sensors.publish("STATE_ESTIMATE", poseMsg(2'600'000, bodyAt(1.6)));
  sensors.publish("CAMERA_DEPTH", frameAt(renderer, 1.6, 2'600'000));
  loop.drain();
  ASSERT_EQ(respawned.mapper().revision(), 5);
  ASSERT_NE(observer.tsdf.layer(), nullptr);
  EXPECT_EQ(observer.tsdf.mapId(), 43);
  EXPECT_TRUE(identicalLayers(*observer.tsdf.layer(), respawned.mapper().tsdf()));
  for (const BlockIndex& b : before.blockIndices()) {
    EXPECT_NE(respawned.mapper().tsdf().block(b), nullptr);
  }
  respawned.removeCheckpoint();
  EXPECT_FALSE(std::filesystem::exists(path));

  // Another flight (its clock starts over) does not continue a checkpoint left behind.
  saveMap(path, *saved);
  {
    lcm::LCM lcm3("memq://");
    Loop loop3(lcm3);
    Observer observer3(lcm3);
    MapperNode next(lcm3, options, 42);
    Node sensors3("sensors", lcm3);
    EXPECT_EQ(next.mapper().revision(), 4);
    sensors3.publish("STATE_ESTIMATE", poseMsg(100'000, bodyAt(0)));
    sensors3.publish("CAMERA_DEPTH", frameAt(renderer, 0, 100'000));
    loop3.drain();
    EXPECT_EQ(next.mapper().revision(), 1);
    const mapper_status_t* dropped = observer3.last(mapper_status_t::RESULT_RESTORED);
    ASSERT_NE(dropped, nullptr);
    EXPECT_NE(dropped->reason.find("checkpoint dropped"), std::string::npos) << dropped->reason;
  }
  // ... and with a map to load, it starts from that map, as it would without the checkpoint.
  saveMap(path, *saved);
  SavedMap earlier = *saved;
  earlier.revision = 2;
  const std::string load = path + ".load";
  saveMap(load, earlier);
  MapperNodeOptions loading = options;
  loading.load_map = load;
  {
    lcm::LCM lcm4("memq://");
    Loop loop4(lcm4);
    MapperNode next(lcm4, loading, 42);
    Node sensors4("sensors", lcm4);
    sensors4.publish("STATE_ESTIMATE", poseMsg(100'000, bodyAt(0)));
    sensors4.publish("CAMERA_DEPTH", frameAt(renderer, 0, 100'000));
    loop4.drain();
    EXPECT_EQ(next.mapper().revision(), 3);  // load_map's revision 2, then this frame
  }
  std::remove(load.c_str());
  std::remove(path.c_str());
}

// The MAP_ESDF messages of a short flight.
std::vector<std::vector<uint8_t>> esdfBytes() {
  lcm::LCM lcm("memq://");
  Loop loop(lcm);
  const sim::DepthRenderer renderer(smallForest(), smallCamera());
  MapperNode mapper(lcm, nodeOptions(), 42);
  Node sensors("sensors", lcm);
  std::vector<std::vector<uint8_t>> bytes;
  sensors.subscribeRaw(
      "MAP_ESDF",
      [&](const void* data, size_t size, const MessageInfo&) {
        bytes.emplace_back(static_cast<const uint8_t*>(data),
                           static_cast<const uint8_t*>(data) + size);
      },
      1000);
  for (int k = 0; k < 4; ++k) {
    const int64_t t = 1'000'000 + k * 500'000;
    sensors.publish("STATE_ESTIMATE", poseMsg(t, bodyAt(k * 0.5)));
    sensors.publish("CAMERA_DEPTH", frameAt(renderer, k * 0.5, t));
    loop.drain();
  }
  return bytes;
}

TEST(MapperNode, IdenticalInputsGiveIdenticalMapMessages) {
  const auto a = esdfBytes();
  const auto b = esdfBytes();
  ASSERT_EQ(a.size(), 4u);
  EXPECT_EQ(a, b);
}

}  // namespace
}  // namespace thicket::mapper
