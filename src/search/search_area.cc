#include "sparseloop/search/search_area.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <unordered_map>

#include <fmt/format.h>
#include <Eigen/Eigenvalues>

#include "sparseloop/core/check.h"

namespace sparseloop {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = 3.14159265358979323846;
// Angular slack (rad) of the wedge test, so that keyframes exactly on a bounding ray are inside.
constexpr double kAngleSlack = 1e-9;

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Ray origin + s * dir (s >= 0, dir unit) against segment a + lambda * (b - a), lambda in [0, 1]
// (or lambda >= 0 when `half_line`). Returns s, or +inf when there is no (non-parallel) hit.
double RayHit(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir, const Eigen::Vector2d& a,
              const Eigen::Vector2d& b, bool half_line) {
  const Eigen::Vector2d e = b - a;
  const double denom = Cross(dir, e);
  if (std::abs(denom) <= 1e-12 * e.norm()) return kInf;  // parallel or degenerate
  const Eigen::Vector2d w = a - origin;
  const double s = Cross(w, e) / denom;
  const double lambda = Cross(w, dir) / denom;
  if (s < 0.0 || lambda < 0.0 || (!half_line && lambda > 1.0)) return kInf;
  return s;
}

double PointSegmentDistance(const Eigen::Vector2d& x, const Eigen::Vector2d& a,
                            const Eigen::Vector2d& b) {
  const Eigen::Vector2d e = b - a;
  const double len2 = e.squaredNorm();
  double t = len2 > 0.0 ? (x - a).dot(e) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return (x - (a + t * e)).norm();
}

Eigen::Vector2d Rotate(const Eigen::Vector2d& d, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {c * d.x() - s * d.y(), s * d.x() + c * d.y()};
}

// Wedge with apex at the query position, from `dir` over `alpha` rad to the side `side`
// (+1 counter-clockwise, -1 clockwise, 0 both sides).
bool InWedge(const Eigen::Vector2d& w, const Eigen::Vector2d& dir, double alpha, int side) {
  if (w.squaredNorm() == 0.0) return true;
  const double theta = std::atan2(Cross(dir, w), dir.dot(w));
  if (side == 0) return std::abs(theta) <= alpha + kAngleSlack;
  const double signed_theta = side * theta;
  return signed_theta >= -kAngleSlack && signed_theta <= alpha + kAngleSlack;
}

uint64_t CellKey(int64_t ix, int64_t iy) {
  return (static_cast<uint64_t>(ix) << 32) ^ (static_cast<uint64_t>(iy) & 0xffffffffULL);
}

// The finest grid a SearchArea builds: a cell at least this fraction of the automatic one (4x the
// mean in-plane step), so a ray crosses at most this many times the cells it does by default.
constexpr double kMinCellOfAutomatic = 1.0 / 16.0;

// Uniform grid hash in the plane: keyframes in their cell, segment k (from keyframe k-1 to k)
// in every cell of its bounding box dilated by one cell, so that a ray sampled every half cell
// finds every segment it crosses despite rounding.
class Grid {
 public:
  void Reset(double cell_size) {
    cell_size_ = cell_size;
    cells_.clear();
    min_ = Eigen::Vector2d::Constant(kInf);
    max_ = Eigen::Vector2d::Constant(-kInf);
  }
  double cell_size() const { return cell_size_; }
  int64_t Coord(double x) const { return static_cast<int64_t>(std::floor(x / cell_size_)); }

  void AddKeyframe(int32_t index, const Eigen::Vector2d& q) {
    cells_[CellKey(Coord(q.x()), Coord(q.y()))].keyframes.push_back(index);
    min_ = min_.cwiseMin(q);
    max_ = max_.cwiseMax(q);
  }

  void AddSegment(int32_t index, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const int64_t x0 = Coord(std::min(a.x(), b.x())) - 1, x1 = Coord(std::max(a.x(), b.x())) + 1;
    const int64_t y0 = Coord(std::min(a.y(), b.y())) - 1, y1 = Coord(std::max(a.y(), b.y())) + 1;
    if ((x1 - x0 + 1) * (y1 - y0 + 1) <= 16) {
      for (int64_t ix = x0; ix <= x1; ++ix)
        for (int64_t iy = y0; iy <= y1; ++iy) cells_[CellKey(ix, iy)].segments.push_back(index);
      return;
    }
    // Long segment: samples every half cell, each with its 3x3 neighbourhood.
    const double length = (b - a).norm();
    const int steps = static_cast<int>(std::ceil(length / (0.5 * cell_size_)));
    std::vector<uint64_t> keys;
    for (int i = 0; i <= steps; ++i) {
      const Eigen::Vector2d q = a + (b - a) * (static_cast<double>(i) / steps);
      const int64_t cx = Coord(q.x()), cy = Coord(q.y());
      for (int64_t dx = -1; dx <= 1; ++dx)
        for (int64_t dy = -1; dy <= 1; ++dy) keys.push_back(CellKey(cx + dx, cy + dy));
    }
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    for (uint64_t key : keys) cells_[key].segments.push_back(index);
  }

  struct Cell {
    std::vector<int32_t> keyframes;
    std::vector<int32_t> segments;
  };
  const Cell* Find(int64_t ix, int64_t iy) const {
    const auto it = cells_.find(CellKey(ix, iy));
    return it == cells_.end() ? nullptr : &it->second;
  }

  // Cell-coordinate bounds of the content (empty when nothing was added).
  bool Empty() const { return min_.x() > max_.x(); }
  int64_t MinX() const { return Coord(min_.x()); }
  int64_t MaxX() const { return Coord(max_.x()); }
  int64_t MinY() const { return Coord(min_.y()); }
  int64_t MaxY() const { return Coord(max_.y()); }

  // Ray parameter where a ray leaves the bounding box of the content, dilated by two cells.
  double ExitParameter(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir) const {
    if (min_.x() > max_.x()) return 0.0;
    double t_exit = kInf;
    for (int i = 0; i < 2; ++i) {
      const double lo = min_[i] - 2 * cell_size_, hi = max_[i] + 2 * cell_size_;
      if (dir[i] > 0) t_exit = std::min(t_exit, (hi - origin[i]) / dir[i]);
      if (dir[i] < 0) t_exit = std::min(t_exit, (lo - origin[i]) / dir[i]);
    }
    return std::max(0.0, t_exit);
  }

 private:
  double cell_size_ = 1.0;
  std::unordered_map<uint64_t, Cell> cells_;
  Eigen::Vector2d min_, max_;
};

}  // namespace

SearchStrategy ParseSearchStrategy(const std::string& name) {
  if (name == "paper") return SearchStrategy::kPaper;
  if (name == "radius") return SearchStrategy::kRadius;
  if (name == "global") return SearchStrategy::kGlobal;
  SL_CHECK_MSG(false, "unknown search strategy '{}' (expected paper, radius or global)", name);
  return SearchStrategy::kPaper;
}

std::string ToString(SearchStrategy strategy) {
  switch (strategy) {
    case SearchStrategy::kPaper:
      return "paper";
    case SearchStrategy::kRadius:
      return "radius";
    case SearchStrategy::kGlobal:
      return "global";
  }
  return "?";
}

std::string ToString(SearchAreaStatus status) {
  switch (status) {
    case SearchAreaStatus::kOk:
      return "ok";
    case SearchAreaStatus::kEmpty:
      return "empty";
    case SearchAreaStatus::kTooShort:
      return "too-short";
    case SearchAreaStatus::kNoMotion:
      return "no-motion";
  }
  return "?";
}

std::string ToString(PaperBranch branch) {
  switch (branch) {
    case PaperBranch::kNotRun:
      return "not-run";
    case PaperBranch::kSegmentHit:
      return "segment-hit";
    case PaperBranch::kBackwardRayHit:
      return "backward-ray-hit";
    case PaperBranch::kNoIntersection:
      return "no-intersection";
  }
  return "?";
}

std::string SearchAreaResult::BriefReport() const {
  auto opt = [](const std::optional<int64_t>& v) {
    return v ? fmt::format("{}", *v) : std::string("-");
  };
  return fmt::format("{} {} {} {} candidates start={} end={} range=[{},{}]", ToString(strategy),
                     ToString(status), ToString(branch), candidates.size(), opt(start_keyframe),
                     opt(end_keyframe), opt(range_first), opt(range_last));
}

void SearchAreaOptions::Check() const {
  SL_CHECK_MSG(alpha_deg > 0.0 && alpha_deg <= 180.0, "alpha_deg must be in (0, 180], got {}",
               alpha_deg);
  SL_CHECK_MSG(exclude_recent >= 0, "exclude_recent must be >= 0, got {}", exclude_recent);
  SL_CHECK_MSG(radius >= 0.0 && std::isfinite(radius), "radius must be finite and >= 0, got {}",
               radius);
  SL_CHECK_MSG(drift_rate >= 0.0 && std::isfinite(drift_rate),
               "drift_rate must be finite and >= 0, got {}", drift_rate);
  SL_CHECK_MSG(drift_base_steps >= 0.0 && std::isfinite(drift_base_steps),
               "drift_base_steps must be finite and >= 0, got {}", drift_base_steps);
  SL_CHECK_MSG(drift_loops >= 0, "drift_loops must be >= 0, got {}", drift_loops);
  SL_CHECK_MSG(drift_max_candidates >= 1, "drift_max_candidates must be >= 1, got {}",
               drift_max_candidates);
  if (plane_normal) {
    SL_CHECK_MSG(plane_normal->allFinite() && plane_normal->norm() > 1e-12,
                 "plane_normal must be finite and non-zero");
  }
  SL_CHECK_MSG(fallback_count >= 1, "fallback_count must be >= 1, got {}", fallback_count);
  SL_CHECK_MSG(min_motion > 0.0 && std::isfinite(min_motion),
               "min_motion must be finite and > 0, got {}", min_motion);
  SL_CHECK_MSG(motion_lookback >= 1, "motion_lookback must be >= 1, got {}", motion_lookback);
  // Above 1 the plane fitted to the first few keyframes (3 points, often on a line) would serve
  // for most of the run: the grid would stop following the trajectory.
  SL_CHECK_MSG(refit_growth > 0.0 && refit_growth <= 1.0, "refit_growth must be in (0, 1], got {}",
               refit_growth);
  SL_CHECK_MSG(cell_size >= 0.0 && std::isfinite(cell_size),
               "cell_size must be finite and >= 0 (0 = automatic), got {}", cell_size);
}

struct SearchArea::Impl {
  SearchAreaOptions options;
  std::vector<int64_t> ids;
  std::vector<Eigen::Vector3d> positions;  // world
  std::vector<Eigen::Vector2d> projected;  // plane coordinates under `plane`
  std::vector<double> path_length;         // cumulative 3D path length, first entry 0
  std::unordered_map<int64_t, int32_t> index_of;
  PlaneFrame plane;
  bool plane_fitted = false;  // a PCA fit has been made (fitted mode)
  // Running sums of (x - origin) for the PCA: O(1) per Add.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();
  size_t built_size = 0;  // size at the last rebuild
  Grid grid;
  struct Loop {
    int32_t q = 0, m = 0;  // query, match indices
    Eigen::Matrix3d correction = Eigen::Matrix3d::Identity();
  };
  std::deque<Loop> loops;  // the last drift_loops accepted loops

  void Rebuild();
  void FitPlane();
  int32_t Nearest(const Eigen::Vector2d& x, int32_t eligible, double bound, size_t* cells) const;
  // First hit of the ray among eligible segments (and optionally a half-line).
  struct Hit {
    double s = kInf;
    int32_t segment = -1;  // 0 = the backward half-line, k >= 1 = segment (k-1, k)
  };
  Hit CastRay(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir, int32_t eligible,
              size_t* cells) const;
  void CollectNearPoint(const Eigen::Vector2d& x, double r, int32_t eligible,
                        std::vector<int32_t>* out, size_t* cells) const;

  // The steps of Query under kPaper.
  // Motion direction at t: towards x'_t from the latest earlier keyframe at least min_motion
  // away (zero when there is none within motion_lookback).
  Eigen::Vector2d MotionDirection(int32_t t) const;
  // The motion ray against past segments, then against the backward half-line from x'_0.
  Hit CastMotionRay(const Eigen::Vector2d& qt, const Eigen::Vector2d& dir, int32_t eligible,
                    size_t* cells) const;
  // The index range [lo, hi] of the paper's area from the ray's hit (start: nearest keyframe to
  // p, end: nearest to p' on the perpendicular, -1 when none; side of the wedge), with the
  // branch, p, p' and their keyframes written to *result.
  struct PaperRange {
    int32_t lo = 0, hi = 0, start = -1, end = -1;
    int side = 0;
  };
  PaperRange PaperIndexRange(const Eigen::Vector2d& qt, const Eigen::Vector2d& dir, const Hit& hit,
                             int32_t eligible, SearchAreaResult* result) const;
  // The uncertainty area (options.drift_rate) of query t: appends its distinct keyframes to *out.
  void CollectUncertain(int32_t t, int32_t eligible, std::vector<int32_t>* out,
                        size_t* cells) const;
};

void SearchArea::Impl::CollectUncertain(int32_t t, int32_t eligible, std::vector<int32_t>* out,
                                        size_t* cells) const {
  if (options.drift_rate <= 0.0 || t < 1 || eligible <= 0) return;
  const double base = options.drift_base_steps * path_length[t] / t;
  const double rate = options.drift_rate;
  // The paths that tie a keyframe k to the query: the odometry between them (q = m = t), or
  // odometry to a remembered loop's match m, the loop, odometry from its query q to t. Each
  // predicts where k should be (`centre`: x_t, or x_m + C (x_t - x_q)); k is tested on the path
  // with the least odometry, odometry(k) = |L(t) - L(q)| + |L(m) - L(k)|.
  struct Path {
    Eigen::Vector3d centre;
    double since = 0.0;  // odometry from q to t
    int32_t m = 0;
  };
  std::vector<Path> paths = {{positions[t], 0.0, t}};
  for (const Loop& l : loops)
    paths.push_back({positions[l.m] + l.correction * (positions[t] - positions[l.q]),
                     std::abs(path_length[t] - path_length[l.q]), l.m});
  std::vector<int32_t> near;
  for (const Path& p : paths) {  // a superset: every keyframe within the largest r of a path
    const double far = std::max(path_length[p.m] - path_length[0],
                                std::abs(path_length[eligible - 1] - path_length[p.m]));
    CollectNearPoint(plane.Project(p.centre), base + rate * (p.since + far), eligible, &near,
                     cells);
  }
  std::sort(near.begin(), near.end());
  near.erase(std::unique(near.begin(), near.end()), near.end());
  std::vector<std::pair<double, int32_t>> inside;  // (distance / radius, k)
  for (const int32_t k : near) {
    const Path* best = nullptr;
    double odometry = kInf;
    for (const Path& p : paths) {
      const double o = p.since + std::abs(path_length[p.m] - path_length[k]);
      if (o < odometry) odometry = o, best = &p;
    }
    const double d = (positions[k] - best->centre).norm();
    const double r = base + rate * odometry;
    if (d <= r) inside.emplace_back(r > 0.0 ? d / r : 0.0, k);
  }
  // Bounded: the drift_max_candidates nearest relative to their radius (then the lower index).
  const size_t cap = static_cast<size_t>(options.drift_max_candidates);
  if (inside.size() > cap) {
    std::nth_element(inside.begin(), inside.begin() + static_cast<std::ptrdiff_t>(cap),
                     inside.end());
    inside.resize(cap);
  }
  for (const auto& [ratio, k] : inside) out->push_back(k);
}

Eigen::Vector2d SearchArea::Impl::MotionDirection(int32_t t) const {
  const Eigen::Vector2d qt = projected[t];
  for (int32_t j = t - 1; j >= std::max(0, t - options.motion_lookback); --j) {
    const Eigen::Vector2d d = qt - projected[j];
    if (d.norm() >= options.min_motion) return d.normalized();
  }
  return Eigen::Vector2d::Zero();
}

SearchArea::Impl::Hit SearchArea::Impl::CastMotionRay(const Eigen::Vector2d& qt,
                                                      const Eigen::Vector2d& dir, int32_t eligible,
                                                      size_t* cells) const {
  Hit hit = CastRay(qt, dir, eligible, cells);
  for (int32_t j = 1; j <= std::min(eligible - 1, options.motion_lookback); ++j) {
    const Eigen::Vector2d back = projected[0] - projected[j];
    if (back.norm() >= options.min_motion) {
      const Eigen::Vector2d q0 = projected[0];
      const double s = RayHit(qt, dir, q0, q0 + back.normalized(), true);
      if (s < hit.s || (s == hit.s && s < kInf)) hit = {s, 0};
      break;
    }
  }
  return hit;
}

SearchArea::Impl::PaperRange SearchArea::Impl::PaperIndexRange(const Eigen::Vector2d& qt,
                                                               const Eigen::Vector2d& dir,
                                                               const Hit& hit, int32_t eligible,
                                                               SearchAreaResult* result) const {
  const SearchAreaOptions& o = options;
  PaperRange r;
  if (hit.segment < 0) {
    result->branch = PaperBranch::kNoIntersection;
    result->fallback_used = true;
    r.lo = 0;
    r.hi = std::min(eligible - 1, o.fallback_count - 1);
    return r;
  }
  result->branch = hit.segment == 0 ? PaperBranch::kBackwardRayHit : PaperBranch::kSegmentHit;
  const Eigen::Vector2d p = qt + hit.s * dir;
  result->p = p;
  const double bound = hit.segment == 0 ? (p - projected[0]).norm()
                                        : std::min((p - projected[hit.segment - 1]).norm(),
                                                   (p - projected[hit.segment]).norm());
  r.start = Nearest(p, eligible, bound, &result->cells_visited);
  result->start_keyframe = ids[r.start];
  // Perpendicular h through x'_t: nearest hit on either side (left wins a tie).
  const Eigen::Vector2d normal(-dir.y(), dir.x());
  const Hit left = CastRay(qt, normal, eligible, &result->cells_visited);
  const Hit right = CastRay(qt, -normal, eligible, &result->cells_visited);
  if (left.segment >= 0 || right.segment >= 0) {
    r.side = left.s <= right.s ? 1 : -1;
    const Hit& h = r.side > 0 ? left : right;
    const Eigen::Vector2d p_end = qt + h.s * r.side * normal;
    result->p_end = p_end;
    const double end_bound =
        std::min((p_end - projected[h.segment - 1]).norm(), (p_end - projected[h.segment]).norm());
    r.end = Nearest(p_end, eligible, end_bound, &result->cells_visited);
    result->end_keyframe = ids[r.end];
    r.lo = std::min(r.start, r.end);
    r.hi = std::max(r.start, r.end);
  } else {
    const int32_t half = o.fallback_count / 2;
    r.lo = std::max(0, r.start - half);
    r.hi = std::min(eligible - 1, r.start + half);
  }
  result->wedge_side = r.side;
  return r;
}

void SearchArea::Impl::FitPlane() {
  const double n = static_cast<double>(positions.size());
  const Eigen::Vector3d mean = sum / n;
  const Eigen::Matrix3d cov = sum_outer / n - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(cov);
  // Eigenvalues ascending: column 0 = normal, column 2 = principal direction.
  Eigen::Vector3d normal = solver.eigenvectors().col(0).normalized();
  if (plane_fitted) {
    if (normal.dot(plane.normal) < 0) normal = -normal;
  } else {
    Eigen::Index axis;
    normal.cwiseAbs().maxCoeff(&axis);
    if (normal[axis] < 0) normal = -normal;
  }
  // Keep the in-plane basis stable: project the previous u into the new plane.
  Eigen::Vector3d u = plane.u - plane.u.dot(normal) * normal;
  if (u.norm() < 1e-6) u = solver.eigenvectors().col(2);
  u = (u - u.dot(normal) * normal).normalized();
  plane.normal = normal;
  plane.u = u;
  plane.v = normal.cross(u);
  plane_fitted = true;
}

void SearchArea::Impl::Rebuild() {
  const size_t n = positions.size();
  if (!options.plane_normal && n >= 3) FitPlane();
  for (size_t k = 0; k < n; ++k) projected[k] = plane.Project(positions[k]);
  double steps = 0.0;
  for (size_t k = 1; k < n; ++k) steps += (projected[k] - projected[k - 1]).norm();
  double automatic = n >= 2 ? 4.0 * steps / static_cast<double>(n - 1) : 0.0;
  if (!(automatic > 0.0)) automatic = 1.0;
  // The grid only speeds the search up (its result does not depend on the cell size), but its
  // cost does: a cell far below the keyframe spacing makes every ray cross millions of cells
  // (1 mm on a 10 m scene: > 30 s per keyframe). A given cell_size is raised to at least
  // kMinCellOfAutomatic x the automatic cell (a ray then costs at most that factor more than by
  // default, whatever the map's size) and lowered to at most the trajectory's extent in the plane
  // (one cell then holds everything).
  double cell = automatic;
  if (options.cell_size > 0.0) {
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(kInf), hi = Eigen::Vector2d::Constant(-kInf);
    for (size_t k = 0; k < n; ++k) {
      lo = lo.cwiseMin(projected[k]);
      hi = hi.cwiseMax(projected[k]);
    }
    const double extent = n == 0 ? 0.0 : (hi - lo).maxCoeff();
    cell = std::max(options.cell_size, kMinCellOfAutomatic * automatic);
    if (extent > 0.0) cell = std::min(cell, std::max(extent, kMinCellOfAutomatic * automatic));
  }
  grid.Reset(cell);
  for (size_t k = 0; k < n; ++k) {
    grid.AddKeyframe(static_cast<int32_t>(k), projected[k]);
    if (k >= 1) grid.AddSegment(static_cast<int32_t>(k), projected[k - 1], projected[k]);
  }
  built_size = n;
}

int32_t SearchArea::Impl::Nearest(const Eigen::Vector2d& x, int32_t eligible, double bound,
                                  size_t* cells) const {
  // Rings of cells around x (Chebyshev distance r), clipped to the content's bounding box, until
  // the ring cannot hold anything nearer than the best so far or than `bound` (the distance to a
  // known eligible keyframe).
  const double cs = grid.cell_size();
  bound = bound * (1.0 + 1e-9) + 1e-12;
  int32_t best = -1;
  double best_d2 = kInf;
  const int64_t cx = grid.Coord(x.x()), cy = grid.Coord(x.y());
  const int64_t bx0 = grid.MinX(), bx1 = grid.MaxX(), by0 = grid.MinY(), by1 = grid.MaxY();
  const int64_t r_first = std::max<int64_t>({0, bx0 - cx, cx - bx1, by0 - cy, cy - by1});
  const int64_t r_last = std::max<int64_t>({cx - bx0, bx1 - cx, cy - by0, by1 - cy});
  auto visit = [&](int64_t ix, int64_t iy) {
    ++*cells;
    const Grid::Cell* cell = grid.Find(ix, iy);
    if (cell == nullptr) return;
    for (int32_t k : cell->keyframes) {
      if (k >= eligible) continue;
      const double d2 = (projected[k] - x).squaredNorm();
      if (d2 < best_d2 || (d2 == best_d2 && k < best)) {
        best_d2 = d2;
        best = k;
      }
    }
  };
  for (int64_t r = r_first; r <= r_last; ++r) {
    // Every point of ring r is at least (r - 1) cells away from x.
    const double ring_distance = static_cast<double>(r - 1) * cs;
    if (ring_distance > bound || (best >= 0 && ring_distance * ring_distance > best_d2)) break;
    if (r == 0) {
      visit(cx, cy);
      continue;
    }
    const int64_t x0 = std::max(cx - r, bx0), x1 = std::min(cx + r, bx1);
    for (const int64_t iy : {cy - r, cy + r}) {
      if (iy < by0 || iy > by1) continue;
      for (int64_t ix = x0; ix <= x1; ++ix) visit(ix, iy);
    }
    const int64_t y0 = std::max(cy - r + 1, by0), y1 = std::min(cy + r - 1, by1);
    for (const int64_t ix : {cx - r, cx + r}) {
      if (ix < bx0 || ix > bx1) continue;
      for (int64_t iy = y0; iy <= y1; ++iy) visit(ix, iy);
    }
  }
  return best;
}

SearchArea::Impl::Hit SearchArea::Impl::CastRay(const Eigen::Vector2d& origin,
                                                const Eigen::Vector2d& dir, int32_t eligible,
                                                size_t* cells) const {
  Hit best;
  const double cs = grid.cell_size();
  const double step = 0.5 * cs;
  const double s_exit = grid.ExitParameter(origin, dir);
  int64_t last_x = std::numeric_limits<int64_t>::min(), last_y = last_x;
  for (double s = 0.0;; s += step) {
    // A segment found from a later sample cannot hit before s - 2 cells.
    if (s - 2.0 * cs > best.s) break;
    const Eigen::Vector2d q = origin + std::min(s, s_exit) * dir;
    const int64_t ix = grid.Coord(q.x()), iy = grid.Coord(q.y());
    if (ix != last_x || iy != last_y) {
      last_x = ix;
      last_y = iy;
      ++*cells;
      if (const Grid::Cell* cell = grid.Find(ix, iy)) {
        for (int32_t k : cell->segments) {
          if (k >= eligible) continue;  // segment (k-1, k) needs both ends eligible
          const double hit = RayHit(origin, dir, projected[k - 1], projected[k], false);
          if (hit < best.s || (hit == best.s && hit < kInf && k < best.segment)) {
            best.s = hit;
            best.segment = k;
          }
        }
      }
    }
    if (s >= s_exit) break;
  }
  return best;
}

void SearchArea::Impl::CollectNearPoint(const Eigen::Vector2d& x, double r, int32_t eligible,
                                        std::vector<int32_t>* out, size_t* cells) const {
  const int64_t x0 = std::max(grid.Coord(x.x() - r), grid.MinX());
  const int64_t x1 = std::min(grid.Coord(x.x() + r), grid.MaxX());
  const int64_t y0 = std::max(grid.Coord(x.y() - r), grid.MinY());
  const int64_t y1 = std::min(grid.Coord(x.y() + r), grid.MaxY());
  for (int64_t ix = x0; ix <= x1; ++ix) {
    for (int64_t iy = y0; iy <= y1; ++iy) {
      ++*cells;
      const Grid::Cell* cell = grid.Find(ix, iy);
      if (cell == nullptr) continue;
      for (int32_t k : cell->keyframes) {
        if (k < eligible) out->push_back(k);  // exact distance test by the caller
      }
    }
  }
}

SearchArea::SearchArea(SearchAreaOptions options) : impl_(std::make_unique<Impl>()) {
  options.Check();
  impl_->options = std::move(options);
  if (impl_->options.plane_normal) {
    const Eigen::Vector3d normal = impl_->options.plane_normal->normalized();
    // In-plane basis: the world axis least aligned with the normal, made orthogonal.
    Eigen::Index axis;
    normal.cwiseAbs().minCoeff(&axis);
    Eigen::Vector3d u = Eigen::Vector3d::Unit(axis);
    u = (u - u.dot(normal) * normal).normalized();
    impl_->plane.normal = normal;
    impl_->plane.u = u;
    impl_->plane.v = normal.cross(u);
  }
}

SearchArea::~SearchArea() = default;
SearchArea::SearchArea(SearchArea&&) noexcept = default;
SearchArea& SearchArea::operator=(SearchArea&&) noexcept = default;

size_t SearchArea::size() const { return impl_->ids.size(); }
const SearchAreaOptions& SearchArea::options() const { return impl_->options; }
PlaneFrame SearchArea::plane() const { return impl_->plane; }

double SearchArea::PathLength(int64_t keyframe_id) const {
  const auto it = impl_->index_of.find(keyframe_id);
  SL_CHECK_MSG(it != impl_->index_of.end(), "PathLength: unknown keyframe {}", keyframe_id);
  return impl_->path_length[static_cast<size_t>(it->second)];
}

void SearchArea::Add(int64_t keyframe_id, const Eigen::Vector3d& p_in_world) {
  Impl& m = *impl_;
  SL_CHECK_MSG(p_in_world.allFinite(), "keyframe {} has a non-finite position", keyframe_id);
  SL_CHECK_MSG(m.index_of.find(keyframe_id) == m.index_of.end(), "keyframe id {} added twice",
               keyframe_id);
  SL_CHECK_MSG(m.ids.size() < static_cast<size_t>(std::numeric_limits<int32_t>::max()),
               "too many keyframes");
  const auto index = static_cast<int32_t>(m.ids.size());
  if (index == 0) m.plane.origin = p_in_world;
  m.index_of.emplace(keyframe_id, index);
  m.ids.push_back(keyframe_id);
  m.positions.push_back(p_in_world);
  m.path_length.push_back(
      index == 0 ? 0.0 : m.path_length.back() + (p_in_world - m.positions[index - 1]).norm());
  const Eigen::Vector3d d = p_in_world - m.plane.origin;
  m.sum += d;
  m.sum_outer += d * d.transpose();
  m.projected.push_back(m.plane.Project(p_in_world));
  const size_t n = m.ids.size();
  if (n <= 3 || static_cast<double>(n) >=
                    static_cast<double>(m.built_size) * (1.0 + m.options.refit_growth)) {
    m.Rebuild();
  } else {
    m.grid.AddKeyframe(index, m.projected[index]);
    m.grid.AddSegment(index, m.projected[index - 1], m.projected[index]);
  }
}

void SearchArea::OnLoopAccepted(int64_t query_id, int64_t match_id,
                                const Eigen::Matrix3d& raw_correction) {
  SL_CHECK_MSG(raw_correction.allFinite(), "OnLoopAccepted: the raw correction is not finite");
  const auto q = impl_->index_of.find(query_id);
  SL_CHECK_MSG(q != impl_->index_of.end(), "OnLoopAccepted: unknown query keyframe {}", query_id);
  SL_CHECK_MSG(impl_->index_of.count(match_id) == 1, "OnLoopAccepted: unknown match keyframe {}",
               match_id);
  if (impl_->options.drift_loops > 0) {
    impl_->loops.push_back({q->second, impl_->index_of.at(match_id), raw_correction});
    if (impl_->loops.size() > static_cast<size_t>(impl_->options.drift_loops))
      impl_->loops.pop_front();
  }
}

SearchAreaResult SearchArea::Query(int64_t keyframe_id) const {
  const Impl& m = *impl_;
  const SearchAreaOptions& o = m.options;
  const auto found = m.index_of.find(keyframe_id);
  SL_CHECK_MSG(found != m.index_of.end(), "Query: unknown keyframe {}", keyframe_id);
  const int32_t t = found->second;

  SearchAreaResult result;
  result.strategy = o.strategy;
  result.plane = m.plane;
  result.position = m.projected[t];
  const int32_t eligible = std::max<int32_t>(0, t - o.exclude_recent);  // indices < eligible
  std::vector<int32_t> selected;
  auto finish = [&]() {
    std::sort(selected.begin(), selected.end());
    selected.erase(std::unique(selected.begin(), selected.end()), selected.end());
    const size_t own = selected.size();
    // The uncertainty area (distinct keyframes); what it adds beyond this area is counted.
    m.CollectUncertain(t, eligible, &selected, &result.cells_visited);
    std::sort(selected.begin(), selected.end());
    selected.erase(std::unique(selected.begin(), selected.end()), selected.end());
    result.uncertainty_added = selected.size() - own;
    result.candidates.reserve(selected.size());
    for (int32_t k : selected) result.candidates.push_back(m.ids[k]);
    result.status = selected.empty() ? SearchAreaStatus::kEmpty : SearchAreaStatus::kOk;
    return result;
  };
  if (eligible <= 0) {
    result.status = SearchAreaStatus::kTooShort;
    return result;
  }

  if (o.strategy == SearchStrategy::kGlobal) {
    result.candidates.assign(m.ids.begin(), m.ids.begin() + eligible);
    result.status = SearchAreaStatus::kOk;
    return result;
  }
  if (o.strategy == SearchStrategy::kRadius) {
    const double r = o.radius;
    std::vector<int32_t> near;
    m.CollectNearPoint(m.projected[t], r, eligible, &near, &result.cells_visited);
    for (int32_t k : near) {
      const double d = o.radius_in_plane ? (m.projected[k] - m.projected[t]).norm()
                                         : (m.positions[k] - m.positions[t]).norm();
      if (d <= r) selected.push_back(k);
    }
    return finish();
  }

  // kPaper.
  const Eigen::Vector2d qt = m.projected[t];
  const Eigen::Vector2d dir = m.MotionDirection(t);
  if (dir.isZero()) {
    result.status = SearchAreaStatus::kNoMotion;
    return result;
  }
  result.direction = dir;
  const Impl::Hit hit = m.CastMotionRay(qt, dir, eligible, &result.cells_visited);
  Impl::PaperRange range = m.PaperIndexRange(qt, dir, hit, eligible, &result);
  const auto [lo, hi, start, end, side] = range;
  result.range_first = m.ids[lo];
  result.range_last = m.ids[hi];

  if (result.branch == PaperBranch::kNoIntersection) {
    for (int32_t k = lo; k <= hi; ++k) selected.push_back(k);
    return finish();
  }
  // The keyframes nearest to p and p' define the range and are always candidates, even when
  // they lie a little outside the wedge (e.g. on the far side of the motion ray).
  selected.push_back(start);
  if (end >= 0) selected.push_back(end);
  const double alpha = o.alpha_deg * kPi / 180.0;
  for (int32_t k = lo; k <= hi; ++k) {
    const Eigen::Vector2d w = m.projected[k] - qt;
    if (InWedge(w, dir, alpha, side)) selected.push_back(k);
  }
  return finish();
}

}  // namespace sparseloop
