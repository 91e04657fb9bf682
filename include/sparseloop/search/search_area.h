#pragma once
// The geometric search area of the paper (section 3, "loop detection search area"): which stored
// keyframes a new keyframe is compared with. The exact geometric definition, every interpretation
// of the paper's text, and a figure are in docs/SEARCH_AREA.md.
//
// Usage: call Add() for every keyframe in time order, then Query() for the keyframe just added.
// Positions are camera centres in the (raw, unoptimised) world frame of the vSLAM, in world units
// (metres for KITTI, arbitrary units for monocular SLAM).
//
// Cost: Add() is amortised O(1) (the projection plane and the uniform grid are rebuilt only when
// the trajectory has grown by `refit_growth`); Query() visits grid cells along the motion ray and
// the perpendicular, plus the selected index range, never the whole trajectory (except `kGlobal`,
// whose answer is the whole trajectory).
//
// Threads: Query() is const and may run concurrently with other Query() calls; Add() and
// OnLoopAccepted() need exclusive access.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace sparseloop {

enum class SearchStrategy {
  kPaper,   // the paper's wedge between the motion-ray hit p and the perpendicular hit p'
  kRadius,  // keyframes within `radius` of the current position
  kGlobal,  // every past keyframe except the most recent `exclude_recent`
};

// "paper", "radius", "global"; throws std::invalid_argument otherwise.
SearchStrategy ParseSearchStrategy(const std::string& name);
std::string ToString(SearchStrategy strategy);

struct SearchAreaOptions {
  SearchStrategy strategy = SearchStrategy::kPaper;
  // Half-opening of the paper's wedge, degrees in (0, 180]: the angle between the motion ray and
  // the "alpha line" drawn toward the perpendicular. 90 = the whole quadrant up to the normal.
  double alpha_deg = 90.0;
  // Number of most recent keyframes before the query that are never candidates (keyframes).
  // With query index t, eligible keyframes have index k < t - exclude_recent.
  int exclude_recent = 10;
  // kRadius: search radius around the current position (world units).
  double radius = 10.0;
  // kRadius: measure the radius in the motion plane (true) or in 3D (false).
  bool radius_in_plane = false;
  // Uncertainty area (strategies kPaper and kRadius), added to the area above. The raw
  // positions of one place seen twice differ by the odometry drift accumulated along the path
  // between the two visits, so every eligible keyframe k with
  //   |x_k - x_t| <= r_k,   r_k = drift_base_steps x s + drift_rate x L(k, t)
  // is a candidate too (3D, raw units; s = the mean raw step so far, path length / steps, so the
  // base is scale-free; L(k, t) = the raw path length from k to the query t). An accepted loop
  // (OnLoopAccepted, query q, match m, the loop's rotation correction C) ties two places: the
  // query's position as the loop predicts it in the match pass's raw frame is
  // x_m + C (x_t - x_q), with odometry |L(t) - L(q)| + |L(m) - L(k)| to keyframe k. Each k is
  // tested on the path with the least odometry (directly, or through one of the last drift_loops
  // loops): near a place already closed the area is tight again, however far the path since.
  // At most drift_max_candidates keyframes are added, those nearest relative to their radius
  // (|x_k - c| / r_k, then the lower index): where the camera has passed a place many times the
  // area would otherwise grow with the number of passes (a 6,000-keyframe soak flight at K = 300:
  // 5 -> 100 ms per keyframe without the bound). 200 keeps every figure of docs/SEARCH_AREA.md
  // (100 lost street05 x4: in area 1.00 -> 0.92, recall 0.83 -> 0.77).
  // drift_rate: fraction of path length, >= 0 (0 disables: the paper's area alone);
  // drift_base_steps: mean steps, >= 0; drift_loops: loops, >= 0; drift_max_candidates:
  // keyframes, >= 1. The default 10 % of the raw path between two passes covers the drift of the
  // benchmark's renders up to x4 (street KITTI 00 / 05 / 07, aerial), raw t_err 1.7-28 %, with
  // zero false loops accepted; docs/SEARCH_AREA.md "Uncertainty area".
  double drift_rate = 0.1;
  double drift_base_steps = 10.0;
  int drift_loops = 8;
  int drift_max_candidates = 200;
  // Normal of the motion plane (any length > 0). Unset: fitted to the trajectory by PCA
  // (smallest principal axis). KITTI camera poses: (0, 1, 0) (the ground plane is x-z).
  std::optional<Eigen::Vector3d> plane_normal;
  // kPaper: keyframes searched when the motion ray hits nothing (the paper's "search starts from
  // the initial position": keyframes 0 .. fallback_count-1), and the width of the index window
  // centred on the start keyframe when the perpendicular hits nothing (keyframes, >= 1).
  int fallback_count = 50;
  // Displacements shorter than this (world units, in the plane) are "no motion".
  double min_motion = 1e-6;
  // How many keyframes back (resp. forward from keyframe 0) to look for a displacement of at
  // least `min_motion` when defining the motion direction (resp. the backward fallback ray).
  int motion_lookback = 5;
  // Relative growth of the trajectory that triggers a plane refit and grid rebuild
  // (dimensionless, (0, 1]; 0.25 = when it has grown by 25 %). Keeps Add() amortised O(1) and
  // the plane and grid fitted to the trajectory as it is.
  double refit_growth = 0.25;
  // Grid cell (world units; 0: 4x the mean in-plane step). A given size is kept between 1/16 of
  // the automatic one (a ray's cost is bounded) and the trajectory's extent in the plane.
  double cell_size = 0.0;

  void Check() const;
};

// Orthonormal frame of the motion plane: in-plane coordinates of x are
// (u.dot(x - origin), v.dot(x - origin)); normal = u x v.
struct PlaneFrame {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d u = Eigen::Vector3d::UnitX();
  Eigen::Vector3d v = Eigen::Vector3d::UnitY();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector2d Project(const Eigen::Vector3d& p_in_world) const {
    const Eigen::Vector3d d = p_in_world - origin;
    return {u.dot(d), v.dot(d)};
  }
  Eigen::Vector3d Lift(const Eigen::Vector2d& q) const { return origin + q.x() * u + q.y() * v; }
};

enum class SearchAreaStatus {
  kOk,        // the area was computed and holds at least one keyframe
  kEmpty,     // the area was computed but no eligible keyframe lies in it
  kTooShort,  // no eligible keyframe yet (trajectory shorter than exclude_recent + 2)
  kNoMotion,  // kPaper: no displacement >= min_motion in the last motion_lookback keyframes
};

// Which branch of the paper's construction ran.
enum class PaperBranch {
  kNotRun,          // another strategy, or kTooShort / kNoMotion
  kSegmentHit,      // the motion ray hit a past segment x'_{k-1} x'_k at p
  kBackwardRayHit,  // the motion ray first hit the backward ray from x'_1 away from x'_2
  kNoIntersection,  // no hit: search from the start of the trajectory (fallback)
};

std::string ToString(SearchAreaStatus status);
std::string ToString(PaperBranch branch);

struct SearchAreaResult {
  // Candidate keyframe ids, in insertion (time) order, without duplicates.
  std::vector<int64_t> candidates;
  SearchAreaStatus status = SearchAreaStatus::kTooShort;
  SearchStrategy strategy = SearchStrategy::kPaper;
  PaperBranch branch = PaperBranch::kNotRun;
  bool fallback_used = false;  // kPaper: the no-intersection fallback ran

  // Geometry, in plane coordinates of `plane` (diagnostics and figures).
  PlaneFrame plane;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();   // x'_t
  Eigen::Vector2d direction = Eigen::Vector2d::Zero();  // unit motion direction (0 if none)
  std::optional<Eigen::Vector2d> p;                     // first hit of the motion ray
  std::optional<Eigen::Vector2d> p_end;                 // nearest hit p' of the perpendicular
  // +1: p' (and the wedge) on the left of the motion (counter-clockwise in (u, v)), -1: right,
  // 0: no p', the wedge spans both sides.
  int wedge_side = 0;
  std::optional<int64_t> start_keyframe;  // keyframe nearest to p
  std::optional<int64_t> end_keyframe;    // keyframe nearest to p'
  // Index range searched (after drift widening), as keyframe ids; unset when not kPaper/empty.
  std::optional<int64_t> range_first;
  std::optional<int64_t> range_last;
  // Candidates the uncertainty area (drift_rate) added beyond the paper's / radius area, count.
  size_t uncertainty_added = 0;
  size_t cells_visited = 0;  // grid cells inspected (cost diagnostic)

  // One line, e.g. "paper ok segment-hit 12 candidates start=40 end=57 margin=0.00".
  std::string BriefReport() const;
};

class SearchArea {
 public:
  // Throws std::invalid_argument when options.Check() fails.
  explicit SearchArea(SearchAreaOptions options);
  ~SearchArea();
  SearchArea(SearchArea&&) noexcept;
  SearchArea& operator=(SearchArea&&) noexcept;

  // Appends a keyframe, in insertion (time) order. Ids must be unique (std::invalid_argument).
  void Add(int64_t keyframe_id, const Eigen::Vector3d& p_in_world);
  // The search area for a stored keyframe (normally the one just added): only keyframes added
  // before it are considered. Unknown id: std::invalid_argument.
  SearchAreaResult Query(int64_t keyframe_id) const;
  // Records an accepted loop: the drift distance restarts at `query_id`, and the uncertainty
  // area (drift_rate) searches around the position it predicts. Both ids must be stored.
  // `raw_correction` (the loop's verified rotation against the raw one, and when known the scale
  // between the two passes: the linear map that takes displacements of the query pass's raw
  // world into the match pass's, s R_wm R_mq R_wq^T) turns the path since the loop into the
  // match pass's frame; identity when unknown.
  void OnLoopAccepted(int64_t query_id, int64_t match_id,
                      const Eigen::Matrix3d& raw_correction = Eigen::Matrix3d::Identity());
  size_t size() const;
  // Path length along the stored keyframes from the first one to `keyframe_id` (sum of the
  // distances between consecutive stored positions; world units). The one online path length:
  // the search area's drift widening and the detector's min_path_ratio filter both read it.
  // Unknown id: std::invalid_argument.
  double PathLength(int64_t keyframe_id) const;

  const SearchAreaOptions& options() const;
  // The current motion plane (fitted or given).
  PlaneFrame plane() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sparseloop
