#pragma once
// The one timestamp-association rule (docs/METRICS.md, "Timestamp association"). Every pairing of
// stamped data goes through it: raw poses, step covariances and GT to a dataset's frames
// (pipeline, io), the ROS node's raw pose of each image, the GT pose of a detected loop's frames,
// and `sparseloop eval`'s pairing of an estimate with GT.
//
// A reference stamp r can take a query stamp t when |r - t| <= max_dt. Of those that can, the
// query takes the nearest; on a tie the earlier (the smaller stamp, then the lower index).
//  - TimePairing::kNearest: each query on its own; a reference may serve several queries
//    (a frame takes the pose nearest its stamp). NearestInTime is this rule for one query.
//  - TimePairing::kOneToOne: every query and every reference at most once, as TUM's
//    associate.py pairs an estimate with GT: the candidate pairs are taken greedily by increasing
//    |dt|, ties by the lower query index, then the earlier reference. It equals kNearest whenever
//    no two queries are within 2 max_dt of each other (max_dt below half the smaller sampling
//    period): then no reference is a candidate of two queries.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <iterator>
#include <optional>
#include <vector>

namespace sparseloop {

enum class TimePairing { kNearest, kOneToOne };

// The partner of each query (index into `references`, nullopt: none) under `pairing`. Stamps in
// seconds, in any order (references are searched in time order; equal stamps keep their order).
// max_dt >= 0 and finite, else std::invalid_argument. O((n + m) log(n + m)).
std::vector<std::optional<size_t>> AssociateInTime(const std::vector<double>& queries,
                                                   const std::vector<double>& references,
                                                   double max_dt, TimePairing pairing);

namespace time_association_internal {

// The rule between the two neighbours of t (nullopt: none): `before` the latest reference stamped
// before t, `after` the earliest at or after t; nothing further can be nearer. Returns the one t
// takes, if any.
template <typename T, typename StampOf>
std::optional<T> Nearer(const std::optional<T>& before, const std::optional<T>& after, double t,
                        double max_dt, StampOf stamp_of) {
  const bool before_wins =
      before && (!after || std::abs(stamp_of(*before) - t) <= std::abs(stamp_of(*after) - t));
  const std::optional<T>& best = before_wins ? before : after;
  if (best && std::abs(stamp_of(*best) - t) <= max_dt) return best;
  return std::nullopt;
}

}  // namespace time_association_internal

// The rule for one query over references in time order, for containers with their own search
// (std::map::lower_bound): `after` is the first element stamped at or after t. Returns the
// element t takes, `end` when none.
template <typename It, typename StampOf>
It NearestInTime(It begin, It after, It end, double t, double max_dt, StampOf stamp_of) {
  std::optional<It> before;
  if (after != begin) {
    It first = std::prev(after);  // the first of a run of equal stamps
    while (first != begin && stamp_of(*std::prev(first)) == stamp_of(*first)) --first;
    before = first;
  }
  return time_association_internal::Nearer<It>(
             before, after == end ? std::nullopt : std::optional<It>(after), t, max_dt,
             [&](It it) { return stamp_of(*it); })
      .value_or(end);
}

// The rule for one query over a random-access range in time order (ascending by stamp_of): the
// index of the element t takes, if any.
template <typename Range, typename StampOf>
std::optional<size_t> NearestInTime(const Range& sorted, double t, double max_dt,
                                    StampOf stamp_of) {
  const auto begin = std::begin(sorted), end = std::end(sorted);
  const auto after =
      std::lower_bound(begin, end, t, [&](const auto& e, double v) { return stamp_of(e) < v; });
  const auto best = NearestInTime(begin, after, end, t, max_dt, stamp_of);
  if (best == end) return std::nullopt;
  return static_cast<size_t>(std::distance(begin, best));
}

}  // namespace sparseloop
