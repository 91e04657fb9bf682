#include "sparseloop/eval/associate.h"

#include <algorithm>
#include <cmath>
#include <tuple>
#include <unordered_map>

#include "sparseloop/core/check.h"

namespace sparseloop {

AssociationMethod ParseAssociationMethod(const std::string& name) {
  if (name == "time" || name == "timestamp") return AssociationMethod::kTimestamp;
  if (name == "index") return AssociationMethod::kIndex;
  SL_CHECK_MSG(false, "unknown association '{}', expected time or index", name);
  return AssociationMethod::kTimestamp;
}

std::string ToString(AssociationMethod method) {
  return method == AssociationMethod::kIndex ? "index" : "time";
}

void AssociationOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(max_dt) && max_dt >= 0.0, "max_dt must be >= 0 s, got {}", max_dt);
  SL_CHECK_MSG(std::isfinite(offset), "offset must be finite, got {}", offset);
}

namespace {

Association AssociateByIndex(const Trajectory& est, const Trajectory& gt) {
  std::unordered_map<int64_t, size_t> gt_by_frame;
  gt_by_frame.reserve(gt.size());
  for (size_t j = 0; j < gt.size(); ++j) {
    const bool inserted = gt_by_frame.emplace(gt.poses[j].frame, j).second;
    SL_CHECK_MSG(inserted, "index association: gt frame id {} appears twice", gt.poses[j].frame);
  }
  Association out;
  std::unordered_map<int64_t, size_t> seen_est;
  for (size_t i = 0; i < est.size(); ++i) {
    const bool inserted = seen_est.emplace(est.poses[i].frame, i).second;
    SL_CHECK_MSG(inserted, "index association: estimate frame id {} appears twice",
                 est.poses[i].frame);
    const auto it = gt_by_frame.find(est.poses[i].frame);
    if (it != gt_by_frame.end()) out.pairs.emplace_back(i, it->second);
  }
  return out;
}

Association AssociateByTime(const Trajectory& est, const Trajectory& gt,
                            const AssociationOptions& options) {
  // gt indices sorted by time, to find the candidates of each est pose by binary search.
  std::vector<size_t> gt_order(gt.size());
  for (size_t j = 0; j < gt.size(); ++j) gt_order[j] = j;
  std::stable_sort(gt_order.begin(), gt_order.end(), [&](size_t a, size_t b) {
    return gt.poses[a].timestamp < gt.poses[b].timestamp;
  });
  std::vector<double> gt_times(gt.size());
  for (size_t k = 0; k < gt.size(); ++k) gt_times[k] = gt.poses[gt_order[k]].timestamp;

  // (|dt|, est index, gt index) for every candidate.
  std::vector<std::tuple<double, size_t, size_t>> candidates;
  for (size_t i = 0; i < est.size(); ++i) {
    const double t = est.poses[i].timestamp + options.offset;
    auto it = std::lower_bound(gt_times.begin(), gt_times.end(), t - options.max_dt);
    for (; it != gt_times.end() && *it <= t + options.max_dt; ++it) {
      const double dt = std::abs(*it - t);
      if (dt <= options.max_dt) {
        candidates.emplace_back(dt, i, gt_order[static_cast<size_t>(it - gt_times.begin())]);
      }
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<bool> est_used(est.size(), false);
  std::vector<bool> gt_used(gt.size(), false);
  Association out;
  for (const auto& [dt, i, j] : candidates) {
    if (est_used[i] || gt_used[j]) continue;
    est_used[i] = true;
    gt_used[j] = true;
    out.pairs.emplace_back(i, j);
  }
  std::sort(out.pairs.begin(), out.pairs.end());
  return out;
}

}  // namespace

Association Associate(const Trajectory& est, const Trajectory& gt,
                      const AssociationOptions& options) {
  options.Check();
  if (options.method == AssociationMethod::kIndex) return AssociateByIndex(est, gt);
  return AssociateByTime(est, gt, options);
}

}  // namespace sparseloop
