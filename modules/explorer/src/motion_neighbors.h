// Internal to the explorer library: the exact nearest neighbours that RRT* (rrt_star.cc) searches
// its tree with; tested on its own.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include <ompl/datastructures/NearestNeighborsLinear.h>
#include <Eigen/Core>

namespace thicket::explorer::detail {

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
    points_.clear();
  }
  void add(const T& data) override {
    Base::add(data);
    points_.push_back(position_(data));
  }
  void add(const std::vector<T>& data) override {
    for (const T& d : data) add(d);
  }
  bool remove(const T& data) override {
    for (std::size_t i = this->data_.size(); i-- > 0;) {
      if (this->data_[i] == data) {
        this->data_.erase(this->data_.begin() + static_cast<std::ptrdiff_t>(i));
        points_.erase(points_.begin() + static_cast<std::ptrdiff_t>(i));
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
    std::size_t best = 0;
    for (std::size_t i = 1; i < squared_.size(); ++i) {
      if (squared_[i] < squared_[best]) best = i;
    }
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

  /// RealVectorStateSpace::distance's arithmetic: the squared differences summed in axis order,
  /// then the square root.
  static double distance(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::sqrt(squaredDistance(a, b));
  }

 private:
  static double squaredDistance(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const double dx = a.x() - b.x();
    const double dy = a.y() - b.y();
    const double dz = a.z() - b.z();
    return dx * dx + dy * dy + dz * dz;
  }

  // Every element's squared distance to data, in insertion order: distance() before its square
  // root, which only the elements ranked need (it rounds, so ties are settled on distances).
  void measure(const T& data) const {
    const Eigen::Vector3d q = position_(data);
    squared_.resize(points_.size());
    for (std::size_t i = 0; i < points_.size(); ++i) squared_[i] = squaredDistance(points_[i], q);
  }

  // The at most k elements within radius, by (distance, insertion).
  void rank(const T& data, std::vector<T>& nbh, double radius, std::size_t k) const {
    measure(data);
    // Each candidate as one integer key, (the top 32 bits of its squared distance, index): a
    // squared distance is not negative, so its bits order as it does. Those a few ulps beyond
    // radius^2 stay until their distance is known.
    const double limit = radius * radius * kSameDistance;
    ranked_.clear();
    for (std::size_t i = 0; i < squared_.size(); ++i) {
      if (squared_[i] <= limit) {
        ranked_.push_back((std::bit_cast<uint64_t>(squared_[i]) >> 32) << 32 | i);
      }
    }
    if (k < ranked_.size()) keepNearest(k);
    sortRanked();
    // By (distance, index): keys whose top bits differ are in distance order (their squares
    // differ by more than a millionth), those that share them in index order, which a stable
    // insertion sort on their distances keeps for equal ones.
    const std::size_t n = ranked_.size();
    distances_.resize(n);
    for (std::size_t i = 0; i < n; ++i) distances_[i] = std::sqrt(squared_[index(ranked_[i])]);
    for (std::size_t i = 1; i < n; ++i) {
      const Key key = ranked_[i];
      const double d = distances_[i];
      std::size_t j = i;
      for (; j > 0 && d < distances_[j - 1]; --j) {
        ranked_[j] = ranked_[j - 1];
        distances_[j] = distances_[j - 1];
      }
      ranked_[j] = key;
      distances_[j] = d;
    }
    nbh.clear();
    for (std::size_t i = 0; i < std::min(k, n) && distances_[i] <= radius; ++i) {
      nbh.push_back(this->data_[index(ranked_[i])]);
    }
  }

  // Drops keys of ranked_ (more than k) that cannot be among its k smallest, keeping their order:
  // RRT*'s k is about a third of a grown tree. A histogram of the squared distances' top 16 bits
  // (sign, exponent and 4 bits of mantissa: buckets a sixteenth of an octave wide), counted from
  // the smallest, finds the bucket of the k-th smallest key; keys beyond the next bucket go (the
  // next stays: a squared distance there may round to the k-th's distance). The last bucket also
  // holds all that lie farther: when the k-th smallest is near there, every key stays.
  void keepNearest(std::size_t k) const {
    const auto bucket_of = [](Key key) { return static_cast<uint32_t>(key >> 48); };
    uint32_t lowest = std::numeric_limits<uint32_t>::max();
    for (const Key key : ranked_) lowest = std::min(lowest, bucket_of(key));
    constexpr uint32_t kBuckets = 1024;
    std::array<uint32_t, kBuckets> count{};
    for (const Key key : ranked_) ++count[std::min(bucket_of(key) - lowest, kBuckets - 1)];
    std::size_t sum = 0;
    uint32_t last = 0;
    while ((sum += count[last]) < k) ++last;
    if (++last >= kBuckets - 1) return;
    std::size_t kept = 0;
    for (const Key key : ranked_) {
      ranked_[kept] = key;
      kept += bucket_of(key) - lowest <= last;
    }
    ranked_.resize(kept);
  }

  // Sorts ranked_. RRT*'s k grows so fast that a query often ranks the whole tree, and comparison
  // sorts mispredict about every other comparison: so a stable radix sort on the top 32 bits (the
  // squared distance's), byte by byte (a byte that every key shares is skipped), which keeps the
  // indices in order among equal bits: the keys end sorted.
  void sortRanked() const {
    const std::size_t n = ranked_.size();
    if (n < 64) {
      std::sort(ranked_.begin(), ranked_.end());
      return;
    }
    scratch_.resize(n);
    std::array<std::array<std::size_t, 256>, 4> start{};
    for (const Key key : ranked_) {
      for (int b = 0; b < 4; ++b) ++start[b][static_cast<uint8_t>(key >> (32 + 8 * b))];
    }
    for (int b = 0; b < 4; ++b) {
      const int shift = 32 + 8 * b;
      if (start[b][static_cast<uint8_t>(ranked_[0] >> shift)] == n) continue;
      std::size_t sum = 0;
      for (std::size_t& s : start[b]) sum += std::exchange(s, sum);
      for (const Key key : ranked_) scratch_[start[b][static_cast<uint8_t>(key >> shift)]++] = key;
      ranked_.swap(scratch_);
    }
  }

  // Squares farther apart than this factor have different square roots: a square root halves
  // relative differences, and doubles round within 1.1e-16 of theirs.
  static constexpr double kSameDistance = 1 + 1e-15;

  using Key = uint64_t;
  static std::size_t index(Key key) { return static_cast<std::size_t>(key & 0xFFFFFFFFu); }

  Position position_;
  std::vector<Eigen::Vector3d> points_;    // position_(data_[i])
  mutable std::vector<double> squared_;    // measure()
  mutable std::vector<double> distances_;  // the ranked keys' distances
  mutable std::vector<Key> ranked_, scratch_;
};

}  // namespace thicket::explorer::detail
