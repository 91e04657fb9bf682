#pragma once
// Internal to the loop module: Hamming matching of a query against candidate records and their
// ranking, shared by the in-session search (candidate_verification.cc) and the appearance-only
// pool of relocalisation and prior sessions (prior_sessions.cc), so that both rank identically.
#include <algorithm>
#include <cstddef>
#include <vector>

#include "sparseloop/matching/descriptor_matching.h"

namespace sparseloop::loop_internal {

// Hamming matching of the query against each candidate record, then the candidates with at least
// `min_matches` ranked by match count, then score, then `tie_key` (ascending).
struct RankedCandidate {
  size_t entry;  // position in the candidate list
  std::vector<DescriptorMatch> matches;
  double score;
  size_t tie_key;
};
struct CandidateRanking {
  std::vector<RankedCandidate> ranked;
  int best_count = 0;     // most matches of any candidate (also below min_matches)
  size_t best_entry = 0;  // its position in the candidate list
};

template <typename RecordAt, typename TieKey, typename Match>
CandidateRanking RankCandidates(size_t num_candidates, RecordAt&& record_at, TieKey&& tie_key,
                                Match&& match, int min_matches, int max_distance) {
  CandidateRanking out;
  for (size_t e = 0; e < num_candidates; ++e) {
    auto m = match(record_at(e));
    const int n = static_cast<int>(m.size());
    if (n > out.best_count) {
      out.best_count = n;
      out.best_entry = e;
    }
    if (n < min_matches) continue;
    const double s = MatchScore(m, max_distance);
    out.ranked.push_back({e, std::move(m), s, tie_key(e)});
  }
  std::sort(out.ranked.begin(), out.ranked.end(),
            [](const RankedCandidate& a, const RankedCandidate& b) {
              if (a.matches.size() != b.matches.size()) return a.matches.size() > b.matches.size();
              if (a.score != b.score) return a.score > b.score;
              return a.tie_key < b.tie_key;
            });
  return out;
}

}  // namespace sparseloop::loop_internal
