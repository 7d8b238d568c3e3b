// RRT*'s nearest neighbours (motion_neighbors.h) against a brute force that measures with OMPL's
// own RealVectorStateSpace::distance and ranks by (distance, insertion): the same elements in the
// same order, ties included, however the distances spread over the buckets of its counting sort.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include <ompl/base/ScopedState.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>

#include "motion_neighbors.h"

namespace thicket::explorer::detail {
namespace {

// Elements are indices into a table of points.
struct TablePosition {
  const std::vector<Eigen::Vector3d>* points = nullptr;
  Eigen::Vector3d operator()(int i) const { return (*points)[static_cast<size_t>(i)]; }
};
using Neighbors = PointNearestNeighbors<int, TablePosition>;

class MotionNeighbors : public ::testing::Test {
 protected:
  MotionNeighbors() : space_(std::make_shared<ompl::base::RealVectorStateSpace>(3)) {}

  // OMPL's distance between two points of the table.
  double omplDistance(int a, int b) const {
    ompl::base::ScopedState<ompl::base::RealVectorStateSpace> sa(space_), sb(space_);
    for (int i = 0; i < 3; ++i) {
      sa[i] = points_[static_cast<size_t>(a)][i];
      sb[i] = points_[static_cast<size_t>(b)][i];
    }
    return space_->distance(sa.get(), sb.get());
  }

  // The elements within radius of the query, by (OMPL distance, insertion), at most k.
  std::vector<int> bruteForce(const std::vector<int>& elements, int query, size_t k,
                              double radius) const {
    std::vector<std::pair<double, size_t>> ranked;
    for (size_t i = 0; i < elements.size(); ++i) {
      const double d = omplDistance(elements[i], query);
      if (d <= radius) ranked.emplace_back(d, i);
    }
    std::sort(ranked.begin(), ranked.end());
    std::vector<int> out;
    for (size_t i = 0; i < std::min(k, ranked.size()); ++i) {
      out.push_back(elements[ranked[i].second]);
    }
    return out;
  }

  // n random points in a 6 m box, a tenth of them repeats of earlier ones and a tenth mirrored
  // through the first query point, so that distances tie exactly.
  void fill(size_t n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> coordinate(-3.0, 3.0);
    points_.clear();
    points_.emplace_back(0.25, -0.5, 1.0);  // the first query
    while (points_.size() < n + 1) {
      const size_t kind = rng() % 10;
      if (kind == 0 && points_.size() > 2) {
        points_.push_back(points_[1 + rng() % (points_.size() - 1)]);
      } else if (kind == 1 && points_.size() > 2) {
        points_.push_back(2 * points_[0] - points_[1 + rng() % (points_.size() - 1)]);
      } else {
        points_.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
      }
    }
  }

  std::shared_ptr<ompl::base::RealVectorStateSpace> space_;
  std::vector<Eigen::Vector3d> points_;
};

TEST_F(MotionNeighbors, DistanceHasTheBitsOfOmplsDistance) {
  fill(200, 1);
  for (int a = 0; a < 200; ++a) {
    const int b = (a * 37 + 11) % 200;
    EXPECT_EQ(std::bit_cast<uint64_t>(spaceDistance(points_[a], points_[b])),
              std::bit_cast<uint64_t>(omplDistance(a, b)))
        << a << " " << b;
  }
}

TEST_F(MotionNeighbors, RanksAsTheBruteForceWithTiesInInsertionOrder) {
  // From a handful of elements to a grown tree's.
  for (const size_t n : {5, 40, 63, 64, 65, 300, 1500}) {
    fill(n, n);
    Neighbors nn(TablePosition{&points_});
    std::vector<int> elements;
    for (int i = 1; i <= static_cast<int>(n); ++i) {
      nn.add(i);
      elements.push_back(i);
    }
    ASSERT_EQ(nn.size(), n);
    std::vector<int> queries = {0, 1, static_cast<int>(n) / 2};
    for (const int q : queries) {
      std::vector<int> got;
      for (const size_t k : {size_t{1}, size_t{7}, n / 2 + 1, n, n + 10}) {
        nn.nearestK(q, k, got);
        EXPECT_EQ(got, bruteForce(elements, q, k, std::numeric_limits<double>::infinity()))
            << "n " << n << " query " << q << " k " << k;
      }
      for (const double r : {0.0, 0.7, 2.5, 100.0}) {
        nn.nearestR(q, r, got);
        EXPECT_EQ(got, bruteForce(elements, q, std::numeric_limits<size_t>::max(), r))
            << "n " << n << " query " << q << " r " << r;
      }
      EXPECT_EQ(nn.nearest(q), bruteForce(elements, q, 1, 1e300).front()) << "n " << n;
    }
  }
}

TEST_F(MotionNeighbors, TiesGoToTheEarlierInsertion) {
  points_ = {{0, 0, 0}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {1, 0, 0}, {0.5, 0, 0}};
  Neighbors nn(TablePosition{&points_});
  for (const int i : {4, 1, 2, 3, 5}) nn.add(i);
  std::vector<int> got;
  nn.nearestK(0, 10, got);
  // 5 at 0.5; then 4, 1, 2, 3 at 1 in insertion order (4 and 1 are the same point).
  EXPECT_EQ(got, (std::vector<int>{5, 4, 1, 2, 3}));
  nn.nearestK(1, 2, got);
  EXPECT_EQ(got, (std::vector<int>{4, 1}));  // both at 0
  EXPECT_EQ(nn.nearest(1), 4);
}

TEST_F(MotionNeighbors, OrdersDistancesThatDifferOnlyInTheirLastBits) {
  // 100 points whose distances differ only in their last bits, inserted farthest first: a few
  // buckets hold them all, and the insertion sort orders them by those bits alone.
  points_ = {Eigen::Vector3d::Zero()};
  for (int i = 0; i < 100; ++i) points_.emplace_back(1.0 + (99 - i) * 1e-13, 0, 0);
  Neighbors nn(TablePosition{&points_});
  for (int i = 1; i <= 100; ++i) nn.add(i);
  std::vector<int> got;
  nn.nearestK(0, 100, got);
  std::vector<int> nearest_first;
  for (int i = 100; i >= 1; --i) nearest_first.push_back(i);
  EXPECT_EQ(got, nearest_first);
}

TEST_F(MotionNeighbors, TiesOnDistancesWhoseSquaresDiffer) {
  // (1, 1.5e-8, 0) is at squared distance 1 + 2^-52 from the origin, (1, 0, 0) at 1: both at
  // distance 1 exactly. Alternated, the first of each pair inserted first, with 98 points at
  // other distances: ties go by insertion whatever the squares say, in nearest() too.
  points_ = {Eigen::Vector3d::Zero()};
  ASSERT_EQ(spaceDistance(points_[0], {1, 1.5e-8, 0}), 1.0);
  ASSERT_NE(Eigen::Vector3d(1, 1.5e-8, 0).squaredNorm(), 1.0);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> coordinate(-2.0, 2.0);
  for (int i = 0; i < 49; ++i) {
    points_.emplace_back(1, i % 2 == 0 ? 1.5e-8 : 0, 0);
    points_.emplace_back(1, i % 2 == 0 ? 0 : 1.5e-8, 0);
    points_.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
    points_.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
  }
  std::vector<int> elements;
  for (int i = 1; i < static_cast<int>(points_.size()); ++i) elements.push_back(i);
  Neighbors nn(TablePosition{&points_});
  for (const int i : elements) nn.add(i);
  std::vector<int> got;
  for (const size_t k : {size_t{1}, size_t{2}, size_t{30}, size_t{60}, elements.size()}) {
    nn.nearestK(0, k, got);
    EXPECT_EQ(got, bruteForce(elements, 0, k, std::numeric_limits<double>::infinity())) << k;
  }
  nn.nearestR(0, 1.0, got);
  EXPECT_EQ(got, bruteForce(elements, 0, std::numeric_limits<size_t>::max(), 1.0));
  Neighbors pair(TablePosition{&points_});
  pair.add(1);  // (1, 1.5e-8, 0)
  pair.add(2);  // (1, 0, 0), the smaller square
  EXPECT_EQ(pair.nearest(0), 1);
  pair.nearestK(0, 1, got);
  EXPECT_EQ(got, std::vector<int>{1});
}

TEST_F(MotionNeighbors, KeepsTheNearestKWhateverTheRangeOfDistances) {
  // Distances from 2^-60 to 2^60 m, a few of them repeated, inserted in a shuffled order: every k
  // gives the brute force's k nearest, although the buckets, spread linearly up to the largest
  // square, put nearly all of them in the first.
  points_ = {Eigen::Vector3d::Zero()};
  for (int e = -60; e <= 60; ++e) {
    for (const double m : {1.0, 1.03, 1.5}) points_.emplace_back(m * std::ldexp(1.0, e), 0, 0);
    if (e % 7 == 0) points_.emplace_back(0, std::ldexp(1.0, e), 0);  // a tie with (2^e, 0, 0)
  }
  std::vector<int> elements;
  for (int i = 1; i < static_cast<int>(points_.size()); ++i) elements.push_back(i);
  std::shuffle(elements.begin(), elements.end(), std::mt19937_64(7));
  Neighbors nn(TablePosition{&points_});
  for (const int i : elements) nn.add(i);
  std::vector<int> got;
  for (size_t k = 0; k <= elements.size(); k += 5) {
    nn.nearestK(0, k, got);
    EXPECT_EQ(got, bruteForce(elements, 0, k, std::numeric_limits<double>::infinity())) << k;
  }
}

TEST_F(MotionNeighbors, RemoveDropsTheLastCopyAndItsPosition) {
  points_ = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}};
  Neighbors nn(TablePosition{&points_});
  for (const int i : {1, 2, 1, 3}) nn.add(i);
  EXPECT_TRUE(nn.remove(1));
  EXPECT_FALSE(nn.remove(0));
  std::vector<int> got;
  nn.nearestK(0, 10, got);
  EXPECT_EQ(got, (std::vector<int>{1, 2, 3}));
  nn.list(got);
  EXPECT_EQ(got, (std::vector<int>{1, 2, 3}));
  nn.clear();
  EXPECT_EQ(nn.size(), 0u);
  EXPECT_THROW(nn.nearest(0), std::logic_error);
}

}  // namespace
}  // namespace thicket::explorer::detail
