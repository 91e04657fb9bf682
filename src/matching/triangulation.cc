#include "sparseloop/matching/triangulation.h"

#include <cmath>

#include <Eigen/Dense>

#include "matching/verification_internal.h"
#include "sparseloop/core/check.h"

namespace sparseloop {

void TriangulationOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(max_reprojection_px) && max_reprojection_px > 0,
               "triangulation.max_reprojection_px must be > 0 pixels, got {}", max_reprojection_px);
  SL_CHECK_MSG(std::isfinite(min_parallax_deg) && min_parallax_deg >= 0 && min_parallax_deg < 90,
               "triangulation.min_parallax_deg must be in [0, 90) degrees, got {}",
               min_parallax_deg);
  SL_CHECK_MSG(min_image_pose_inliers == 0 || min_image_pose_inliers >= 8,
               "triangulation.min_image_pose_inliers must be 0 (raw poses only) or >= 8, got {}",
               min_image_pose_inliers);
  SL_CHECK_MSG(std::isfinite(image_pose_prior_deg) && image_pose_prior_deg > 0 &&
                   image_pose_prior_deg <= kMaxImagePoseRotationChangeDeg,
               "triangulation.image_pose_prior_deg must be in (0, {}] degrees, got {}",
               kMaxImagePoseRotationChangeDeg, image_pose_prior_deg);
  match.Check();
}

namespace {

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

}  // namespace

std::optional<Sim3d> RelativePoseFromImages(const KeyframeRecord& a, const KeyframeRecord& b,
                                            const std::vector<DescriptorMatch>& matches,
                                            const Sim3d& raw_b_from_a, int min_inliers,
                                            double prior_deg, std::vector<int>* inliers) {
  const double baseline = raw_b_from_a.translation.norm();
  if (min_inliers <= 0 || static_cast<int>(matches.size()) < min_inliers || !(baseline > 0))
    return std::nullopt;
  // The two-view model is query_from_match with query = a, match = b: a_from_b, unit direction.
  const VerifyOptions verify;
  const float focal = std::max(1.0f, 0.5f * (a.focal_px + b.focal_px));
  const matching_internal::TwoViewData data =
      matching_internal::MakeTwoViewData(a, b, matches, verify.threshold_px / focal);
  const Eigen::Matrix3d r_ba = raw_b_from_a.rotation.toRotationMatrix();
  matching_internal::TwoViewModel model{
      r_ba.transpose(), (-r_ba.transpose() * raw_b_from_a.translation).normalized()};
  // The raw pose as a prior of `prior_deg` per axis against image noise of half the inlier
  // threshold: where the matches fix the pose (roll about the optical axis, rotation with the
  // baseline known) they win; where two views leave it loose (the rotation / translation
  // ambiguity of a narrow field of view) it stays near the raw pose.
  model.prior_weight = 0.5 * data.threshold / (prior_deg * M_PI / 180.0);
  model.prior_r = model.r;
  model.prior_t = model.t;
  const std::vector<uint8_t> in =
      matching_internal::RefineFromPrior(data, std::sin(kImagePoseFirstThresholdDeg * M_PI / 180.0),
                                         verify.local_optimization_rounds, &model);
  std::vector<int> agree;
  for (size_t i = 0; i < in.size(); ++i)
    if (in[i]) agree.push_back(static_cast<int>(i));
  if (static_cast<int>(agree.size()) < min_inliers) return std::nullopt;
  Sim3d out = raw_b_from_a;
  out.rotation = Eigen::Quaterniond(model.r.transpose()).normalized();
  const Eigen::Vector3d direction = (-model.r.transpose() * model.t).normalized();
  if (out.rotation.angularDistance(raw_b_from_a.rotation) * 180.0 / M_PI >
          kMaxImagePoseRotationChangeDeg ||
      AngleDeg(direction, raw_b_from_a.translation) > kMaxImagePoseDirectionChangeDeg)
    return std::nullopt;
  out.translation = direction * baseline;
  if (inliers != nullptr) *inliers = std::move(agree);
  return out;
}

std::optional<Sim3d> RelativePoseCache::Get(const KeyframeRecord& a, const KeyframeRecord& b,
                                            const std::vector<DescriptorMatch>& matches,
                                            const Sim3d& raw_b_from_a,
                                            const TriangulationOptions& options) {
  const auto pa = reinterpret_cast<uintptr_t>(&a), pb = reinterpret_cast<uintptr_t>(&b);
  const bool a_first = pa < pb;
  const auto key = a_first ? std::make_pair(pa, pb) : std::make_pair(pb, pa);
  auto it = second_from_first_.find(key);
  if (it == second_from_first_.end()) {
    std::optional<Sim3d> b_from_a = RelativePoseFromImages(
        a, b, matches, raw_b_from_a, options.min_image_pose_inliers, options.image_pose_prior_deg);
    if (b_from_a && !a_first) b_from_a = b_from_a->Inverse();
    it = second_from_first_.emplace(key, b_from_a).first;
  }
  if (!it->second || a_first) return it->second;
  return it->second->Inverse();
}

TriangulationResult TriangulateFromNeighbours(const KeyframeRecord& record,
                                              const std::vector<const KeyframeRecord*>& neighbours,
                                              const TriangulationOptions& options,
                                              RelativePoseCache* cache) {
  options.Check();
  SL_CHECK_MSG(record.has_pose, "triangulation needs the record's raw pose (keyframe {})",
               record.id);
  TriangulationResult out;
  out.depths.assign(record.size(), 0.0f);
  std::vector<double> best_parallax(record.size(), 0.0);
  const double min_sin = std::sin(options.min_parallax_deg * M_PI / 180.0);
  for (const KeyframeRecord* n : neighbours) {
    if (n == nullptr || !n->has_pose || n->size() == 0) continue;
    const float focal = std::max(1.0f, 0.5f * (record.focal_px + n->focal_px));
    const double max_err = options.max_reprojection_px / focal;
    // Point X in the record's camera frame maps to the neighbour's as s R X + t.
    Sim3d n_from_r = n->world_from_cam.Inverse() * record.world_from_cam;
    if (n_from_r.translation.norm() <= 0) continue;  // no baseline
    const std::vector<DescriptorMatch> matches =
        MatchDescriptors(record.descriptors, n->descriptors, options.match);
    const std::optional<Sim3d> from_images =
        cache != nullptr
            ? cache->Get(record, *n, matches, n_from_r, options)
            : RelativePoseFromImages(record, *n, matches, n_from_r, options.min_image_pose_inliers,
                                     options.image_pose_prior_deg);
    ++(from_images ? out.image_poses : out.raw_poses);
    if (from_images) n_from_r = *from_images;
    const Eigen::Matrix3d sr = n_from_r.scale * n_from_r.rotation.toRotationMatrix();
    const Eigen::Matrix3d sr_inv = sr.inverse();  // once per neighbour, not per match
    const Eigen::Vector3d t = n_from_r.translation;
    for (const DescriptorMatch& m : matches) {
      const CompactKeypoint& kr = record.keypoints[m.query];
      const CompactKeypoint& kn = n->keypoints[m.train];
      const Eigen::Vector3d fr(kr.x, kr.y, 1.0);
      const Eigen::Vector3d fn(kn.x, kn.y, 1.0);
      const Eigen::Vector3d a = sr * fr;  // record ray, in the neighbour's frame
      // Parallax: angle between the two rays.
      const double sin_par = a.normalized().cross(fn.normalized()).norm();
      if (sin_par < min_sin || sin_par <= best_parallax[m.query]) continue;
      // Midpoint: d_r a - d_n fn = -t in the least-squares sense.
      Eigen::Matrix<double, 3, 2> A;
      A.col(0) = a;
      A.col(1) = -fn;
      const Eigen::Vector2d d = A.colPivHouseholderQr().solve(-t);
      if (!(d(0) > 0 && d(1) > 0)) continue;
      const Eigen::Vector3d x_r = d(0) * fr;     // in the record's frame
      const Eigen::Vector3d x_n = sr * x_r + t;  // in the neighbour's frame
      if (x_n.z() <= 0) continue;
      // Reprojection in both views: each ray's point into the other view.
      const double err_n = (x_n.head<2>() / x_n.z() - fn.head<2>()).norm();
      const Eigen::Vector3d y_n = d(1) * fn;           // neighbour's point
      const Eigen::Vector3d y_r = sr_inv * (y_n - t);  // in the record's frame
      if (y_r.z() <= 0) continue;
      const double err_r = (y_r.head<2>() / y_r.z() - fr.head<2>()).norm();
      if (err_n > max_err || err_r > max_err) continue;
      best_parallax[m.query] = sin_par;
      out.depths[m.query] = static_cast<float>(0.5 * (x_r.z() + y_r.z()));
    }
  }
  for (float d : out.depths) out.triangulated += d > 0 ? 1 : 0;
  return out;
}

}  // namespace sparseloop
