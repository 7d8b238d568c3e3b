// Internal to the explorer library: the exact nearest neighbours that RRT* (rrt_star.cc) searches
// its tree with; tested on its own.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include <ompl/datastructures/NearestNeighborsLinear.h>
#include <Eigen/Core>

namespace thicket::explorer::detail {

/// RealVectorStateSpace::distance's arithmetic in 3-D: the squared differences summed in axis
/// order, then the square root; the same bits.
inline double squaredSpaceDistance(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const double dx = a.x() - b.x();
  const double dy = a.y() - b.y();
  const double dz = a.z() - b.z();
  return dx * dx + dy * dy + dz * dz;
}
inline double spaceDistance(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::sqrt(squaredSpaceDistance(a, b));
}

/// Exact nearest neighbours by a linear scan, for elements that are points of a 3-D
/// RealVectorStateSpace (position(element) gives the point). The distance is that space's: the
/// same operations in the same order, so the same bits as its distance(), but computed inline from
/// positions kept beside the elements, each once per query, rather than through OMPL's distance
/// function (a std::function and two virtual calls per element, which dominated RRT*'s run time).
/// Ties are broken by insertion order, so the answer depends on no sorting algorithm: nearest() is
/// the first element at the smallest distance (as NearestNeighborsLinear's), nearestK() and
/// nearestR() list elements by (distance, insertion).
template <typename T, typename Position>
class PointNearestNeighbors final : public ompl::NearestNeighborsLinear<T> {
  using Base = ompl::NearestNeighborsLinear<T>;

 public:
  explicit PointNearestNeighbors(Position position = Position()) : position_(position) {}

  void clear() override {
    Base::clear();
    for (std::vector<double>& axis : points_) axis.clear();
  }
  void add(const T& data) override {
    Base::add(data);
    const Eigen::Vector3d p = position_(data);
    for (int a = 0; a < 3; ++a) points_[a].push_back(p[a]);
  }
  void add(const std::vector<T>& data) override {
    for (const T& d : data) add(d);
  }
  bool remove(const T& data) override {
    for (std::size_t i = this->data_.size(); i-- > 0;) {
      if (this->data_[i] == data) {
        this->data_.erase(this->data_.begin() + static_cast<std::ptrdiff_t>(i));
        for (std::vector<double>& axis : points_) {
          axis.erase(axis.begin() + static_cast<std::ptrdiff_t>(i));
        }
        return true;
      }
    }
    return false;
  }

  T nearest(const T& data) const override {
    if (this->data_.empty()) {
      throw std::logic_error("PointNearestNeighbors: nearest() of an empty set");
    }
    measure(data);
    // The first at the smallest square (bounded should a position be NaN, whose square none is).
    std::size_t best = 0;
    while (best + 1 < squared_.size() && squared_[best] != lowest_) ++best;
    // An earlier element whose larger squared distance rounds to the same distance ties, and
    // wins.
    const double d = std::sqrt(squared_[best]);
    const double window = squared_[best] * kSameDistance;
    for (std::size_t i = 0; i < best; ++i) {
      if (squared_[i] <= window && std::sqrt(squared_[i]) == d) return this->data_[i];
    }
    return this->data_[best];
  }
  void nearestK(const T& data, std::size_t k, std::vector<T>& nbh) const override {
    rank(data, nbh, std::numeric_limits<double>::infinity(), k);
  }
  void nearestR(const T& data, double radius, std::vector<T>& nbh) const override {
    rank(data, nbh, radius, std::numeric_limits<std::size_t>::max());
  }

 private:
  // Every element's squared distance to data, in insertion order: spaceDistance() before its square
  // root, which only the elements ranked need (it rounds, so ties are settled on distances); and
  // the smallest and the largest of them (NaNs left out).
  void measure(const T& data) const {
    const Eigen::Vector3d q = position_(data);
    const std::size_t n = points_[0].size();
    squared_.resize(n);
    const double* x = points_[0].data();
    const double* y = points_[1].data();
    const double* z = points_[2].data();
    double* out = squared_.data();
    // squaredSpaceDistance(point, q), two elements at a time: the same operations lane by lane.
    std::size_t i = 0;
    const Doubles2 qx = {q.x(), q.x()}, qy = {q.y(), q.y()}, qz = {q.z(), q.z()};
    constexpr double kInf = std::numeric_limits<double>::infinity();
    Doubles2 lowest = {kInf, kInf}, highest = {0, 0};
    for (; i + 2 <= n; i += 2) {
      Doubles2 px, py, pz;
      std::memcpy(&px, x + i, sizeof(px));
      std::memcpy(&py, y + i, sizeof(py));
      std::memcpy(&pz, z + i, sizeof(pz));
      const Doubles2 dx = px - qx, dy = py - qy, dz = pz - qz;
      const Doubles2 squares = dx * dx + dy * dy + dz * dz;
      std::memcpy(out + i, &squares, sizeof(squares));
      lowest = squares < lowest ? squares : lowest;
      highest = squares > highest ? squares : highest;
    }
    lowest_ = std::min(lowest[0], lowest[1]);
    highest_ = std::max(highest[0], highest[1]);
    for (; i < n; ++i) {
      out[i] = squaredSpaceDistance({x[i], y[i], z[i]}, q);
      lowest_ = std::min(lowest_, out[i]);
      highest_ = std::max(highest_, out[i]);
    }
  }

  // The at most k elements within radius, by (distance, insertion). RRT*'s k is over half of a
  // grown tree, so nearly every element is ranked: a counting sort on the squared distances
  // (kBucketsPerElement buckets per element, spread linearly between the smallest and the largest
  // candidate: in a 3-D tree the squares come about evenly spread) puts the candidates nearly in
  // order, and an insertion sort on (distance, insertion) finishes, moving a candidate only past
  // the few of its own bucket or next to it. Comparison sorts mispredict about every other
  // comparison; this has no branch on the data but the insertion sort's.
  void rank(const T& data, std::vector<T>& nbh, double radius, std::size_t k) const {
    measure(data);
    nbh.clear();
    // Candidates a few ulps beyond radius^2 stay until their distance is known.
    const double limit = radius * radius * kSameDistance;
    const std::size_t n = squared_.size();
    if (n == 0 || k == 0 || !(lowest_ <= limit)) return;
    // The buckets span the candidates' squares (those up to limit). bucket(s) does not decrease as
    // s grows (a subtraction, a product by a positive factor and a truncation are each
    // monotonic), whatever it rounds.
    const double lo = lowest_;
    const double hi = std::min(highest_, limit);
    const std::size_t buckets = kBucketsPerElement * n;
    double scale = static_cast<double>(buckets) / (hi - lo);
    if (!std::isfinite(scale)) scale = 0;  // all squares equal, or too close to divide by
    const double top = static_cast<double>(buckets - 1);
    const auto bucket = [&](double s) {
      // Not NaN but for an infinite square (with scale 0): the last bucket then.
      const double t = (s - lo) * scale;
      return t < top ? static_cast<uint32_t>(t) : static_cast<uint32_t>(buckets - 1);
    };
    // A counting sort of all elements by bucket, stable (so in insertion order within one), those
    // beyond the radius in one more bucket at the end; without a branch that depends on the data,
    // which would mispredict at every other element.
    count_.assign(buckets + 1, 0);
    bucket_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double s = squared_[i];
      bucket_[i] = s <= limit ? bucket(s) : static_cast<uint32_t>(buckets);
      ++count_[bucket_[i]];
    }
    uint32_t start = 0;
    for (uint32_t& c : count_) start += std::exchange(c, start);
    ranked_.resize(n);
    for (std::size_t i = 0; i < n; ++i) ranked_[count_[bucket_[i]]++] = static_cast<uint32_t>(i);
    // count_[b] is now where bucket b ends. Kept: all candidates, or the buckets that hold the k
    // smallest squares and every square whose distance can tie with the k-th's (within
    // kSameDistance of the largest square up to the k-th's bucket).
    std::size_t total = count_[buckets - 1];
    if (k < total) {
      const uint32_t end = count_[bucket_[ranked_[k - 1]]];
      double cut = lo;
      for (uint32_t i = 0; i < end; ++i) cut = std::max(cut, squared_[ranked_[i]]);
      total = count_[bucket(std::min(cut * kSameDistance, hi))];
    }
    distances_.resize(total);
    for (std::size_t i = 0; i < total; ++i) distances_[i] = std::sqrt(squared_[ranked_[i]]);
    for (std::size_t i = 1; i < total; ++i) {
      const uint32_t index = ranked_[i];
      const double d = distances_[i];
      std::size_t j = i;
      for (; j > 0 && (d < distances_[j - 1] || (d == distances_[j - 1] && index < ranked_[j - 1]));
           --j) {
        ranked_[j] = ranked_[j - 1];
        distances_[j] = distances_[j - 1];
      }
      ranked_[j] = index;
      distances_[j] = d;
    }
    for (std::size_t i = 0; i < std::min(k, total) && distances_[i] <= radius; ++i) {
      nbh.push_back(this->data_[ranked_[i]]);
    }
  }

  // Squares farther apart than this factor have different square roots: a square root halves
  // relative differences, and doubles round within 1.1e-16 of theirs.
  static constexpr double kSameDistance = 1 + 1e-15;

  using Doubles2 = double __attribute__((vector_size(16)));

  // rank()'s buckets per element: enough that few share one, so that the insertion sort moves
  // few.
  static constexpr std::size_t kBucketsPerElement = 2;

  Position position_;
  std::array<std::vector<double>, 3> points_;  // per axis, position_(data_[i])
  mutable std::vector<double> squared_;        // measure()
  mutable double lowest_ = 0, highest_ = 0;    // measure(): the smallest and largest squares
  mutable std::vector<uint32_t> bucket_;       // rank(): each element's bucket
  mutable std::vector<uint32_t> count_;        // rank(): per bucket, its count, then its next slot
  mutable std::vector<uint32_t> ranked_;       // rank(): the elements' indices, by bucket
  mutable std::vector<double> distances_;      // rank(): their distances
};

}  // namespace thicket::explorer::detail
