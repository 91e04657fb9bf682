#include "sparseloop/matching/triangulation.h"

#include <cmath>

#include <Eigen/Dense>

#include "sparseloop/core/check.h"

namespace sparseloop {

void TriangulationOptions::Check() const {
  SL_CHECK_MSG(std::isfinite(max_reprojection_px) && max_reprojection_px > 0,
               "triangulation.max_reprojection_px must be > 0 pixels, got {}", max_reprojection_px);
  SL_CHECK_MSG(std::isfinite(min_parallax_deg) && min_parallax_deg >= 0 && min_parallax_deg < 90,
               "triangulation.min_parallax_deg must be in [0, 90) degrees, got {}",
               min_parallax_deg);
  match.Check();
}

TriangulationResult TriangulateFromNeighbours(const KeyframeRecord& record,
                                              const std::vector<const KeyframeRecord*>& neighbours,
                                              const TriangulationOptions& options) {
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
    const Sim3d n_from_r = n->world_from_cam.Inverse() * record.world_from_cam;
    const Eigen::Matrix3d sr = n_from_r.scale * n_from_r.rotation.toRotationMatrix();
    const Eigen::Matrix3d sr_inv = sr.inverse();  // once per neighbour, not per match
    const Eigen::Vector3d t = n_from_r.translation;
    if (t.norm() <= 0) continue;  // no baseline
    for (const DescriptorMatch& m :
         MatchDescriptors(record.descriptors, n->descriptors, options.match)) {
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
