// Multi-session loop closure and relocalisation on the synthetic aerial world.
//
// Session 1 flies a circuit; its keyframe records go through the map database (SQLite round
// trip) and are loaded into a second detector as a prior session. Session 2 flies over the same
// area, shifted and with a different phase, and its raw poses live in another Sim(3) frame (other
// origin, rotation and scale, as a monocular vSLAM restarted elsewhere would give). Checks: the
// cross-session loops are correct by GT distance and none is false; relocalisation of pose-less
// keyframes lands on the right keyframe with the pose close to GT.
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>

#include <gtest/gtest.h>

#include "cameras.h"
#include "sparseloop/loop/loop_detector.h"
#include "sparseloop/map/map_database.h"
#include "sparseloop/pipeline/map_records.h"
#include "sparseloop/synthetic/renderer.h"
#include "sparseloop/synthetic/texture.h"
#include "sparseloop/synthetic/vslam_sim.h"
#include "sparseloop/synthetic/worlds.h"
#include "test_util.h"

namespace sparseloop {
namespace {

using synthetic::FlightPlanOptions;

CameraIntrinsics SmallCamera() { return test::PinholeCamera(250.0, 320, 240, 159.5, 119.5); }

// The camera footprint on the ground at 40 m is about 51 x 38 m; a cross-session pair is a true
// revisit when the two cameras are closer than this (metres).
constexpr double kTrueLoopDistance = 20.0;

struct Frame {
  Rigid3d gt;  // world_from_cam, metres
  cv::Mat image;
  std::vector<cv::Point2f> pixels;
  std::vector<float> depths_metric;
};

class MultiSession : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    synthetic::ProceduralTextureOptions t;
    t.count = 6;
    t.size = 256;
    world_ = new synthetic::World(synthetic::MakeAerialWorld(synthetic::MakeProceduralTextures(t)));
    FlightPlanOptions f;
    f.plan = synthetic::FlightPlan::kCircuit;
    f.size = 120.0;
    f.altitude = 40.0;
    f.laps = 1;
    f.frames = 60;
    const Trajectory a = synthetic::MakeFlightTrajectory(f);
    session1_ = new std::vector<Frame>();
    session2_ = new std::vector<Frame>();
    for (size_t i = 0; i < a.poses.size(); ++i)
      session1_->push_back(Render(a.poses[i].world_from_cam, i));
    // Session 2: same circuit shifted by (6, -4) m, starting 20 frames later along it.
    for (size_t k = 0; k < a.poses.size(); ++k) {
      Rigid3d p = a.poses[(k + 20) % a.poses.size()].world_from_cam;
      p.translation += Eigen::Vector3d(6.0, -4.0, 0.0);
      session2_->push_back(Render(p, 1000 + k));
    }
  }
  static void TearDownTestSuite() {
    delete world_;
    delete session1_;
    delete session2_;
  }

  static Frame Render(const Rigid3d& pose, uint64_t seed) {
    synthetic::RenderOptions o;
    o.noise_sigma = 1.0;
    const auto r = synthetic::RenderFrame(*world_, SmallCamera(), pose, o, {}, seed);
    Frame f;
    f.gt = pose;
    f.image = cv::Mat(r.image.height, r.image.width, CV_8UC1).clone();
    std::memcpy(f.image.data, r.image.pixels.data(), r.image.pixels.size());
    for (const auto& m : synthetic::SelectMappedPixels(r.image, r.depth, 1.0)) {
      f.pixels.emplace_back(m.u, m.v);
      f.depths_metric.push_back(m.depth);
    }
    return f;
  }

  // `raw_from_gt` maps GT (metres) to the session's raw frame (raw units = metres x its scale);
  // depths are in raw units.
  static KeyframeInput Input(const Frame& f, int64_t id, const Sim3d& raw_from_gt, bool pose,
                             bool depths) {
    KeyframeInput in;
    in.id = id;
    in.timestamp = 0.1 * static_cast<double>(id + 1);
    in.image = f.image;
    in.intrinsics = SmallCamera();
    if (pose) {
      // A vSLAM reports its camera in its own units: scale 1, translation in raw units.
      Sim3d raw = raw_from_gt * Sim3d(f.gt);
      raw.scale = 1.0;
      in.world_from_cam = raw;
    }
    in.mapped_pixels = f.pixels;
    if (depths) {
      for (float d : f.depths_metric) in.mapped_depths.push_back(d * float(raw_from_gt.scale));
    }
    return in;
  }

  static LoopDetector::Options Options() {
    LoopDetector::Options o;
    o.features.max_features = 150;
    return o;
  }

  // Session 1 (raw = GT frame) processed, stored in a map file, reloaded into a fresh detector.
  static std::unique_ptr<LoopDetector> DetectorWithSession1(bool depths) {
    const auto dir = test::TempDir("multisession");
    const auto path = dir / "map.db";
    {
      LoopDetector first(Options());
      auto map = MapDatabase::Open(path);
      const int64_t s = map->BeginSession("one");
      EXPECT_EQ(s, 1);
      for (size_t i = 0; i < session1_->size(); ++i) {
        first.Process(Input((*session1_)[i], int64_t(i), Sim3d(), true, depths));
        map->PutKeyframe(ToStoredKeyframe(first.record(int64_t(i)), s));
      }
    }
    auto map = MapDatabase::Open(path);
    auto second = std::make_unique<LoopDetector>(Options());
    EXPECT_EQ(LoadPriorSessions(*map, 0.0f, second.get()), session1_->size());
    return second;
  }

  // Another Sim(3) frame for session 2: rotated 40 deg about an oblique axis, moved, scale 0.3.
  static Sim3d Session2Frame() {
    return Sim3d(0.3,
                 Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())),
                 Eigen::Vector3d(100.0, -50.0, 7.0));
  }

  // Options::loop_distance_window's step (w keyframes each side of match m, before query q),
  // from the raw positions fed to the detector.
  static double LocalStep(
      const std::vector<Eigen::Vector3d>& raw, size_t m, size_t q,
      size_t w = static_cast<size_t>(LoopDetector::Options{}.loop_distance_window)) {
    const size_t lo = m >= w ? m - w : 0, hi = std::min(m + w, q - 1);
    double path = 0.0;
    for (size_t i = lo; i < hi; ++i) path += (raw[i + 1] - raw[i]).norm();
    return path / static_cast<double>(hi - lo);
  }

  static double DistanceDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
    return a.angularDistance(b) * 180.0 / M_PI;
  }

  static synthetic::World* world_;
  static std::vector<Frame>* session1_;
  static std::vector<Frame>* session2_;
};
synthetic::World* MultiSession::world_ = nullptr;
std::vector<Frame>* MultiSession::session1_ = nullptr;
std::vector<Frame>* MultiSession::session2_ = nullptr;

// A loop is a revisit (LoopDetector::Options::max_loop_distance_steps): one session flies the
// circuit, then flies on around it again 7.2 m to the side (session 2's frames, raw = GT, metres,
// depths given: metric loops; one pose segment, no jump). The raw step is ~8 m: with the gate
// at 0.5 steps (around the match) no metric loop farther than that is kept (those frames end
// rejected_by_consistency or find a nearer match), while the default 10 steps keeps them.
TEST_F(MultiSession, RevisitDistanceGateRejectsMetricLoopsFartherThanTheSteps) {
  std::vector<Frame> frames = *session1_;
  // Session 2's frame k is at pose k + 20 (+ the offset): continue the circuit from pose 0.
  for (size_t k = 0; k < session2_->size(); ++k)
    frames.push_back((*session2_)[(k + 40) % session2_->size()]);
  std::vector<Eigen::Vector3d> raw;  // raw = GT here
  for (const Frame& f : frames) raw.push_back(f.gt.translation);
  const auto metric = [](const LoopResult& r) {
    return r.detected() &&
           (r.pose_kind == RelativePoseKind::kSim3 || r.pose_kind == RelativePoseKind::kSE3Metric);
  };
  const auto run = [&](double max_steps) {
    LoopDetector::Options o = Options();
    o.max_loop_distance_steps = max_steps;
    LoopDetector d(o);
    std::vector<LoopResult> results;
    for (size_t i = 0; i < frames.size(); ++i)
      results.push_back(d.Process(Input(frames[i], int64_t(i), Sim3d(), true, true)));
    return results;
  };
  const std::vector<LoopResult> kept = run(10.0);
  const std::vector<LoopResult> gated = run(0.5);
  int far_kept = 0, gated_far = 0, rejected = 0;
  for (size_t i = session1_->size(); i < frames.size(); ++i) {
    const auto limit = [&](const LoopResult& r) {
      return 0.5 * LocalStep(raw, static_cast<size_t>(r.match_id), i);
    };
    if (metric(kept[i]) && kept[i].match_from_query.translation.norm() > limit(kept[i])) ++far_kept;
    if (metric(gated[i]) && gated[i].match_from_query.translation.norm() > limit(gated[i])) {
      ++gated_far;
      ADD_FAILURE() << "frame " << i << " kept a metric loop "
                    << gated[i].match_from_query.translation.norm() << " m from its match (limit "
                    << limit(gated[i]) << " m)";
    }
    rejected += gated[i].status == LoopStatus::kRejectedByConsistency;
  }
  std::cerr << far_kept
            << " metric loops beyond 0.5 steps with the default gate; gated: " << rejected
            << " frames rejected_by_consistency\n";
  EXPECT_GE(far_kept, 10) << "the test needs metric loops beyond the gate";
  EXPECT_EQ(gated_far, 0);
  EXPECT_GE(rejected, far_kept / 3) << "far loops rejected (or replaced by a nearer match)";
}

// The gate's step is the raw step around the match (Options::loop_distance_window), because a
// metric loop's translation is in the match's raw units and a monocular trajectory's scale
// drifts. Here the second lap's raw scale is 3x the first's (raw steps and depths, scaled about
// the lap's start, as a vSLAM whose scale grew): the run's mean step is then ~2x the first lap's,
// so "0.5 mean steps" keeps the loops 7.2 m to the side that 0.5 of the match's own steps (~4 m)
// rejects. The window's gate keeps none beyond 0.5 local steps; the whole path's mean keeps some.
TEST_F(MultiSession, RevisitDistanceGateMeasuresStepsAroundTheMatch) {
  std::vector<Frame> frames = *session1_;
  for (size_t k = 0; k < session2_->size(); ++k)
    frames.push_back((*session2_)[(k + 40) % session2_->size()]);
  const size_t lap2 = session1_->size();
  const Eigen::Vector3d start = frames[lap2].gt.translation;
  const Sim3d raw_from_gt_lap2 = Sim3d(3.0, Eigen::Quaterniond::Identity(), -2.0 * start);
  std::vector<Eigen::Vector3d> raw(frames.size());
  for (size_t i = 0; i < frames.size(); ++i)
    raw[i] = i < lap2 ? frames[i].gt.translation : raw_from_gt_lap2 * frames[i].gt.translation;
  const auto run = [&](int window) {
    LoopDetector::Options o = Options();
    o.appearance_fallback = true;  // lap 2's raw positions are far from lap 1's
    o.max_loop_distance_steps = 0.5;
    o.loop_distance_window = window;
    LoopDetector d(o);
    int beyond = 0, metric = 0;
    for (size_t i = 0; i < frames.size(); ++i) {
      const LoopResult r = d.Process(
          Input(frames[i], int64_t(i), i < lap2 ? Sim3d() : raw_from_gt_lap2, true, true));
      if (!r.detected() ||
          (r.pose_kind != RelativePoseKind::kSim3 && r.pose_kind != RelativePoseKind::kSE3Metric))
        continue;
      ++metric;
      const size_t m = static_cast<size_t>(r.match_id);
      beyond += r.match_from_query.translation.norm() > 0.5 * LocalStep(raw, m, i, 10);
    }
    std::cerr << "window " << window << ": " << metric << " metric loops, " << beyond
              << " beyond 0.5 steps around the match\n";
    return beyond;
  };
  EXPECT_EQ(run(10), 0);  // a 10-keyframe window: a lap here is 60 keyframes
  EXPECT_GE(run(0), 3) << "the whole path's mean step lets loops 7.2 m to the side through";
}

TEST_F(MultiSession, StoredRecordRoundTripKeepsWhatMatchingNeeds) {
  LoopDetector d(Options());
  d.Process(Input((*session1_)[3], 3, Sim3d(), true, true));
  const KeyframeRecord& r = d.record(3);
  const KeyframeRecord back = FromStoredKeyframe(ToStoredKeyframe(r, 1), 0.0f);
  EXPECT_EQ(back.id, r.id);
  EXPECT_EQ(back.descriptors, r.descriptors);
  ASSERT_EQ(back.keypoints.size(), r.keypoints.size());
  for (size_t i = 0; i < r.keypoints.size(); ++i) {
    EXPECT_EQ(back.keypoints[i].x, r.keypoints[i].x);
    EXPECT_EQ(back.keypoints[i].y, r.keypoints[i].y);
  }
  EXPECT_EQ(back.depths, r.depths);
  EXPECT_EQ(back.focal_px, r.focal_px);
  EXPECT_TRUE(back.has_pose);
  EXPECT_TRUE(back.world_from_cam.ToVector().isApprox(r.world_from_cam.ToVector()));
  // A record without focal (schema-1 map) takes the fallback, and fails without one.
  StoredKeyframe s = ToStoredKeyframe(r, 1);
  s.focal_px = 0.0f;
  EXPECT_EQ(FromStoredKeyframe(s, 321.0f).focal_px, 321.0f);
  EXPECT_THROW(FromStoredKeyframe(s, 0.0f), std::invalid_argument);
}

TEST_F(MultiSession, AddPriorKeyframesRejectsBadInput) {
  LoopDetector d(Options());
  d.Process(Input((*session1_)[0], 0, Sim3d(), true, false));
  KeyframeRecord r = d.record(0);
  EXPECT_THROW(d.AddPriorKeyframes(0, {r}), std::invalid_argument);     // 0 = current session
  EXPECT_THROW(d.AddPriorKeyframes(2, {r, r}), std::invalid_argument);  // duplicate id
  KeyframeRecord no_focal = r;
  no_focal.focal_px = 0.0f;
  EXPECT_THROW(d.AddPriorKeyframes(2, {no_focal}), std::invalid_argument);
  EXPECT_EQ(d.num_prior_keyframes(), 0u);  // nothing added by a rejected call
  d.AddPriorKeyframes(2, {r});
  EXPECT_THROW(d.AddPriorKeyframes(2, {r}), std::invalid_argument);  // session added twice
  EXPECT_EQ(d.prior_record(2, r.id).descriptors, r.descriptors);
}

// The main multi-session check, without depths (essential matrix, the monocular case).
TEST_F(MultiSession, SecondSessionInAnotherSim3FrameFindsCorrectCrossSessionLoops) {
  auto detector = DetectorWithSession1(/*depths=*/false);
  const Sim3d frame2 = Session2Frame();
  int cross = 0, wrong = 0;
  double max_rot = 0.0;
  for (size_t k = 0; k < session2_->size(); ++k) {
    const LoopResult r = detector->Process(Input((*session2_)[k], int64_t(k), frame2, true, false));
    if (!r.detected() || r.match_session == 0) continue;
    ASSERT_EQ(r.match_session, 1);
    ++cross;
    const double d =
        ((*session2_)[k].gt.translation - (*session1_)[size_t(r.match_id)].gt.translation).norm();
    if (d > kTrueLoopDistance) ++wrong;
    EXPECT_LE(d, kTrueLoopDistance) << "query " << k << " -> session 1 keyframe " << r.match_id;
    // Orientation in session 1's frame (= GT frame here) is measured by the essential matrix.
    ASSERT_TRUE(r.has_world_from_query);
    // Nadir view of planar ground is near-degenerate for the 5-point essential matrix: measured
    // rotation errors 0.5-17 deg (K = 150, 320x240); the depth-based relocalisation below is
    // sub-degree.
    const double rot = DistanceDeg(r.world_from_query.rotation, (*session2_)[k].gt.rotation);
    max_rot = std::max(max_rot, rot);
    EXPECT_LT(rot, 20.0) << k;
  }
  // Every keyframe of session 2 overlaps session 1 (shift 7 m, footprint ~50 m).
  EXPECT_GE(cross, int(session2_->size()) / 2) << "cross-session loops found";
  EXPECT_EQ(wrong, 0);
  std::printf("cross-session loops: %d of %zu keyframes, wrong %d, max rotation error %.2f deg\n",
              cross, session2_->size(), wrong, max_rot);
}

// Records of another K match: a map stored at one K serves a later session at another. Session 1
// stored at K_a (its records hold K_a features), session 2 in another Sim(3) frame at K_b, no
// depths: the cross-session loops are found as at the same K, and no more are wrong than at the
// stored K itself. A pair's floors
// (matches, inliers) and score are those of the K its stored record was kept with. A symmetric
// K = 20 query (20 features) rarely reaches the floors of a K = 150 record: it finds some, none
// wrong (the floors of K = 20 let 3 wrong loops of 49 through, all 60 frames queried).
TEST_F(MultiSession, ASessionStoredAtAnotherKServesThisOne) {
  auto options = [](int k, bool asymmetric) {
    LoopDetector::Options o = Options();
    o.features.max_features = k;
    o.asymmetric_matching = asymmetric;
    return o;
  };
  // Session 1 stored once per (K, asymmetric); session 2 queried on every other frame.
  std::map<std::pair<int, bool>, std::filesystem::path> maps;
  auto stored_map = [&](const LoopDetector::Options& stored) {
    const auto key = std::make_pair(stored.features.max_features, stored.asymmetric_matching);
    if (maps.count(key)) return maps[key];
    const auto path =
        test::TempDir("other_k_" + std::to_string(key.first) + (key.second ? "a" : "s")) / "map.db";
    LoopDetector first(stored);
    auto map = MapDatabase::Open(path);
    const int64_t s = map->BeginSession("one");
    for (size_t i = 0; i < session1_->size(); ++i) {
      first.Process(Input((*session1_)[i], int64_t(i), Sim3d(), true, false));
      map->PutKeyframe(ToStoredKeyframe(first.record(int64_t(i)), s));
    }
    return maps[key] = path;
  };
  auto cross_session = [&](const LoopDetector::Options& stored, const LoopDetector::Options& now) {
    auto map = MapDatabase::Open(stored_map(stored));
    LoopDetector second(now);
    LoadPriorSessions(*map, 0.0f, &second);
    std::pair<int, int> found_wrong{0, 0};
    for (size_t k = 0; k < session2_->size(); k += 2) {
      const LoopResult r =
          second.Process(Input((*session2_)[k], int64_t(k), Session2Frame(), true, false));
      if (!r.detected() || r.match_session != 1) continue;
      ++found_wrong.first;
      const double d =
          ((*session2_)[k].gt.translation - (*session1_)[size_t(r.match_id)].gt.translation).norm();
      if (d > kTrueLoopDistance) ++found_wrong.second;
      EXPECT_GT(r.score, 0.0);
      EXPECT_LE(r.score, 1.0);
    }
    return found_wrong;
  };
  const int half = int(session2_->size()) / 4;  // of the 30 queries
  // The same K stored and searched: what a record of that K gives (cross-session pairs are
  // verified by appearance only, without the weak-pair agreement or the pose gate, so a K = 20
  // record lets a few wrong pairs through even at its own K).
  std::map<int, int> wrong_at_own_k;
  for (const int k : {20, 150}) {
    const auto [found, wrong] = cross_session(options(k, true), options(k, true));
    EXPECT_GE(found, half) << "K " << k;
    wrong_at_own_k[k] = wrong;
    std::printf("stored K %d, now K %d asymmetric: %d found, %d wrong\n", k, k, found, wrong);
  }
  for (const auto& [a, b] : std::vector<std::pair<LoopDetector::Options, LoopDetector::Options>>{
           {options(150, false), options(20, true)},
           {options(20, true), options(150, true)},
           {options(150, false), options(20, false)},
           {options(20, false), options(150, false)}}) {
    const auto [found, wrong] = cross_session(a, b);
    SCOPED_TRACE(testing::Message()
                 << "stored K " << a.features.max_features << ", now K " << b.features.max_features
                 << (b.asymmetric_matching ? " asymmetric" : ""));
    const bool small_symmetric_query =
        !b.asymmetric_matching && b.features.max_features < a.features.max_features;
    EXPECT_GE(found, small_symmetric_query ? 3 : half);
    EXPECT_LE(wrong, wrong_at_own_k[a.features.max_features]);
    std::printf("stored K %d, now K %d%s: %d found, %d wrong\n", a.features.max_features,
                b.features.max_features, b.asymmetric_matching ? " asymmetric" : "", found, wrong);
  }
}

// Disabling the prior search gives no cross-session loop (SecondSessionInAnotherSim3Frame* is not
// vacuous), and the same frames against an unrelated prior session give none either.
TEST_F(MultiSession, NoCrossSessionLoopsWhenDisabledOrUnrelated) {
  auto detector = DetectorWithSession1(false);
  LoopDetector::Options off = Options();
  off.search_prior_sessions = false;
  LoopDetector disabled(off);
  // Unrelated prior: session 1's flight over another world (other textures). (The same world
  // 2 km away is NOT unrelated: its tiles reuse the same few procedural textures, and the
  // detector then finds 30 genuine-looking matches there.)
  LoopDetector unrelated(Options());
  {
    synthetic::ProceduralTextureOptions t;
    t.count = 6;
    t.size = 256;
    t.seed = 99;
    const synthetic::World other = synthetic::MakeAerialWorld(synthetic::MakeProceduralTextures(t));
    LoopDetector far(Options());
    std::vector<KeyframeRecord> records;
    for (size_t i = 0; i < session1_->size(); i += 2) {
      synthetic::RenderOptions o;
      o.noise_sigma = 1.0;
      const auto r = synthetic::RenderFrame(other, SmallCamera(), (*session1_)[i].gt, o, {}, i);
      Frame f;
      f.gt = (*session1_)[i].gt;
      f.image = cv::Mat(r.image.height, r.image.width, CV_8UC1);
      std::memcpy(f.image.data, r.image.pixels.data(), r.image.pixels.size());
      far.Process(Input(f, int64_t(i), Sim3d(), true, false));
      records.push_back(far.record(int64_t(i)));
    }
    unrelated.AddPriorKeyframes(1, std::move(records));
  }
  disabled.AddPriorKeyframes(1, [&] {
    std::vector<KeyframeRecord> v;
    for (size_t i = 0; i < session1_->size(); ++i)
      v.push_back(detector->prior_record(1, int64_t(i)));
    return v;
  }());
  int cross_disabled = 0, cross_unrelated = 0;
  for (size_t k = 0; k < session2_->size(); k += 2) {
    const auto in = Input((*session2_)[k], int64_t(k), Session2Frame(), true, false);
    cross_disabled += disabled.Process(in).match_session != 0;
    const LoopResult u = unrelated.Process(in);
    cross_unrelated += u.detected() && u.match_session != 0;
  }
  EXPECT_EQ(cross_disabled, 0);
  EXPECT_EQ(cross_unrelated, 0);
}

// Relocalisation after tracking loss, inside one session: after the full circuit (with poses,
// raw frame = another Sim(3) frame, with depths) tracking is lost; the next 10 keyframes (the
// shifted second flight over the same ground) arrive without a pose and are matched against every
// stored keyframe. The pose is checked in metres through the known raw frame.
TEST_F(MultiSession, PoselessKeyframesRelocaliseInTheCurrentSession) {
  LoopDetector detector(Options());
  const Sim3d raw_from_gt = Session2Frame();
  for (size_t i = 0; i < session1_->size(); ++i)
    detector.Process(Input((*session1_)[i], int64_t(i), raw_from_gt, true, true));
  int relocalised = 0;
  double max_position_err = 0.0, max_rotation_err = 0.0;
  const int64_t first_lost = int64_t(session1_->size());
  for (size_t k = 0; k < 10; ++k) {
    const Frame& f = (*session2_)[k];
    const LoopResult r =
        detector.Process(Input(f, first_lost + int64_t(k), raw_from_gt, false, true));
    EXPECT_TRUE(r.relocalization);
    if (!r.detected()) continue;
    ++relocalised;
    EXPECT_EQ(r.match_session, 0);
    ASSERT_LT(r.match_id, first_lost);  // only keyframes with a pose can anchor a relocalisation
    EXPECT_LE((f.gt.translation - (*session1_)[size_t(r.match_id)].gt.translation).norm(),
              kTrueLoopDistance);
    ASSERT_TRUE(r.has_world_from_query);
    // Back to metres: gt_from_raw * world_from_query (camera scale 1 in raw units -> 1 / 0.3).
    const Sim3d gt_pose = raw_from_gt.Inverse() * r.world_from_query;
    max_position_err = std::max(max_position_err, (gt_pose.translation - f.gt.translation).norm());
    max_rotation_err = std::max(max_rotation_err, DistanceDeg(gt_pose.rotation, f.gt.rotation));
  }
  std::printf("relocalised %d of 10, max position error %.3f m, max rotation error %.3f deg\n",
              relocalised, max_position_err, max_rotation_err);
  EXPECT_GE(relocalised, 8);
  EXPECT_LT(max_position_err, 1.0);  // metres, camera at 40 m altitude
  EXPECT_LT(max_rotation_err, 1.0);  // degrees
  // A pose-less keyframe is stored (id taken) but has no pose.
  EXPECT_EQ(detector.num_keyframes(), session1_->size() + 10);
  EXPECT_FALSE(detector.record(first_lost + 3).has_pose);
}

// Explicit Relocalize() against a prior session (world frame of session 1 = GT): the pose comes
// out in session 1's frame; nothing is stored.
TEST_F(MultiSession, RelocalizeAgainstPriorSessionGivesPoseInItsFrame) {
  auto detector = DetectorWithSession1(/*depths=*/true);
  int relocalised = 0;
  double max_position_err = 0.0, max_rotation_err = 0.0;
  for (size_t k = 0; k < session2_->size(); k += 6) {
    const LoopResult r =
        detector->Relocalize(Input((*session2_)[k], 500, Session2Frame(), false, true));
    EXPECT_TRUE(r.relocalization);
    if (!r.detected()) continue;
    ++relocalised;
    EXPECT_EQ(r.match_session, 1);
    EXPECT_LE(
        ((*session2_)[k].gt.translation - (*session1_)[size_t(r.match_id)].gt.translation).norm(),
        kTrueLoopDistance);
    EXPECT_EQ(r.pose_kind, RelativePoseKind::kSim3);
    ASSERT_TRUE(r.has_world_from_query);
    max_position_err = std::max(
        max_position_err, (r.world_from_query.translation - (*session2_)[k].gt.translation).norm());
    max_rotation_err = std::max(
        max_rotation_err, DistanceDeg(r.world_from_query.rotation, (*session2_)[k].gt.rotation));
  }
  std::printf("relocalised %d of %zu, max position error %.3f m, max rotation error %.3f deg\n",
              relocalised, (session2_->size() + 5) / 6, max_position_err, max_rotation_err);
  EXPECT_GE(relocalised, 8);
  EXPECT_LT(max_position_err, 1.0);
  EXPECT_LT(max_rotation_err, 1.0);
  EXPECT_EQ(detector->num_keyframes(), 0u);
}

// Without a pose and relocalisation disabled, the old rule holds: rejected before storing.
TEST_F(MultiSession, PoselessKeyframeRejectedWhenRelocalisationIsOff) {
  LoopDetector::Options o = Options();
  o.relocalize_without_pose = false;
  LoopDetector detector(o);
  EXPECT_THROW(detector.Process(Input((*session1_)[0], 0, Sim3d(), false, false)),
               std::invalid_argument);
  EXPECT_EQ(detector.num_keyframes(), 0u);
}

}  // namespace
}  // namespace sparseloop
