// quantile and median against values worked by hand (and numpy's default method).
#include <gtest/gtest.h>

#include "thicket/common/statistics.h"

namespace thicket {
namespace {

TEST(Statistics, MedianOfAnEvenCountIsTheMeanOfTheMiddleTwo) {
  EXPECT_EQ(median({4, 1, 3, 2}), 2.5);  // the old nearest-rank rounding gave 3
  EXPECT_EQ(median({10, 20}), 15);
  EXPECT_EQ(median({5, 1, 3}), 3);
  EXPECT_EQ(median({7}), 7);
  EXPECT_EQ(median({}), 0);
}

TEST(Statistics, QuantilesInterpolateBetweenRanks) {
  const std::vector<double> values = {15, 20, 35, 40, 50};  // numpy.quantile(values, q)
  EXPECT_DOUBLE_EQ(quantile(values, 0.0), 15);
  EXPECT_DOUBLE_EQ(quantile(values, 0.25), 20);
  EXPECT_DOUBLE_EQ(quantile(values, 0.4), 29);
  EXPECT_DOUBLE_EQ(quantile(values, 0.95), 48);
  EXPECT_DOUBLE_EQ(quantile(values, 1.0), 50);
  EXPECT_DOUBLE_EQ(quantile(values, 7.0), 50);  // clamped
  EXPECT_DOUBLE_EQ(quantile({3, 1, 2}, 0.5), 2);
}

}  // namespace
}  // namespace thicket
