// How good is the paper's search area on a real trajectory? KITTI 00 ground-truth poses with the
// published loop ground truth (z014xw): the fraction of loop queries whose true match lies in the
// area. This measures the geometric definition, not an implementation detail (the oracle test
// does that).
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include <gtest/gtest.h>

#include "sparseloop/search/search_area.h"
#include "test_util.h"

namespace sparseloop {
namespace {

std::vector<Eigen::Vector3d> ReadKittiPositions(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::vector<Eigen::Vector3d> positions;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ss(line);
    double m[12];
    for (double& v : m) ss >> v;
    if (!ss) break;
    positions.emplace_back(m[3], m[7], m[11]);
  }
  return positions;
}

// query frame -> set of true match frames.
std::map<int, std::set<int>> ReadLoopGt(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::map<int, std::set<int>> loops;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    int i = 0, j = 0;
    if (ss >> i >> j) loops[i].insert(j);
  }
  return loops;
}

struct Coverage {
  double fraction = 0.0;         // GT queries with at least one true match among the candidates
  double mean_candidates = 0.0;  // over GT queries
  double fallback_rate = 0.0;    // kPaper: queries answered by the no-intersection fallback
  int queries = 0;
};

Coverage Measure(const std::vector<Eigen::Vector3d>& positions,
                 const std::map<int, std::set<int>>& loops, const SearchAreaOptions& o) {
  SearchArea area(o);
  Coverage c;
  size_t candidates = 0;
  int covered = 0, fallbacks = 0;
  for (int t = 0; t < static_cast<int>(positions.size()); ++t) {
    area.Add(t, positions[t]);
    const auto it = loops.find(t);
    if (it == loops.end()) continue;
    const SearchAreaResult r = area.Query(t);
    const std::set<int64_t> got(r.candidates.begin(), r.candidates.end());
    bool hit = false;
    for (int j : it->second) hit = hit || got.count(j) > 0;
    covered += hit;
    fallbacks += r.fallback_used;
    candidates += r.candidates.size();
    ++c.queries;
  }
  c.fraction = static_cast<double>(covered) / c.queries;
  c.mean_candidates = static_cast<double>(candidates) / c.queries;
  c.fallback_rate = static_cast<double>(fallbacks) / c.queries;
  return c;
}

TEST(SearchAreaKitti, PaperAreaCoverageOfGroundTruthLoops) {
  SL_REQUIRE_DATA("kitti_gt_poses");
  SL_REQUIRE_DATA("kitti_loop_gt");
  const auto positions = ReadKittiPositions(test::DataDir() / "kitti_gt_poses/00.txt");
  const auto loops = ReadLoopGt(test::DataDir() / "kitti_loop_gt/z014xw_kitti00GroundTruth.txt");
  ASSERT_EQ(positions.size(), 4541u);
  ASSERT_GT(loops.size(), 100u);

  SearchAreaOptions paper;
  paper.drift_rate = 0.0;                         // the paper's area alone
  paper.plane_normal = Eigen::Vector3d::UnitY();  // KITTI camera frame: ground plane x-z
  paper.exclude_recent = 50;                      // 5 s at 10 Hz
  const Coverage plain = Measure(positions, loops, paper);
  SearchAreaOptions uncertain = paper;  // with the product's uncertainty area
  uncertain.drift_rate = SearchAreaOptions{}.drift_rate;
  const Coverage widened = Measure(positions, loops, uncertain);
  SearchAreaOptions radius = paper;
  radius.strategy = SearchStrategy::kRadius;
  radius.radius = 10.0;
  const Coverage near = Measure(positions, loops, radius);

  for (const auto& [name, c] : {std::pair{"paper", plain}, std::pair{"paper+uncertainty", widened},
                                std::pair{"radius10m", near}}) {
    std::cerr << "KITTI 00 " << name << ": " << c.queries << " GT queries, coverage " << c.fraction
              << ", mean candidates " << c.mean_candidates << ", fallback rate " << c.fallback_rate
              << "\n";
    testing::Test::RecordProperty(std::string(name) + "_coverage", std::to_string(c.fraction));
    testing::Test::RecordProperty(std::string(name) + "_mean_candidates",
                                  std::to_string(c.mean_candidates));
  }
  // Floors set a little below the values measured when this test was written (see
  // docs/SEARCH_AREA.md); a regression of the geometry shows up here.
  EXPECT_GE(plain.fraction, 0.76);  // measured 0.788 (819 queries)
  EXPECT_GE(widened.fraction, plain.fraction);
  EXPECT_GE(widened.fraction, 0.99);        // measured 1.0 (286 candidates: no loop accepted)
  EXPECT_GE(near.fraction, 0.95);           // measured 1.0: GT loops are close by construction
  EXPECT_LT(plain.mean_candidates, 150.0);  // measured 112 (global: 3366)
}

}  // namespace
}  // namespace sparseloop
