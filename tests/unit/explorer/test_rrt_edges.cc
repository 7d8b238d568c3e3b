// RRT*'s edge checks and prices (rrt_edges.h) against OMPL's own DiscreteMotionValidator and
// PathLengthOptimizationObjective on random edges: the same answers, from the same states, to the
// bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include <ompl/base/DiscreteMotionValidator.h>
#include <ompl/base/ScopedState.h>
#include <ompl/base/SpaceInformation.h>
#include <ompl/base/objectives/PathLengthOptimizationObjective.h>
#include <ompl/base/spaces/RealVectorStateSpace.h>

#include "rrt_edges.h"

namespace thicket::explorer::detail {
namespace {

namespace ob = ompl::base;

using Bits = std::array<uint64_t, 3>;
Bits bitsOf(const Eigen::Vector3d& p) {
  return {std::bit_cast<uint64_t>(p.x()), std::bit_cast<uint64_t>(p.y()),
          std::bit_cast<uint64_t>(p.z())};
}

class RrtEdges : public ::testing::Test {
 protected:
  RrtEdges() : space_(std::make_shared<ob::RealVectorStateSpace>(3)) {
    space_->setBounds(-10, 10);
    si_ = std::make_shared<ob::SpaceInformation>(space_);
    si_->setStateValidityChecker([this](const ob::State* s) { return free(statePosition(s)); });
    // 0.1 m of the space's extent, as rrt_star.check_step gives it.
    si_->setStateValidityCheckingResolution(0.1 / space_->getMaximumExtent());
    si_->setup();
    // Obstacles: balls of 0.5 to 1.5 m scattered through the box, in the way of about half the
    // edges.
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> coordinate(-10, 10), radius(0.5, 1.5);
    for (int i = 0; i < 400; ++i) {
      balls_.push_back({{coordinate(rng), coordinate(rng), coordinate(rng)}, radius(rng)});
    }
    ompl_ = std::make_unique<ob::DiscreteMotionValidator>(si_);
    ours_ = std::make_unique<EdgeValidator<Free>>(si_, Free{this});
  }

  // EdgeValidator's predicate: the fixture's free().
  struct Free {
    RrtEdges* test;
    bool operator()(const Eigen::Vector3d& p) const { return test->free(p); }
  };

  bool free(const Eigen::Vector3d& p) {
    checked_.push_back(bitsOf(p));
    return std::none_of(balls_.begin(), balls_.end(),
                        [&](const auto& ball) { return (p - ball.first).norm() < ball.second; });
  }

  // Random edges up to 3 m long (RRT*'s range is 1.5 m; longer ones have more states).
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> edges(int n) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> coordinate(-9, 9), offset(-1.7, 1.7);
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> out;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d a(coordinate(rng), coordinate(rng), coordinate(rng));
      out.emplace_back(a, a + Eigen::Vector3d(offset(rng), offset(rng), offset(rng)));
    }
    return out;
  }

  ob::ScopedState<ob::RealVectorStateSpace> state(const Eigen::Vector3d& p) const {
    ob::ScopedState<ob::RealVectorStateSpace> s(space_);
    for (int i = 0; i < 3; ++i) s[i] = p[i];
    return s;
  }

  std::shared_ptr<ob::RealVectorStateSpace> space_;
  ob::SpaceInformationPtr si_;
  std::vector<std::pair<Eigen::Vector3d, double>> balls_;
  std::vector<Bits> checked_;  // every state the validity checker was asked about
  std::unique_ptr<ob::DiscreteMotionValidator> ompl_;
  std::unique_ptr<EdgeValidator<Free>> ours_;
};

TEST_F(RrtEdges, EdgeValidatorAnswersAsOmplsDiscreteMotionValidator) {
  int valid = 0, invalid = 0;
  for (const auto& [a, b] : edges(4000)) {
    const auto sa = state(a), sb = state(b);
    const bool expected = ompl_->checkMotion(sa.get(), sb.get());
    ASSERT_EQ(ours_->checkMotion(sa.get(), sb.get()), expected)
        << a.transpose() << " -> " << b.transpose();
    ++(expected ? valid : invalid);
  }
  // Both answers occur often, so a validator that always said one of them would fail.
  EXPECT_GT(valid, 400);
  EXPECT_GT(invalid, 400);
  EXPECT_EQ(ours_->getValidMotionCount(), static_cast<unsigned>(valid));
  EXPECT_EQ(ours_->getInvalidMotionCount(), static_cast<unsigned>(invalid));
}

// On free edges both check every state, so the states themselves can be compared: the same set,
// to the bit (OMPL's in bisection order, ours along the edge).
TEST_F(RrtEdges, EdgeValidatorChecksTheStatesOmplChecks) {
  balls_.clear();
  size_t states = 0;
  for (const auto& [a, b] : edges(300)) {
    const auto sa = state(a), sb = state(b);
    checked_.clear();
    ASSERT_TRUE(ompl_->checkMotion(sa.get(), sb.get()));
    std::vector<Bits> expected = checked_;
    checked_.clear();
    ASSERT_TRUE(ours_->checkMotion(sa.get(), sb.get()));
    std::vector<Bits> got = checked_;
    std::sort(expected.begin(), expected.end());
    std::sort(got.begin(), got.end());
    ASSERT_EQ(got, expected) << a.transpose() << " -> " << b.transpose();
    states += got.size();
  }
  EXPECT_GT(states, 300u * 5);  // edges of several states, not just their ends
}

TEST_F(RrtEdges, EdgeValidatorReportsTheLastValidStateAsOmpl) {
  int blocked = 0;
  for (const auto& [a, b] : edges(1000)) {
    const auto sa = state(a), sb = state(b);
    auto ompl_last = state(a), our_last = state(a);
    std::pair<ob::State*, double> expected(ompl_last.get(), -1), got(our_last.get(), -1);
    const bool ok = ompl_->checkMotion(sa.get(), sb.get(), expected);
    ASSERT_EQ(ours_->checkMotion(sa.get(), sb.get(), got), ok);
    if (ok) continue;
    ++blocked;
    ASSERT_EQ(std::bit_cast<uint64_t>(got.second), std::bit_cast<uint64_t>(expected.second));
    for (int i = 0; i < 3; ++i) {
      ASSERT_EQ(std::bit_cast<uint64_t>(our_last[i]), std::bit_cast<uint64_t>(ompl_last[i]));
    }
  }
  EXPECT_GT(blocked, 100);
}

TEST_F(RrtEdges, EdgeLengthIsOmplsPathLengthToTheBit) {
  const ob::PathLengthOptimizationObjective ompl_objective(si_);
  const EdgeLengthObjective ours(si_);
  std::mt19937_64 rng(3);
  // Coordinates of every magnitude, where rounding differences would show.
  std::uniform_real_distribution<double> mantissa(-1, 1), exponent(-8, 4);
  for (int i = 0; i < 20000; ++i) {
    Eigen::Vector3d a, b;
    for (int k = 0; k < 3; ++k) {
      a[k] = mantissa(rng) * std::pow(10.0, exponent(rng));
      b[k] = mantissa(rng) * std::pow(10.0, exponent(rng));
    }
    const auto sa = state(a), sb = state(b);
    ASSERT_EQ(std::bit_cast<uint64_t>(ours.motionCost(sa.get(), sb.get()).value()),
              std::bit_cast<uint64_t>(ompl_objective.motionCost(sa.get(), sb.get()).value()));
  }
}

}  // namespace
}  // namespace thicket::explorer::detail
