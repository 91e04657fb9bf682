#pragma once
// Brute-force Hamming matching of two small descriptor sets (K x K popcounts on 64-bit words).
#include <compare>
#include <cstddef>
#include <functional>
#include <span>
#include <vector>

#include "sparseloop/features/informative_features.h"

namespace sparseloop {

struct MatchOptions {
  int max_distance = 64;  // largest accepted Hamming distance, bits (of 256)
  double ratio = 0.9;     // best < ratio * second best (1 = no ratio test), ratio in (0, 1]
  bool mutual = true;     // keep a match only when it is also best in the other direction
  void Check() const;
};

struct DescriptorMatch {
  int query = 0;     // index into the query descriptors
  int train = 0;     // index into the candidate descriptors
  int distance = 0;  // Hamming distance, bits
};

// Matches every query descriptor against `train`; result sorted by query index. Deterministic.
std::vector<DescriptorMatch> MatchDescriptors(std::span<const Descriptor> query,
                                              std::span<const Descriptor> train,
                                              const MatchOptions& options);

// Asymmetric matching: a small stored set (a record's K descriptors) against a query's whole
// extraction. Every stored descriptor finds its best among `query`; the ratio test runs on that
// side (best < ratio x second best among the query's many, which is what tells a repeated corner
// from a chance one), mutual as in MatchDescriptors. Indices as MatchDescriptors(query, stored)
// (query = index into `query`, train = index into `stored`), sorted by query index.
// Deterministic.
std::vector<DescriptorMatch> MatchStoredIntoQuery(std::span<const Descriptor> query,
                                                  std::span<const Descriptor> stored,
                                                  const MatchOptions& options);

// The same on vectors (also braced lists of descriptors).
inline std::vector<DescriptorMatch> MatchDescriptors(const std::vector<Descriptor>& query,
                                                     const std::vector<Descriptor>& train,
                                                     const MatchOptions& options) {
  return MatchDescriptors(std::span<const Descriptor>(query), std::span<const Descriptor>(train),
                          options);
}
inline std::vector<DescriptorMatch> MatchStoredIntoQuery(const std::vector<Descriptor>& query,
                                                         const std::vector<Descriptor>& stored,
                                                         const MatchOptions& options) {
  return MatchStoredIntoQuery(std::span<const Descriptor>(query),
                              std::span<const Descriptor>(stored), options);
}

// Score of a match set: sum over matches of (max_distance + 1 - distance) / (max_distance + 1).
double MatchScore(const std::vector<DescriptorMatch>& matches, int max_distance);

// A cheap appearance score of a stored descriptor set against a small probe set (the appearance
// fallback's pre-ranking, LoopDetector::Options::fallback_candidates): `found` = stored
// descriptors whose nearest probe descriptor lies within max_distance bits, `closeness` = the sum
// of (max_distance + 1 - that distance) over them. No ratio test, no mutual check: stored x probe
// Hamming distances and nothing else. Ordered by found, then closeness (more is better).
struct ProbeScore {
  int found = 0;
  int closeness = 0;
  auto operator<=>(const ProbeScore&) const = default;
};
ProbeScore ScoreAgainstProbe(std::span<const Descriptor> stored, std::span<const Descriptor> probe,
                             int max_distance);

// Ranking many stored keyframes by ScoreAgainstProbe (the appearance fallback's pre-ranking).
struct ProbeRankOptions {
  size_t keep = 20;  // keyframes returned, best first
  // Coarse stage, when there are more than coarse_keep keyframes: score each by its first
  // coarse_features stored descriptors only (a record keeps its best-ranked first), keep the
  // coarse_keep best, then score those with all their descriptors. 0: one stage.
  size_t coarse_features = 0;
  size_t coarse_keep = 200;
  // The coarse stage compares with the probe's first coarse_probe descriptors only (0: all of
  // them): at K = 300 the coarse stage over 10,000 keyframes is most of the fallback's time.
  size_t coarse_probe = 0;
  // The last stage scores each keyframe by its first fine_features stored descriptors (0: all):
  // at a large K the full K x probe score of every coarse survivor is the fallback's main cost.
  size_t fine_features = 0;
  int max_distance = 64;  // bits
};
// Indices (into 0..n-1) of the `keep` best keyframes, best first (ties: lower index first); all of
// them, in index order, when n <= keep. `stored(i)` gives keyframe i's descriptors.
std::vector<size_t> RankByProbe(size_t n,
                                const std::function<std::span<const Descriptor>(size_t)>& stored,
                                std::span<const Descriptor> probe, const ProbeRankOptions& options);

}  // namespace sparseloop
