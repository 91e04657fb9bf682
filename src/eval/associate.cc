#include "sparseloop/eval/associate.h"

#include <cmath>
#include <unordered_map>

#include "sparseloop/core/check.h"
#include "sparseloop/core/time_association.h"

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

// TUM associate.py's one-to-one pairing, by core's rule (core/time_association.h).
Association AssociateByTime(const Trajectory& est, const Trajectory& gt,
                            const AssociationOptions& options) {
  std::vector<double> est_times, gt_times;
  for (const StampedPose& p : est.poses) est_times.push_back(p.timestamp + options.offset);
  for (const StampedPose& p : gt.poses) gt_times.push_back(p.timestamp);
  const auto partner = AssociateInTime(est_times, gt_times, options.max_dt, TimePairing::kOneToOne);
  Association out;
  for (size_t i = 0; i < partner.size(); ++i) {
    if (partner[i]) out.pairs.emplace_back(i, *partner[i]);
  }
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
