#include "sparseloop/core/time_association.h"

#include <algorithm>
#include <functional>
#include <numeric>
#include <queue>
#include <tuple>

#include "sparseloop/core/check.h"

namespace sparseloop {

namespace {

// The free slots of n references in time order, after some were taken: the first free slot at or
// after a position and the last one before it, in near-constant time (skip links with path
// halving).
class FreeSlots {
 public:
  explicit FreeSlots(size_t n) : next_(n + 1), prev_(n + 1) {
    std::iota(next_.begin(), next_.end(), size_t{0});
    std::iota(prev_.begin(), prev_.end(), size_t{0});
  }
  std::optional<size_t> AtOrAfter(size_t k) {
    const size_t s = Find(next_, k);
    return s + 1 == next_.size() ? std::nullopt : std::optional<size_t>(s);
  }
  // prev_[k] == k: slot k - 1 is free (k = 0: no slot before).
  std::optional<size_t> Before(size_t k) {
    const size_t s = Find(prev_, k);
    return s == 0 ? std::nullopt : std::optional<size_t>(s - 1);
  }
  bool Free(size_t slot) const { return next_[slot] == slot; }
  void Take(size_t slot) {
    next_[slot] = slot + 1;
    prev_[slot + 1] = slot;
  }

 private:
  static size_t Find(std::vector<size_t>& link, size_t k) {
    while (link[k] != k) k = link[k] = link[link[k]];
    return k;
  }
  std::vector<size_t> next_, prev_;
};

}  // namespace

std::vector<std::optional<size_t>> AssociateInTime(const std::vector<double>& queries,
                                                   const std::vector<double>& references,
                                                   double max_dt, TimePairing pairing) {
  SL_CHECK_MSG(std::isfinite(max_dt) && max_dt >= 0.0, "max_dt must be >= 0 s, got {}", max_dt);
  // The references in time order: slot k holds references[order[k]].
  std::vector<size_t> order(references.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return references[a] < references[b]; });
  std::vector<double> stamps(order.size());
  for (size_t k = 0; k < order.size(); ++k) stamps[k] = references[order[k]];
  FreeSlots free(stamps.size());

  // The slot query i takes among the free ones: the rule between its two free neighbours (the
  // first of a run of equal stamps before it).
  const auto nearest_free = [&](size_t i) -> std::optional<size_t> {
    const double t = queries[i];
    const size_t first_after =
        static_cast<size_t>(std::lower_bound(stamps.begin(), stamps.end(), t) - stamps.begin());
    const std::optional<size_t> after = free.AtOrAfter(first_after);
    std::optional<size_t> before = free.Before(first_after);
    for (auto earlier = before ? free.Before(*before) : std::nullopt;
         earlier && stamps[*earlier] == stamps[*before]; earlier = free.Before(*earlier)) {
      before = earlier;
    }
    return time_association_internal::Nearer<size_t>(before, after, t, max_dt,
                                                     [&](size_t slot) { return stamps[slot]; });
  };

  // Each query's proposal (|dt|, query, slot), smallest first. A proposal whose slot was taken
  // meanwhile is renewed: proposals only get worse as slots go, so the smallest valid one is the
  // greedy's next pair. With kNearest no slot is ever taken and every first proposal stands.
  using Proposal = std::tuple<double, size_t, size_t>;
  std::priority_queue<Proposal, std::vector<Proposal>, std::greater<>> proposals;
  const auto propose = [&](size_t i) {
    if (const auto slot = nearest_free(i)) {
      proposals.emplace(std::abs(stamps[*slot] - queries[i]), i, *slot);
    }
  };
  for (size_t i = 0; i < queries.size(); ++i) propose(i);
  std::vector<std::optional<size_t>> partner(queries.size());
  while (!proposals.empty()) {
    const size_t i = std::get<1>(proposals.top()), slot = std::get<2>(proposals.top());
    proposals.pop();
    if (!free.Free(slot)) {
      propose(i);
      continue;
    }
    partner[i] = order[slot];
    if (pairing == TimePairing::kOneToOne) free.Take(slot);
  }
  return partner;
}

}  // namespace sparseloop
