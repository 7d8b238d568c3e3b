// The mapper refuses options its YAML declaration refuses, also when they are built in code.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <stdexcept>

#include "thicket/mapper/mapper.h"

namespace thicket::mapper {
namespace {

TEST(MapperOptions, EveryFieldKeepsItsYamlRule) {
  const auto refused = [](const std::function<void(MapperOptions&)>& mutate,
                          const std::string& words) {
    MapperOptions options;
    mutate(options);
    try {
      Mapper mapper(options);
      ADD_FAILURE() << words << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  refused([](MapperOptions& o) { o.voxel_size = 5; }, "voxel_size");
  refused([](MapperOptions& o) { o.max_pending_frames = 0; }, "max_pending_frames");
  refused([](MapperOptions& o) { o.poses.tolerance_us = -1; }, "pose_tolerance_us");
  refused([](MapperOptions& o) { o.tsdf.truncation_voxels = 0; }, "truncation");
  refused([](MapperOptions& o) { o.esdf.max_distance = std::nan(""); }, "max_distance");
  EXPECT_NO_THROW(Mapper{MapperOptions{}});
}

}  // namespace
}  // namespace thicket::mapper
