#pragma once
// Brute-force oracle of the search-area definition in docs/SEARCH_AREA.md: loops over every
// segment and every keyframe, no grid, no pruning. Used to check SearchArea exactly.
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "sparseloop/search/search_area.h"

namespace sparseloop::test {

struct OracleAnswer {
  std::vector<int> candidates;  // keyframe indices, ascending
  SearchAreaStatus status = SearchAreaStatus::kTooShort;
  PaperBranch branch = PaperBranch::kNotRun;
  int start = -1;  // index
  int end = -1;    // index
};

namespace oracle_detail {
inline double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}
// s >= 0 on the ray origin + s dir where it meets a + l (b - a), l in [0,1] (or l >= 0).
inline double Intersect(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir,
                        const Eigen::Vector2d& a, const Eigen::Vector2d& b, bool half_line) {
  const Eigen::Vector2d e = b - a;
  const double denom = Cross(dir, e);
  if (std::abs(denom) <= 1e-12 * e.norm()) return std::numeric_limits<double>::infinity();
  const Eigen::Vector2d w = a - origin;
  const double s = Cross(w, e) / denom;
  const double l = Cross(w, dir) / denom;
  if (s < 0.0 || l < 0.0 || (!half_line && l > 1.0)) return std::numeric_limits<double>::infinity();
  return s;
}
inline bool InWedge(const Eigen::Vector2d& w, const Eigen::Vector2d& dir, double alpha, int side) {
  if (w.squaredNorm() == 0.0) return true;
  const double theta = std::atan2(Cross(dir, w), dir.dot(w));
  if (side == 0) return std::abs(theta) <= alpha + 1e-9;
  return side * theta >= -1e-9 && side * theta <= alpha + 1e-9;
}
}  // namespace oracle_detail

// positions[0..t] are the keyframes added so far (at least up to t); `plane` the frame the
// SearchArea used; `loops` every accepted loop (query, match index) in order (the uncertainty area
// reads the last o.drift_loops).
inline OracleAnswer BruteForceSearchArea(const std::vector<Eigen::Vector3d>& positions,
                                         const PlaneFrame& plane, const SearchAreaOptions& o, int t,
                                         const std::vector<std::pair<int, int>>& loops = {}) {
  using namespace oracle_detail;
  const double inf = std::numeric_limits<double>::infinity();
  OracleAnswer ans;
  std::vector<Eigen::Vector2d> q;
  std::vector<double> L;
  for (int k = 0; k <= t; ++k) {
    q.push_back(plane.Project(positions[k]));
    L.push_back(k == 0 ? 0.0 : L.back() + (positions[k] - positions[k - 1]).norm());
  }
  const int E = std::max(0, t - o.exclude_recent);
  if (E <= 0) return ans;
  auto done = [&](std::vector<int> c) {
    // The uncertainty area (drift_rate): |x_k - centre| <= base + rate * odometry on the path
    // with the least odometry, directly or through one of the last drift_loops loops (the
    // earliest such path wins a tie).
    if (o.drift_rate > 0.0 && t >= 1) {
      const double base = o.drift_base_steps * L[t] / t;
      std::vector<std::pair<int, int>> paths = {{t, t}};
      const size_t first =
          loops.size() - std::min(loops.size(), static_cast<size_t>(o.drift_loops));
      paths.insert(paths.end(), loops.begin() + static_cast<std::ptrdiff_t>(first), loops.end());
      std::vector<std::pair<double, int>> inside;  // (distance / radius, k)
      for (int k = 0; k < E; ++k) {
        double best = std::numeric_limits<double>::infinity();
        Eigen::Vector3d centre = Eigen::Vector3d::Zero();
        for (const auto& [lq, lm] : paths) {
          const double odometry = std::abs(L[t] - L[lq]) + std::abs(L[lm] - L[k]);
          if (odometry < best) {
            best = odometry;
            centre = positions[lm] + (positions[t] - positions[lq]);
          }
        }
        const double d = (positions[k] - centre).norm();
        const double r = base + o.drift_rate * best;
        if (d <= r) inside.emplace_back(r > 0.0 ? d / r : 0.0, k);
      }
      // The drift_max_candidates nearest relative to their radius, then the lower index.
      std::sort(inside.begin(), inside.end());
      if (inside.size() > static_cast<size_t>(o.drift_max_candidates))
        inside.resize(static_cast<size_t>(o.drift_max_candidates));
      for (const auto& [ratio, k] : inside) c.push_back(k);
      std::sort(c.begin(), c.end());
      c.erase(std::unique(c.begin(), c.end()), c.end());
    }
    ans.candidates = std::move(c);
    ans.status = ans.candidates.empty() ? SearchAreaStatus::kEmpty : SearchAreaStatus::kOk;
    return ans;
  };
  std::vector<int> c;
  if (o.strategy == SearchStrategy::kGlobal) {
    for (int k = 0; k < E; ++k) c.push_back(k);
    return done(c);
  }
  if (o.strategy == SearchStrategy::kRadius) {
    for (int k = 0; k < E; ++k) {
      const double d =
          o.radius_in_plane ? (q[k] - q[t]).norm() : (positions[k] - positions[t]).norm();
      if (d <= o.radius) c.push_back(k);
    }
    return done(c);
  }
  Eigen::Vector2d dir = Eigen::Vector2d::Zero();
  for (int j = t - 1; j >= 0 && j >= t - o.motion_lookback; --j) {
    if ((q[t] - q[j]).norm() >= o.min_motion) {
      dir = (q[t] - q[j]).normalized();
      break;
    }
  }
  if (dir.isZero()) {
    ans.status = SearchAreaStatus::kNoMotion;
    return ans;
  }
  // First hit over ALL eligible segments, then the backward half-line (index 0 wins ties).
  double best_s = inf;
  int best_seg = -1;
  for (int k = 1; k < E; ++k) {
    const double s = Intersect(q[t], dir, q[k - 1], q[k], false);
    if (s < best_s) {  // ascending k: the smallest index wins a tie
      best_s = s;
      best_seg = k;
    }
  }
  for (int j = 1; j <= std::min(E - 1, o.motion_lookback); ++j) {
    if ((q[0] - q[j]).norm() >= o.min_motion) {
      const double s = Intersect(q[t], dir, q[0], q[0] + (q[0] - q[j]).normalized(), true);
      if (s <= best_s && s < inf) {
        best_s = s;
        best_seg = 0;
      }
      break;
    }
  }
  auto nearest = [&](const Eigen::Vector2d& x) {
    int best = -1;
    double bd = inf;
    for (int k = 0; k < E; ++k) {
      const double d2 = (q[k] - x).squaredNorm();
      if (d2 < bd) {
        bd = d2;
        best = k;
      }
    }
    return best;
  };
  int lo = 0, hi = 0, side = 0;
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  if (best_seg < 0) {
    ans.branch = PaperBranch::kNoIntersection;
    hi = std::min(E - 1, o.fallback_count - 1);
  } else {
    ans.branch = best_seg == 0 ? PaperBranch::kBackwardRayHit : PaperBranch::kSegmentHit;
    p = q[t] + best_s * dir;
    ans.start = nearest(p);
    const Eigen::Vector2d n(-dir.y(), dir.x());
    double sl = inf, sr = inf;
    int kl = -1, kr = -1;
    for (int k = 1; k < E; ++k) {
      const double a = Intersect(q[t], n, q[k - 1], q[k], false);
      const double b = Intersect(q[t], -n, q[k - 1], q[k], false);
      if (a < sl) sl = a, kl = k;
      if (b < sr) sr = b, kr = k;
    }
    if (kl >= 0 || kr >= 0) {
      side = sl <= sr ? 1 : -1;
      ans.end = nearest(q[t] + (side > 0 ? sl : sr) * side * n);
      lo = std::min(ans.start, ans.end);
      hi = std::max(ans.start, ans.end);
    } else {
      lo = std::max(0, ans.start - o.fallback_count / 2);
      hi = std::min(E - 1, ans.start + o.fallback_count / 2);
    }
  }
  if (ans.branch == PaperBranch::kNoIntersection) {
    for (int k = lo; k <= hi; ++k) c.push_back(k);
    return done(c);
  }
  const double alpha = o.alpha_deg * 3.14159265358979323846 / 180.0;
  for (int k = 0; k < E; ++k) {
    const Eigen::Vector2d w = q[k] - q[t];
    bool in = k == ans.start || k == ans.end;
    if (!in && k >= lo && k <= hi) in = InWedge(w, dir, alpha, side);
    if (in) c.push_back(k);
  }
  return done(c);
}

}  // namespace sparseloop::test
