#include "sparseloop/matching/descriptor_matching.h"

#include <algorithm>
#include <climits>
#include <cmath>

#include "sparseloop/core/check.h"

namespace sparseloop {

void MatchOptions::Check() const {
  SL_CHECK_MSG(max_distance >= 0 && max_distance <= 256,
               "match.max_distance must be in [0, 256] bits, got {}", max_distance);
  SL_CHECK_MSG(std::isfinite(ratio) && ratio > 0 && ratio <= 1.0,
               "match.ratio must be in (0, 1], got {}", ratio);
}

std::vector<DescriptorMatch> MatchDescriptors(std::span<const Descriptor> query,
                                              std::span<const Descriptor> train,
                                              const MatchOptions& options) {
  options.Check();
  std::vector<DescriptorMatch> matches;
  if (query.empty() || train.empty()) return matches;
  const int nq = static_cast<int>(query.size());
  const int nt = static_cast<int>(train.size());
  std::vector<int> best_t(nq, -1), best_d(nq, INT_MAX), second_d(nq, INT_MAX);
  std::vector<int> best_q_for_t(nt, -1), best_d_for_t(nt, INT_MAX);
  for (int i = 0; i < nq; ++i) {
    for (int j = 0; j < nt; ++j) {
      const int d = HammingDistance(query[i], train[j]);
      if (d < best_d[i]) {
        second_d[i] = best_d[i];
        best_d[i] = d;
        best_t[i] = j;
      } else if (d < second_d[i]) {
        second_d[i] = d;
      }
      if (d < best_d_for_t[j]) {
        best_d_for_t[j] = d;
        best_q_for_t[j] = i;
      }
    }
  }
  for (int i = 0; i < nq; ++i) {
    if (best_t[i] < 0 || best_d[i] > options.max_distance) continue;
    if (options.ratio < 1.0 && second_d[i] != INT_MAX && !(best_d[i] < options.ratio * second_d[i]))
      continue;
    if (options.mutual && best_q_for_t[best_t[i]] != i) continue;
    matches.push_back({i, best_t[i], best_d[i]});
  }
  return matches;
}

std::vector<DescriptorMatch> MatchStoredIntoQuery(std::span<const Descriptor> query,
                                                  std::span<const Descriptor> stored,
                                                  const MatchOptions& options) {
  std::vector<DescriptorMatch> matches = MatchDescriptors(stored, query, options);
  for (DescriptorMatch& m : matches) std::swap(m.query, m.train);
  std::sort(matches.begin(), matches.end(),
            [](const DescriptorMatch& a, const DescriptorMatch& b) { return a.query < b.query; });
  return matches;
}

double MatchScore(const std::vector<DescriptorMatch>& matches, int max_distance) {
  double s = 0;
  for (const auto& m : matches) s += double(max_distance + 1 - m.distance) / (max_distance + 1);
  return s;
}

ProbeScore ScoreAgainstProbe(std::span<const Descriptor> stored, std::span<const Descriptor> probe,
                             int max_distance) {
  ProbeScore score;
  for (const Descriptor& d : stored) {
    int nearest = max_distance + 1;
    for (const Descriptor& p : probe) nearest = std::min(nearest, HammingDistance(d, p));
    if (nearest > max_distance) continue;
    ++score.found;
    score.closeness += max_distance + 1 - nearest;
  }
  return score;
}

}  // namespace sparseloop
