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
    for (std::size_t i = 1; i < distances_.size(); ++i) {
      if (distances_[i] < distances_[best]) best = i;
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
    const double dx = a.x() - b.x();
    const double dy = a.y() - b.y();
    const double dz = a.z() - b.z();
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  }

 private:
  // Every element's distance to data, in insertion order.
  void measure(const T& data) const {
    const Eigen::Vector3d q = position_(data);
    distances_.resize(points_.size());
    for (std::size_t i = 0; i < points_.size(); ++i) distances_[i] = distance(points_[i], q);
  }

  // The at most k elements within radius, nearest first.
  void rank(const T& data, std::vector<T>& nbh, double radius, std::size_t k) const {
    measure(data);
    // Each candidate as one integer key, (distance, index): a distance is not negative, so its
    // bits order as it does. A total order: the k nearest, sorted, whatever the algorithm.
    ranked_.clear();
    for (std::size_t i = 0; i < distances_.size(); ++i) {
      if (distances_[i] <= radius) {
        ranked_.push_back(Key{std::bit_cast<uint64_t>(distances_[i])} << 64 | Key{i});
      }
    }
    if (k < ranked_.size()) keepNearest(k);
    sortRanked();
    const auto end = ranked_.begin() + static_cast<std::ptrdiff_t>(std::min(k, ranked_.size()));
    nbh.clear();
    for (auto it = ranked_.begin(); it != end; ++it) {
      nbh.push_back(this->data_[static_cast<std::size_t>(static_cast<uint64_t>(*it))]);
    }
  }

  // Drops keys of ranked_ (more than k) that cannot be among its k smallest, keeping their order:
  // RRT*'s k is about a third of a grown tree. A histogram of the distances' top 16 bits (sign,
  // exponent and 4 bits of mantissa: buckets a sixteenth of an octave wide), counted from the
  // smallest, finds the bucket of the k-th smallest key; keys in later buckets go. The last bucket
  // also holds all that lie farther: when the k-th smallest is there, every key stays.
  void keepNearest(std::size_t k) const {
    const auto bucket_of = [](Key key) { return static_cast<uint32_t>(key >> 112); };
    uint32_t lowest = std::numeric_limits<uint32_t>::max();
    for (const Key key : ranked_) lowest = std::min(lowest, bucket_of(key));
    constexpr uint32_t kBuckets = 1024;
    std::array<uint32_t, kBuckets> count{};
    for (const Key key : ranked_) ++count[std::min(bucket_of(key) - lowest, kBuckets - 1)];
    std::size_t sum = 0;
    uint32_t last = 0;
    while ((sum += count[last]) < k) ++last;
    if (last == kBuckets - 1) return;
    std::size_t kept = 0;
    for (const Key key : ranked_) {
      ranked_[kept] = key;
      kept += bucket_of(key) - lowest <= last;
    }
    ranked_.resize(kept);
  }

  // Sorts ranked_. RRT*'s k grows so fast that a query often ranks the whole tree, and comparison
  // sorts mispredict about every other comparison: so a stable radix sort on the top 32 bits of
  // the distance, byte by byte (a byte that every key shares is skipped), then an insertion sort
  // on the whole keys, which only moves keys whose top bits are equal.
  void sortRanked() const {
    const std::size_t n = ranked_.size();
    if (n < 64) {
      std::sort(ranked_.begin(), ranked_.end());
      return;
    }
    scratch_.resize(n);
    for (int shift = 96; shift < 128; shift += 8) {
      const auto digit = [shift](Key key) { return static_cast<uint8_t>(key >> shift); };
      std::array<std::size_t, 256> start{};
      for (const Key key : ranked_) ++start[digit(key)];
      if (start[digit(ranked_[0])] == n) continue;
      std::size_t sum = 0;
      for (std::size_t& s : start) sum += std::exchange(s, sum);
      for (const Key key : ranked_) scratch_[start[digit(key)]++] = key;
      ranked_.swap(scratch_);
    }
    for (std::size_t i = 1; i < n; ++i) {
      const Key key = ranked_[i];
      std::size_t j = i;
      for (; j > 0 && key < ranked_[j - 1]; --j) ranked_[j] = ranked_[j - 1];
      ranked_[j] = key;
    }
  }

  using Key = unsigned __int128;

  Position position_;
  std::vector<Eigen::Vector3d> points_;  // position_(data_[i])
  mutable std::vector<double> distances_;
  mutable std::vector<Key> ranked_, scratch_;
};

}  // namespace thicket::explorer::detail
