#include "sparseloop/search/search_area.h"

#include <cmath>
#include <fstream>
#include <numeric>
#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "search/search_oracle.h"
#include "sparseloop/core/trajectory.h"
#include "test_util.h"

namespace sparseloop {
namespace {

// The paper's area alone, as these tests were written for: 30 recent keyframes excluded, no
// uncertainty area (the product's defaults: 10 and drift_rate 0.1, tested where said).
SearchAreaOptions PaperArea() {
  SearchAreaOptions o;
  o.exclude_recent = 30;
  o.drift_rate = 0.0;
  return o;
}

using test::BruteForceSearchArea;

std::vector<int64_t> Range(int64_t first, int64_t last) {
  std::vector<int64_t> v;
  for (int64_t k = first; k <= last; ++k) v.push_back(k);
  return v;
}

// Counter-clockwise square of side 10 from (0,0), then down the line x = 2 from (2,10) to (2,3).
std::vector<Eigen::Vector3d> SquareThenDown() {
  std::vector<Eigen::Vector3d> pts;
  for (int x = 0; x <= 10; ++x) pts.emplace_back(x, 0, 0);   // 0..10
  for (int y = 1; y <= 10; ++y) pts.emplace_back(10, y, 0);  // 11..20
  for (int x = 9; x >= 2; --x) pts.emplace_back(x, 10, 0);   // 21..28
  for (int y = 9; y >= 3; --y) pts.emplace_back(2, y, 0);    // 29..35
  return pts;
}

SearchArea Build(const SearchAreaOptions& options, const std::vector<Eigen::Vector3d>& pts) {
  SearchArea area(options);
  for (size_t k = 0; k < pts.size(); ++k) area.Add(static_cast<int64_t>(k), pts[k]);
  return area;
}

TEST(SearchAreaPaper, SquareRayHitsFirstSideQuadrant) {
  SearchAreaOptions o = PaperArea();
  o.plane_normal = Eigen::Vector3d::UnitZ();
  o.exclude_recent = 5;
  const auto pts = SquareThenDown();
  const SearchArea area = Build(o, pts);
  const SearchAreaResult r = area.Query(35);  // at (2,3), moving south
  ASSERT_EQ(r.status, SearchAreaStatus::kOk) << r.BriefReport();
  EXPECT_EQ(r.branch, PaperBranch::kSegmentHit);
  EXPECT_FALSE(r.fallback_used);
  ASSERT_TRUE(r.p.has_value());
  // The ray hits the first side at (2,0); the perpendicular hits the east side at (10,3).
  EXPECT_NEAR((r.plane.Lift(*r.p) - Eigen::Vector3d(2, 0, 0)).norm(), 0.0, 1e-9);
  ASSERT_TRUE(r.p_end.has_value());
  EXPECT_NEAR((r.plane.Lift(*r.p_end) - Eigen::Vector3d(10, 3, 0)).norm(), 0.0, 1e-9);
  EXPECT_EQ(r.start_keyframe, 2);
  EXPECT_EQ(r.end_keyframe, 13);
  // alpha = 90: the whole south-east quadrant of (2,3) within keyframes 2..13.
  EXPECT_EQ(r.candidates, Range(2, 13));
}

TEST(SearchAreaPaper, SquareNarrowWedge) {
  SearchAreaOptions o = PaperArea();
  o.plane_normal = Eigen::Vector3d::UnitZ();
  o.exclude_recent = 5;
  o.alpha_deg = 45.0;
  const SearchAreaResult r = Build(o, SquareThenDown()).Query(35);
  // Within 45 deg of south toward east from (2,3): x - 2 <= 3 - y, i.e. (2..5, 0); plus the end
  // keyframe 13 at (10,3) nearest to p', which is always a candidate.
  EXPECT_EQ(r.candidates, (std::vector<int64_t>{2, 3, 4, 5, 13})) << r.BriefReport();
  EXPECT_EQ(r.wedge_side, 1);
}

TEST(SearchAreaPaper, SquareInTiltedPlaneWithFittedPlaneGivesSameAnswer) {
  SearchAreaOptions o = PaperArea();
  o.exclude_recent = 5;
  o.alpha_deg = 45.0;
  const Eigen::Matrix3d rot =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 0.5).normalized()).toRotationMatrix();
  std::vector<Eigen::Vector3d> pts;
  for (const auto& p : SquareThenDown()) pts.push_back(rot * p + Eigen::Vector3d(100, -50, 7));
  const SearchArea area = Build(o, pts);
  EXPECT_NEAR(std::abs(area.plane().normal.dot(rot.col(2))), 1.0, 1e-9);
  const SearchAreaResult r = area.Query(35);
  EXPECT_EQ(r.candidates, (std::vector<int64_t>{2, 3, 4, 5, 13})) << r.BriefReport();
}

TEST(SearchAreaPaper, StraightLineFallsBackToStart) {
  SearchAreaOptions o = PaperArea();
  o.plane_normal = Eigen::Vector3d::UnitZ();
  o.exclude_recent = 10;
  o.fallback_count = 20;
  std::vector<Eigen::Vector3d> pts;
  for (int k = 0; k < 100; ++k) pts.emplace_back(0.5 * k, 0, 0);
  const SearchAreaResult r = Build(o, pts).Query(99);
  EXPECT_EQ(r.branch, PaperBranch::kNoIntersection);
  EXPECT_TRUE(r.fallback_used);
  EXPECT_FALSE(r.p.has_value());
  EXPECT_EQ(r.candidates, Range(0, 19));
}

TEST(SearchAreaPaper, BackwardRayFromStart) {
  // East along y = 0, north to (10,5), west along y = 5 past x = 0 to (-3,5), then south: the
  // motion ray from (-3,2) misses every segment and meets the backward ray from x'_0 (pointing
  // away from x'_1, i.e. -x) at (-3,0); keyframe 0 is the nearest to it.
  SearchAreaOptions o = PaperArea();
  o.plane_normal = Eigen::Vector3d::UnitZ();
  o.exclude_recent = 3;
  std::vector<Eigen::Vector3d> pts;
  for (int x = 0; x <= 10; ++x) pts.emplace_back(x, 0, 0);  // 0..10
  for (int y = 1; y <= 5; ++y) pts.emplace_back(10, y, 0);  // 11..15
  for (int x = 9; x >= -3; --x) pts.emplace_back(x, 5, 0);  // 16..28 (ends at (-3,5))
  for (int y = 4; y >= 2; --y) pts.emplace_back(-3, y, 0);  // 29..31, heading south
  const SearchAreaResult r = Build(o, pts).Query(31);
  EXPECT_EQ(r.branch, PaperBranch::kBackwardRayHit) << r.BriefReport();
  ASSERT_TRUE(r.p.has_value());
  EXPECT_NEAR((*r.p - Eigen::Vector2d(-3, 0)).norm(), 0.0, 1e-9);
  EXPECT_EQ(r.start_keyframe, 0);
}

TEST(SearchAreaGlobal, AllButRecent) {
  SearchAreaOptions o = PaperArea();
  o.strategy = SearchStrategy::kGlobal;
  o.exclude_recent = 30;
  std::vector<Eigen::Vector3d> pts;
  for (int k = 0; k < 100; ++k) pts.emplace_back(std::cos(0.1 * k), std::sin(0.1 * k), 0.0);
  SearchArea area(o);
  for (int k = 0; k < 100; ++k) area.Add(1000 + k, pts[k]);
  const SearchAreaResult r = area.Query(1099);
  EXPECT_EQ(r.candidates, Range(1000, 1068));
  EXPECT_EQ(area.Query(1030).status, SearchAreaStatus::kTooShort);
  EXPECT_EQ(area.Query(1031).candidates, Range(1000, 1000));
}

TEST(SearchAreaRadius, KnownNeighbours3dAndInPlane) {
  SearchAreaOptions o = PaperArea();
  o.strategy = SearchStrategy::kRadius;
  o.plane_normal = Eigen::Vector3d::UnitZ();
  o.exclude_recent = 1;
  o.radius = 1.5;
  std::vector<Eigen::Vector3d> pts = {{0, 0, 0}, {1, 0, 5}, {1, 1, 0},
                                      {3, 0, 0}, {5, 0, 0}, {0.5, 0.5, 0}};
  SearchAreaResult r = Build(o, pts).Query(5);
  // 3D: (0,0,0) d=.71, (1,0,5) d=5.05, (1,1,0) d=.71, (3,0,0) d=2.55; keyframe 4 is recent.
  EXPECT_EQ(r.candidates, (std::vector<int64_t>{0, 2}));
  o.radius_in_plane = true;
  r = Build(o, pts).Query(5);
  EXPECT_EQ(r.candidates, (std::vector<int64_t>{0, 1, 2}));
}

// Two laps of a 100 x 60 rectangle in the same direction (a street revisited as KITTI 00 does: the
// motion ray runs parallel to the old path), 1 m steps, raw positions drifted by a heading bias
// and a scale growth per step. Every lap-2 keyframe's true match is the lap-1 keyframe one lap
// back. The paper's area (drift_rate 0) loses it as the drift grows; the uncertainty area
// (drift_rate above the raw drift per path length) keeps it, with far fewer candidates than a
// global search. Measured per drift level and per seed of the drift's direction.
TEST(SearchAreaUncertainty, ContainsTheTruthOnDriftedLapsWhereThePaperAreaDoesNot) {
  const int lap = 320;  // keyframes per lap (2 x (100 + 60) m)
  std::vector<Eigen::Vector3d> gt;
  for (int i = 0; i < 2 * lap; ++i) {
    const int s = i % lap;
    if (s < 100)
      gt.emplace_back(s, 0, 0);
    else if (s < 160)
      gt.emplace_back(100, s - 100, 0);
    else if (s < 260)
      gt.emplace_back(100 - (s - 160), 60, 0);
    else
      gt.emplace_back(0, 60 - (s - 260), 0);
  }
  for (const double drift : {1.0, 4.0}) {
    for (const int seed : {1, 2, 3}) {
      // Raw odometry: each GT step rotated by the accumulated heading bias and scaled.
      auto rng = test::SeededRng(static_cast<uint32_t>(seed));
      std::normal_distribution<double> noise(0.0, 1.0);
      const double bias = drift * 0.01 * (seed % 2 == 0 ? -1.0 : 1.0) * M_PI / 180.0;  // rad/step
      std::vector<Eigen::Vector3d> raw = {gt[0]};
      std::vector<double> raw_heading = {0.0};  // raw minus GT heading
      double heading = 0.0, scale = 1.0;
      for (size_t i = 1; i < gt.size(); ++i) {
        heading += bias + drift * 0.002 * noise(rng);
        raw_heading.push_back(heading);
        scale *= 1.0 + drift * 0.0002;
        const Eigen::Vector3d step = gt[i] - gt[i - 1];
        raw.push_back(raw.back() +
                      scale * (Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()) * step));
      }
      SearchAreaOptions paper = PaperArea();
      paper.plane_normal = Eigen::Vector3d::UnitZ();
      paper.exclude_recent = 10;
      SearchAreaOptions uncertain = paper;
      uncertain.drift_rate = 0.1;
      // c: the same, with the first revisit accepted as a loop (lap + 5 -> 5) and its rotation.
      SearchArea a(paper), b(uncertain), c(uncertain);
      int queries = 0, in_paper = 0, in_uncertain = 0, in_tied = 0;
      double candidates = 0.0, tied_candidates = 0.0, paper_candidates = 0.0, eligible = 0.0;
      for (int t = 0; t < 2 * lap; ++t) {
        a.Add(t, raw[t]);
        b.Add(t, raw[t]);
        c.Add(t, raw[t]);
        // The loop's rotation against the raw one (what the detector's verified pose gives).
        if (t == lap + 5)
          c.OnLoopAccepted(
              t, 5,
              Eigen::AngleAxisd(raw_heading[5] - raw_heading[t], Eigen::Vector3d::UnitZ())
                  .toRotationMatrix());
        if (t <= lap + 5) continue;
        const int64_t truth = t - lap;
        const auto contains = [&](const SearchAreaResult& r) {
          return std::binary_search(r.candidates.begin(), r.candidates.end(), truth);
        };
        const SearchAreaResult rb = b.Query(t);
        ++queries;
        const SearchAreaResult ra = a.Query(t);
        in_paper += contains(ra);
        paper_candidates += static_cast<double>(ra.candidates.size());
        in_uncertain += contains(rb);
        candidates += static_cast<double>(rb.candidates.size());
        const SearchAreaResult rc = c.Query(t);
        in_tied += contains(rc);
        tied_candidates += static_cast<double>(rc.candidates.size());
        eligible += t - paper.exclude_recent;
      }
      const double f_paper = static_cast<double>(in_paper) / queries;
      const double f_uncertain = static_cast<double>(in_uncertain) / queries;
      std::cerr << "drift x" << drift << " seed " << seed << ": truth in the paper area " << f_paper
                << " (" << paper_candidates / queries << " candidates), in the uncertainty area "
                << f_uncertain << ", candidates " << candidates / queries << " ("
                << candidates / eligible << " of global); after a loop "
                << static_cast<double>(in_tied) / queries << " with " << tied_candidates / queries
                << " candidates\n";
      EXPECT_GE(f_uncertain, 0.95) << "drift x" << drift << " seed " << seed;
      EXPECT_GE(f_uncertain, f_paper);
      EXPECT_LT(candidates / eligible, 0.5);  // an area, not the whole past
      if (drift >= 4.0) {
        EXPECT_LT(f_paper, 0.5) << "the old area should lose the truth here";
      }
      // Tied by a loop, the odometry since it is shorter: the area stays on the truth and
      // shrinks (measured: by 10-25 %; the keyframes far from the loop keep their long paths).
      EXPECT_GE(static_cast<double>(in_tied) / queries, 0.95);
      EXPECT_LT(tied_candidates, 0.95 * candidates);
    }
  }
}

// The online path length equals the trajectory's (Trajectory::CumulativeDistances, the one
// definition) at every stored keyframe; unknown ids are refused.
TEST(SearchAreaPath, PathLengthEqualsTheTrajectorysCumulativeDistance) {
  const std::vector<Eigen::Vector3d> pts = SquareThenDown();
  const SearchArea area = Build(PaperArea(), pts);
  Trajectory traj;
  for (size_t k = 0; k < pts.size(); ++k) {
    traj.poses.push_back({double(k), int64_t(k), Rigid3d(Eigen::Quaterniond::Identity(), pts[k])});
  }
  const std::vector<double> expected = traj.CumulativeDistances();
  for (size_t k = 0; k < pts.size(); ++k)
    EXPECT_DOUBLE_EQ(area.PathLength(static_cast<int64_t>(k)), expected[k]) << k;
  EXPECT_DOUBLE_EQ(area.PathLength(35), 10.0 + 10.0 + 8.0 + 7.0);
  EXPECT_THROW(area.PathLength(36), std::invalid_argument);
}

TEST(SearchAreaPaper, TooShortAndNoMotion) {
  SearchAreaOptions o = PaperArea();
  o.exclude_recent = 2;
  SearchArea area(o);
  area.Add(0, Eigen::Vector3d::Zero());
  EXPECT_EQ(area.Query(0).status, SearchAreaStatus::kTooShort);
  for (int k = 1; k < 10; ++k) area.Add(k, Eigen::Vector3d::Zero());
  const SearchAreaResult r = area.Query(9);
  EXPECT_EQ(r.status, SearchAreaStatus::kNoMotion);
  EXPECT_TRUE(r.candidates.empty());
}

TEST(SearchAreaOptions, CheckAndCallerErrors) {
  SearchAreaOptions o = PaperArea();
  EXPECT_NO_THROW(o.Check());
  o.alpha_deg = 0.0;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o = {};
  o.exclude_recent = -1;
  EXPECT_THROW(SearchArea{o}, std::invalid_argument);
  o = {};
  o.plane_normal = Eigen::Vector3d::Zero();
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o = {};
  o.refit_growth = 0.0;
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o.refit_growth = 1.5;  // the plane of the first 3 keyframes would serve for most of a run
  EXPECT_THROW(o.Check(), std::invalid_argument);
  o.refit_growth = 1.0;
  EXPECT_NO_THROW(o.Check());
  SearchArea area(PaperArea());
  area.Add(4, Eigen::Vector3d::Zero());
  EXPECT_THROW(area.Add(4, Eigen::Vector3d::Ones()), std::invalid_argument);
  EXPECT_THROW(area.Query(5), std::invalid_argument);
  EXPECT_THROW(area.OnLoopAccepted(4, 9), std::invalid_argument);
  EXPECT_THROW(area.Add(5, Eigen::Vector3d(NAN, 0, 0)), std::invalid_argument);
  EXPECT_EQ(ParseSearchStrategy("radius"), SearchStrategy::kRadius);
  EXPECT_THROW(ParseSearchStrategy("nope"), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Oracle: random trajectories, every strategy, compared with brute force at every keyframe.

enum class Shape { kRandomWalk, kCircles, kFigureEight };

std::vector<Eigen::Vector3d> MakeTrajectory(Shape shape, int n, std::mt19937_64& rng,
                                            Eigen::Matrix3d* rotation) {
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<Eigen::Vector3d> pts;
  double heading = 2 * M_PI * uni(rng);
  Eigen::Vector2d xy(0, 0);
  const double laps = 1.5 + 2.0 * uni(rng);
  for (int k = 0; k < n; ++k) {
    const double a = 2 * M_PI * laps * k / n;
    switch (shape) {
      case Shape::kRandomWalk:
        heading += 0.4 * noise(rng);
        xy += Eigen::Vector2d(std::cos(heading), std::sin(heading)) * (0.5 + uni(rng));
        break;
      case Shape::kCircles:
        xy = Eigen::Vector2d(20 * std::cos(a), 20 * std::sin(a)) +
             0.8 * Eigen::Vector2d(noise(rng), noise(rng));
        break;
      case Shape::kFigureEight:
        xy = Eigen::Vector2d(25 * std::sin(a), 12 * std::sin(2 * a)) +
             0.5 * Eigen::Vector2d(noise(rng), noise(rng));
        break;
    }
    pts.emplace_back(xy.x(), xy.y(), 0.05 * noise(rng));
  }
  *rotation = Eigen::AngleAxisd(0.8 * uni(rng),
                                Eigen::Vector3d(noise(rng), noise(rng), noise(rng)).normalized())
                  .toRotationMatrix();
  const Eigen::Vector3d offset(50 * noise(rng), 50 * noise(rng), 50 * noise(rng));
  for (auto& p : pts) p = *rotation * p + offset;
  return pts;
}

TEST(SearchAreaOracle, IdenticalToBruteForceOnRandomTrajectories) {
  auto rng = test::SeededRng(3);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  int compared = 0, paper_hits = 0, paper_fallbacks = 0, backward_hits = 0, no_end = 0,
      nonempty = 0;
  size_t uncertainty_added = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const Shape shape = static_cast<Shape>(trial % 3);
    Eigen::Matrix3d rot;
    const int n = 150 + static_cast<int>(150 * uni(rng));
    const auto pts = MakeTrajectory(shape, n, rng, &rot);
    SearchAreaOptions o = PaperArea();
    o.strategy = static_cast<SearchStrategy>((trial / 3) % 3);
    o.alpha_deg = 10.0 + 170.0 * uni(rng);
    o.exclude_recent = static_cast<int>(20 * uni(rng));
    o.radius = 2.0 + 6.0 * uni(rng);
    o.radius_in_plane = uni(rng) < 0.5;
    o.drift_rate = (trial / 18) % 2 == 0 ? 0.0 : 0.005 + 0.05 * uni(rng);
    o.drift_base_steps = 5.0 * uni(rng);
    o.drift_loops = static_cast<int>(4 * uni(rng));
    o.drift_max_candidates = uni(rng) < 0.5 ? 1000 : 1 + static_cast<int>(30 * uni(rng));
    o.fallback_count = 1 + static_cast<int>(40 * uni(rng));
    if (uni(rng) < 0.5) o.plane_normal = rot.col(2);
    // The grid cell: automatic, given, or given far outside what the grid keeps (raised to 1/16
    // of the automatic cell, lowered to the extent): the area must not depend on it.
    const double cell_pick = uni(rng);
    o.cell_size = cell_pick < 0.2   ? 0.3 + 3.0 * uni(rng)
                  : cell_pick < 0.3 ? 1e-300
                  : cell_pick < 0.4 ? 1e6
                                    : 0.0;
    SearchArea area(o);
    std::vector<std::pair<int, int>> loops;
    for (int t = 0; t < n; ++t) {
      const int64_t id = 7 * t + 3;
      area.Add(id, pts[t]);
      if (t > 50 && uni(rng) < 0.02) {
        const int match = static_cast<int>((t - 40) * uni(rng));
        area.OnLoopAccepted(id, 7 * match + 3);
        loops.emplace_back(t, match);
      }
      const SearchAreaResult got = area.Query(id);
      const auto want = BruteForceSearchArea(pts, area.plane(), o, t, loops);
      uncertainty_added += got.uncertainty_added;
      std::vector<int64_t> want_ids;
      for (int k : want.candidates) want_ids.push_back(7 * k + 3);
      ASSERT_EQ(got.candidates, want_ids)
          << "trial " << trial << " t " << t << " " << got.BriefReport();
      ASSERT_EQ(got.status, want.status) << "trial " << trial << " t " << t;
      ASSERT_EQ(got.branch, want.branch) << "trial " << trial << " t " << t;
      if (want.start >= 0) {
        ASSERT_EQ(got.start_keyframe, 7 * want.start + 3);
      }
      if (want.end >= 0) {
        ASSERT_EQ(got.end_keyframe, 7 * want.end + 3);
      }
      ++compared;
      nonempty += !want.candidates.empty();
      paper_hits += want.branch == PaperBranch::kSegmentHit;
      paper_fallbacks += want.branch == PaperBranch::kNoIntersection;
      backward_hits += want.branch == PaperBranch::kBackwardRayHit;
      no_end += want.start >= 0 && want.end < 0;
    }
  }
  // The random cases must exercise every branch, otherwise the comparison proves little.
  EXPECT_GT(compared, 10000);
  EXPECT_GT(paper_hits, 1000);
  EXPECT_GT(paper_fallbacks, 50);
  EXPECT_GT(backward_hits, 20);
  EXPECT_GT(no_end, 20);
  EXPECT_GT(uncertainty_added, 1000u);  // the uncertainty area adds to the others
  std::cerr << compared << " queries: " << paper_hits << " segment hits, " << backward_hits
            << " backward-ray hits, " << paper_fallbacks << " fallbacks, " << no_end
            << " without p'\n";
  EXPECT_GT(nonempty, compared / 2);
}

TEST(SearchAreaPlane, FittedNormalMatchesTiltAndIsStable) {
  auto rng = test::SeededRng(4);
  Eigen::Matrix3d rot;
  const auto pts = MakeTrajectory(Shape::kCircles, 2000, rng, &rot);
  SearchArea area(PaperArea());
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < pts.size(); ++k) {
    area.Add(static_cast<int64_t>(k), pts[k]);
    const Eigen::Vector3d normal = area.plane().normal;
    if (k > 100) {
      ASSERT_GT(std::abs(normal.dot(rot.col(2))), 0.999) << k;
      ASSERT_GT(normal.dot(previous), 0.99) << "sign flipped at " << k;
    }
    previous = normal;
  }
}

// Writes the geometry of one paper query for docs/img/search_area.png
// (scripts/plot_search_area.py reads it). Also a check that the JSON holds the answer.
TEST(SearchAreaFigure, DumpGeometryJson) {
  SearchAreaOptions o = PaperArea();
  o.plane_normal = Eigen::Vector3d::UnitZ();
  o.exclude_recent = 5;
  o.alpha_deg = 60.0;
  // A loop that comes back toward its first leg at an angle, sampled every 1.5 units.
  const std::vector<Eigen::Vector2d> corners = {{0, 0},  {30, 0}, {30, 20},
                                                {2, 20}, {2, 14}, {9, 4}};
  std::vector<Eigen::Vector3d> pts;
  for (size_t c = 1; c < corners.size(); ++c) {
    const Eigen::Vector2d e = corners[c] - corners[c - 1];
    const int steps = static_cast<int>(std::ceil(e.norm() / 1.5));
    for (int i = c == 1 ? 0 : 1; i <= steps; ++i) {
      const Eigen::Vector2d q = corners[c - 1] + e * (static_cast<double>(i) / steps);
      pts.emplace_back(q.x(), q.y(), 0.0);
    }
  }
  const SearchArea area = Build(o, pts);
  const SearchAreaResult r = area.Query(static_cast<int64_t>(pts.size()) - 1);
  ASSERT_EQ(r.branch, PaperBranch::kSegmentHit) << r.BriefReport();
  ASSERT_FALSE(r.candidates.empty());
  const auto path = test::TempDir() / "search_area_figure.json";
  {
    std::ofstream out(path);
    out.precision(12);
    out << "{\"alpha_deg\": " << o.alpha_deg << ", \"exclude_recent\": " << o.exclude_recent
        << ", \"wedge_side\": " << r.wedge_side << ",\n \"positions\": [";
    for (size_t k = 0; k < pts.size(); ++k) {
      const Eigen::Vector2d q = r.plane.Project(pts[k]);
      out << (k ? ", " : "") << "[" << q.x() << ", " << q.y() << "]";
    }
    out << "],\n \"position\": [" << r.position.x() << ", " << r.position.y() << "]"
        << ", \"direction\": [" << r.direction.x() << ", " << r.direction.y() << "]"
        << ", \"p\": [" << r.p->x() << ", " << r.p->y() << "]";
    if (r.p_end) out << ", \"p_end\": [" << r.p_end->x() << ", " << r.p_end->y() << "]";
    out << ", \"start\": " << *r.start_keyframe << ", \"end\": " << r.end_keyframe.value_or(-1)
        << ", \"candidates\": [";
    for (size_t i = 0; i < r.candidates.size(); ++i) out << (i ? ", " : "") << r.candidates[i];
    out << "]}\n";
  }
  std::cerr << "search-area figure geometry: " << path << "\n";
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"candidates\": [" + std::to_string(r.candidates.front())),
            std::string::npos);
}

}  // namespace
}  // namespace sparseloop
