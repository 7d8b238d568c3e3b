// Statistical outlier removal (PCL) on a depth image: isolated returns floating in front of a
// wall are removed, the wall stays; disabled, nothing changes.
#include <vector>

#include <gtest/gtest.h>

#include "thicket/stereo_depth/outlier_filter.h"

namespace thicket::stereo_depth {
namespace {

TEST(OutlierFilter, RemovesIsolatedReturnsAndKeepsTheWall) {
  const PinholeCamera camera = PinholeCamera::fromHorizontalFov(80, 60, 1.5);
  std::vector<float> depth(80 * 60, 4.0f);  // a wall 4 m away
  const std::vector<int> strays = {10 * 80 + 10, 30 * 80 + 50, 50 * 80 + 70};
  for (int i : strays) depth[i] = 1.0f;  // single pixels 3 m in front of it
  OutlierFilterOptions options;
  options.stride = 1;
  std::vector<float> unchanged = depth;
  EXPECT_EQ(removeOutliers(unchanged, camera, options), 0);  // disabled by default
  EXPECT_EQ(unchanged, depth);
  options.enabled = true;
  EXPECT_EQ(removeOutliers(depth, camera, options), 3);
  for (int i : strays) EXPECT_EQ(depth[i], 0.0f);
  size_t wall = 0;
  for (float z : depth) wall += z == 4.0f ? 1 : 0;
  EXPECT_EQ(wall, depth.size() - strays.size());
}

}  // namespace
}  // namespace thicket::stereo_depth
