#pragma once
// The keyframes of earlier map sessions (LoopDetector::AddPriorKeyframes), packed as this
// session's are, with the K each session was stored with. The detector searches them by
// appearance only (their world frames are not this session's).
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "sparseloop/features/informative_features.h"

namespace sparseloop {

class PriorSessions {
 public:
  // Adds session `session` (> 0, once) whole, or throws std::invalid_argument and adds nothing
  // (duplicate ids, focal_px <= 0, sizes that disagree, a pose that is not finite).
  void Add(int64_t session, std::vector<KeyframeRecord> records);
  // The record `id` of `session`, unpacked; throws std::invalid_argument when unknown.
  KeyframeRecord Record(int64_t session, int64_t id) const;

  size_t size() const { return records_.size(); }
  bool empty() const { return records_.empty(); }
  const PackedKeyframe& record(size_t i) const { return records_[i]; }
  int64_t session(size_t i) const { return session_[i]; }
  // Features per keyframe `session` was stored with (its records' most), by session.
  int K(int64_t session) const { return k_.at(session); }
  const std::unordered_map<int64_t, int>& ks() const { return k_; }

 private:
  std::vector<PackedKeyframe> records_;
  std::vector<int64_t> session_;  // of each record
  std::unordered_map<int64_t, int> k_;
  std::unordered_map<int64_t, std::unordered_map<int64_t, size_t>> index_;  // session, id
};

}  // namespace sparseloop
