#include "sparseloop/pipeline/config.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <type_traits>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "sparseloop/core/error.h"

namespace sparseloop {
namespace {

// A reference to one field of PipelineOptions, const or not.
#define SL_FIELD(member) \
  [](auto& o) -> auto& { return o.member; }

template <typename T>
T ReadValue(const nlohmann::json& v) {
  if constexpr (std::is_same_v<T, bool>) {
    if (!v.is_boolean()) throw ConfigValueError{"a boolean", v.dump()};
    return v.get<bool>();
  } else if constexpr (std::is_integral_v<T>) {
    if (!v.is_number_integer()) throw ConfigValueError{"an integer", v.dump()};
    const bool fits = v.is_number_unsigned()
                          ? v.get<uint64_t>() <= uint64_t(std::numeric_limits<T>::max())
                          : v.get<int64_t>() >= int64_t(std::numeric_limits<T>::min()) &&
                                (!std::is_signed_v<T> ||
                                 v.get<int64_t>() <= int64_t(std::numeric_limits<T>::max()));
    if (!fits) {
      throw ConfigValueError{fmt::format("an integer in [{}, {}]", std::numeric_limits<T>::min(),
                                         std::numeric_limits<T>::max()),
                             v.dump()};
    }
    return v.get<T>();
  } else {
    static_assert(std::is_floating_point_v<T>);
    if (!v.is_number()) throw ConfigValueError{"a number", v.dump()};
    return v.get<T>();
  }
}

// The type of the field a SL_FIELD lambda refers to.
template <typename Field>
using FieldType =
    std::remove_cvref_t<decltype(std::declval<Field>()(std::declval<PipelineOptions&>()))>;

template <typename T>
const char* TypeName() {
  if constexpr (std::is_same_v<T, bool>) return "boolean";
  if constexpr (std::is_integral_v<T>) return "integer";
  return "number";
}

class KeyList {
 public:
  // A boolean or numeric field.
  template <typename Field>
  void Add(std::string path, Field field, std::string unit, std::string help) {
    using T = FieldType<Field>;
    keys_.push_back(ConfigKey{
        std::move(path),
        TypeName<T>(),
        std::move(unit),
        std::move(help),
        {},
        [field](const PipelineOptions& o) { return nlohmann::json(field(o)); },
        [field](const nlohmann::json& v, PipelineOptions* o) { field(*o) = ReadValue<T>(v); }});
  }

  // An enum field written as a name: `values` are the accepted ones, `name` the enum's own
  // name function (so the spelling lives next to the enum).
  template <typename Field, typename Name>
  void AddEnum(std::string path, Field field, std::vector<FieldType<Field>> values, Name name,
               std::string help) {
    std::vector<std::string> names;
    for (const auto e : values) names.push_back(name(e));
    std::string expected = "one of ";
    for (size_t i = 0; i < names.size(); ++i) expected += (i ? "|" : "") + names[i];
    keys_.push_back(
        ConfigKey{std::move(path), "string", "", std::move(help), names,
                  [field, name](const PipelineOptions& o) {
                    return nlohmann::json(std::string(name(field(o))));
                  },
                  [field, values, names, expected](const nlohmann::json& v, PipelineOptions* o) {
                    if (!v.is_string()) throw ConfigValueError{"a string", v.dump()};
                    const auto it = std::find(names.begin(), names.end(), v.get<std::string>());
                    if (it == names.end()) throw ConfigValueError{expected, v.dump()};
                    field(*o) = values[it - names.begin()];
                  }});
  }

  void Add(ConfigKey key) { keys_.push_back(std::move(key)); }
  std::vector<ConfigKey> Take() { return std::move(keys_); }

 private:
  std::vector<ConfigKey> keys_;
};

// detector.search.plane_normal: unset (absent) or [x, y, z].
ConfigKey PlaneNormalKey() {
  return ConfigKey{"detector.search.plane_normal",
                   "[x, y, z]",
                   "",
                   "normal of the motion plane (any length > 0);"
                   " absent: fitted to the trajectory by PCA; KITTI camera poses: [0, 1, 0]",
                   {},
                   [](const PipelineOptions& o) -> nlohmann::json {
                     const auto& n = o.detector.search.plane_normal;
                     if (!n) return nullptr;
                     return {n->x(), n->y(), n->z()};
                   },
                   [](const nlohmann::json& n, PipelineOptions* o) {
                     if (!n.is_array() || n.size() != 3 || !n[0].is_number() || !n[1].is_number() ||
                         !n[2].is_number()) {
                       throw ConfigValueError{"an array of 3 numbers", ""};
                     }
                     o->detector.search.plane_normal = Eigen::Vector3d(
                         n[0].get<double>(), n[1].get<double>(), n[2].get<double>());
                   }};
}

// detector.features.*: the informative features.
void AddFeatureKeys(KeyList& k) {
  const std::string f = "detector.features.";
  k.Add(f + "max_features", SL_FIELD(detector.features.max_features), "features",
        "K, informative features kept per keyframe ([5, 10000])");
  k.AddEnum(
      f + "ranking", SL_FIELD(detector.features.ranking),
      {FeatureRanking::kPopcount, FeatureRanking::kResponse, FeatureRanking::kGridResponse},
      [](FeatureRanking r) { return ToString(r); },
      "how the K are chosen: popcount (paper), ORB response, grid (response per cell)");
  k.Add(f + "orb_candidates", SL_FIELD(detector.features.orb_candidates), "features",
        "ORB detections before ranking (>= K)");
  k.Add(f + "orb_levels", SL_FIELD(detector.features.orb_levels), "levels",
        "ORB pyramid levels ([1, 16])");
  k.Add(f + "orb_scale_factor", SL_FIELD(detector.features.orb_scale_factor), "ratio",
        "ORB pyramid scale step (1, 2]");
  k.Add(f + "orb_fast_threshold", SL_FIELD(detector.features.orb_fast_threshold), "grey levels",
        "FAST threshold");
  k.Add(f + "grid_cols", SL_FIELD(detector.features.grid_cols), "cells",
        "grid ranking: columns ([1, 1000])");
  k.Add(f + "grid_rows", SL_FIELD(detector.features.grid_rows), "cells",
        "grid ranking: rows ([1, 1000])");
  k.Add(f + "use_gradient_mask", SL_FIELD(detector.features.use_gradient_mask), "",
        "keep features in the high-gradient area only when the keyframe brings no mask");
}

// detector.search.*: the search area.
void AddSearchKeys(KeyList& k) {
  const std::string s = "detector.search.";
  k.AddEnum(
      s + "strategy", SL_FIELD(detector.search.strategy),
      {SearchStrategy::kPaper, SearchStrategy::kRadius, SearchStrategy::kGlobal},
      [](SearchStrategy x) { return ToString(x); },
      "search area: paper (wedge on the trajectory), radius, global (every past keyframe)");
  k.Add(s + "alpha_deg", SL_FIELD(detector.search.alpha_deg), "deg",
        "paper: half-opening of the wedge (0, 180]");
  k.Add(s + "exclude_recent", SL_FIELD(detector.search.exclude_recent), "keyframes",
        "most recent keyframes before the query never searched (>= 0)");
  k.Add(s + "radius", SL_FIELD(detector.search.radius), "world units",
        "radius: search radius around the current position");
  k.Add(s + "radius_in_plane", SL_FIELD(detector.search.radius_in_plane), "",
        "radius: measured in the motion plane (true) or in 3D (false)");
  k.Add(s + "drift_rate", SL_FIELD(detector.search.drift_rate), "fraction",
        "uncertainty area: keyframes within base + this fraction of the raw path between them "
        "and the query, or through a recent loop (0: off)");
  k.Add(s + "drift_base_steps", SL_FIELD(detector.search.drift_base_steps), "mean steps",
        "uncertainty area: radius at zero path, in mean raw steps (>= 0)");
  k.Add(PlaneNormalKey());
  k.Add(s + "fallback_count", SL_FIELD(detector.search.fallback_count), "keyframes",
        "paper: keyframes searched when the motion ray hits nothing (>= 1)");
}

// detector.match.*, detector.verify.*, detector.local_map.*: matching and verification.
void AddMatchingKeys(KeyList& k) {
  const std::string m = "detector.match.";
  k.Add(m + "max_distance", SL_FIELD(detector.match.max_distance), "bits",
        "largest accepted Hamming distance [0, 256]");
  k.Add(m + "ratio", SL_FIELD(detector.match.ratio), "ratio",
        "best < ratio x second best, (0, 1] (1: no ratio test)");
  k.Add(m + "mutual", SL_FIELD(detector.match.mutual), "",
        "keep a match only when it is also best in the other direction");

  const std::string v = "detector.verify.";
  k.Add(v + "threshold_px", SL_FIELD(detector.verify.threshold_px), "px",
        "RANSAC inlier threshold");
  k.Add(v + "min_inliers", SL_FIELD(detector.verify.min_inliers), "inliers",
        "a pair with fewer geometric inliers fails");
  k.Add(v + "use_depths", SL_FIELD(detector.verify.use_depths), "",
        "PnP / Sim(3) when depths exist");

  const std::string l = "detector.local_map.";
  k.Add(l + "enabled", SL_FIELD(detector.local_map.enabled), "",
        "verify monocular loops again by PnP against a local map of the match");
  k.Add(l + "window", SL_FIELD(detector.local_map.window), "keyframes",
        "keyframes each side of the match whose points enter the local map (>= 0)");
  k.Add(l + "neighbours", SL_FIELD(detector.local_map.neighbours), "keyframes",
        "keyframes each side each map keyframe is triangulated with (>= 1)");
  k.Add(l + "query_points", SL_FIELD(detector.local_map.query_points), "",
        "when the map falls short: PnP of the match against the query's triangulated points");
  k.Add(l + "min_image_pose_inliers",
        SL_FIELD(detector.local_map.triangulation.min_image_pose_inliers), "inliers",
        "a neighbour's relative pose from the images (essential matrix) when this many matches "
        "agree, else the raw one (0 = off: the vSLAM's raw poses only, else >= 8)");
}

// detector.*: what is stored, matched, accepted and gated.
void AddDetectorPolicyKeys(KeyList& k) {
  const std::string d = "detector.";
  k.Add(d + "asymmetric_matching", SL_FIELD(detector.asymmetric_matching), "",
        "match the stored K features against the query's whole extraction (not K x K)");
  k.Add(d + "repeatability_window", SL_FIELD(detector.repeatability_window), "keyframes",
        "store first the features re-found in this many previous keyframes [0, 16] (0: off)");
  k.Add(d + "weak_pairs", SL_FIELD(detector.weak_pairs), "",
        "accept pairs below the inlier floor when the keyframe before verified the same place");
  k.Add(d + "appearance_fallback", SL_FIELD(detector.appearance_fallback), "",
        "no loop in the search area: rank every stored keyframe by descriptor matches and "
        "verify the best");
  k.Add(d + "fallback_candidates", SL_FIELD(detector.fallback_candidates), "keyframes",
        "appearance fallback: keyframes matched in full after the cheap pre-ranking (0: all)");
  k.Add(d + "pose_jump_factor", SL_FIELD(detector.pose_jump_factor), "",
        "a raw step this x the usual one starts a new pose segment (0: off)");
  k.Add(d + "check_every", SL_FIELD(detector.check_every), "keyframes",
        "run the loop check every N keyframes (>= 1)");
  k.Add(d + "min_matches", SL_FIELD(detector.min_matches), "matches",
        "candidates with fewer descriptor matches are not verified");
  k.Add(d + "max_verify", SL_FIELD(detector.max_verify), "candidates",
        "best-ranked candidates verified geometrically (>= 1)");
  k.Add(d + "best_of_verified", SL_FIELD(detector.best_of_verified), "",
        "no pose: verify every candidate to verify and keep the loop with the most inliers "
        "(false: the first that passes)");
  k.Add(d + "min_inlier_fraction_of_k", SL_FIELD(detector.min_inlier_fraction_of_k), "fraction",
        "inlier floor grows as ceil(fraction x K) [0, 1]");
  k.Add(d + "min_path_ratio", SL_FIELD(detector.min_path_ratio), "ratio",
        "path between candidate and query >= ratio x their distance (needs poses; 0: off)");
  k.Add(d + "overlap_gap", SL_FIELD(detector.overlap_gap), "keyframes",
        "no pose: keyframes still sharing the scene with the query are excluded until this "
        "many in a row do not (0: off)");
  k.Add(d + "continuity_check", SL_FIELD(detector.continuity_check), "",
        "no pose: reject a loop when a keyframe between it and the query verifies as well");
  k.Add(d + "max_loop_distance_steps", SL_FIELD(detector.max_loop_distance_steps), "steps",
        "reject a metric loop whose query is farther than this many raw steps (mean around the "
        "match) from it (0: off)");
  k.Add(d + "check_consistency", SL_FIELD(detector.check_consistency), "",
        "reject loops whose rotation disagrees with the pose prior");
  k.Add(d + "consistency_max_deg", SL_FIELD(detector.consistency_max_deg), "deg",
        "rotation gate: largest tolerance");
  k.AddEnum(
      d + "retrieval", SL_FIELD(detector.retrieval),
      {CandidateRetrieval::kBruteForce, CandidateRetrieval::kAnn},
      [](CandidateRetrieval r) { return ToString(r); },
      "candidates: brute_force (match every one) or ann (index votes)");
  k.Add(d + "search_prior_sessions", SL_FIELD(detector.search_prior_sessions), "",
        "multi-session: match earlier map sessions when this one gives no loop");
  k.Add(d + "relocalize_without_pose", SL_FIELD(detector.relocalize_without_pose), "",
        "a keyframe without a pose is relocalised (false: rejected)");
}

// detector.ann.* (the approximate index) and detector.seed.
void AddAnnKeys(KeyList& k) {
  const std::string a = "detector.ann.";
  k.Add(a + "max_candidates", SL_FIELD(detector.ann.max_candidates), "keyframes",
        "top-voted keyframes matched and verified (>= 1)");
  k.Add("detector.seed", SL_FIELD(detector.seed), "", "RNG seed of the verification");
}

// Registration order is the order of `config --dump` and of the docs table.
void AddDetectorKeys(KeyList& k) {
  AddFeatureKeys(k);
  AddSearchKeys(k);
  AddMatchingKeys(k);
  AddDetectorPolicyKeys(k);
  AddAnnKeys(k);
}

void AddOptimizerKeys(KeyList& k) {
  const std::string p = "optimizer.";
  k.Add(p + "max_iterations", SL_FIELD(optimizer.max_iterations), "iterations",
        "Levenberg-Marquardt iterations (>= 1)");
  const std::vector<RobustLoss> losses = {RobustLoss::kTrivial, RobustLoss::kHuber,
                                          RobustLoss::kCauchy};
  k.AddEnum(
      p + "loop_loss", SL_FIELD(optimizer.loop_loss), losses,
      [](RobustLoss l) { return ToString(l); }, "robust loss on loop residuals");
  k.AddEnum(
      p + "edge_loss", SL_FIELD(optimizer.edge_loss), losses,
      [](RobustLoss l) { return ToString(l); }, "robust loss on odometry edges");
  k.Add(p + "loss_scale", SL_FIELD(optimizer.loss_scale), "sigmas",
        "whitened residual where the robust loss bends ([1e-6, 1e6])");
  k.AddEnum(
      p + "rejection", SL_FIELD(optimizer.rejection),
      {OutlierRejection::kNone, OutlierRejection::kPcm},
      [](OutlierRejection r) { return ToString(r); }, "outlier loop rejection");
  k.Add(p + "pcm_confidence", SL_FIELD(optimizer.pcm.confidence), "probability",
        "PCM: chi-square quantile of the consistency threshold");
  k.Add(p + "pcm_step_translation_fraction", SL_FIELD(optimizer.pcm.step_translation_fraction),
        "fraction", "PCM: translation sigma per step / step length");
  k.Add(p + "pcm_step_rotation_sigma_rad", SL_FIELD(optimizer.pcm.step_rotation_sigma_rad), "rad",
        "PCM: rotation sigma per step");
  k.Add(p + "pcm_step_scale_sigma", SL_FIELD(optimizer.pcm.step_scale_sigma), "log-scale",
        "PCM: scale sigma per step (Sim(3))");
  k.Add(p + "pcm_free_scale_prior", SL_FIELD(optimizer.pcm.free_scale_prior), "",
        "PCM: test loops with a free scale (se3_metric) with the scale drift prior, not at 1");
  k.Add(p + "pcm_odometry_check", SL_FIELD(optimizer.pcm.odometry_check), "",
        "PCM: also test each loop alone against its own odometry chain");
  k.Add(p + "num_threads", SL_FIELD(optimizer.num_threads), "threads", "Ceres threads ([1, 256])");
  k.Add(p + "log_progress", SL_FIELD(optimizer.log_progress), "",
        "log every iteration (through the logger, never stdout)");
  k.Add(p + "loop_weight_rounds", SL_FIELD(optimizer.loop_weight_rounds), "solves",
        "re-solves with heavier kept loops while the median one is inconsistent (>= 0; 0: off)");
}

void AddGraphKeys(KeyList& k) {
  const std::string o = "odometry.";
  k.Add(o + "translation_fraction", SL_FIELD(odometry.translation_fraction), "fraction",
        "odometry translation sigma / step length");
  k.Add(o + "min_translation_sigma", SL_FIELD(odometry.min_translation_sigma), "raw units",
        "floor of the odometry translation sigma");
  k.Add(o + "rotation_sigma_rad", SL_FIELD(odometry.rotation_sigma_rad), "rad",
        "odometry rotation sigma per step");
  k.Add(o + "scale_sigma", SL_FIELD(odometry.scale_sigma), "log-scale",
        "odometry scale sigma per step (Sim(3))");
  const std::string d = "direction_loop.";
  k.Add(d + "direction_sigma_rad", SL_FIELD(direction_loop.direction_sigma_rad), "rad",
        "loop with a direction only: angular sigma of the direction");
  k.Add(d + "rotation_sigma_rad", SL_FIELD(direction_loop.rotation_sigma_rad), "rad",
        "loop with a direction only: rotation sigma");
  k.Add(d + "weight", SL_FIELD(direction_loop.weight), "",
        "loop with a direction only: "
        "information multiplier");
  k.AddEnum(
      "vertex_type", SL_FIELD(vertex_type),
      {VertexType::kSim3, VertexType::kSe3, VertexType::kFourDof},
      [](VertexType v) { return ToString(v); },
      "pose-graph vertices (sim3 for monocular raw poses)");
  k.Add("loop_translation_sigma_steps", SL_FIELD(loop_translation_sigma_steps), "steps",
        "metric loop: translation sigma in raw steps at the query");
  k.Add("loop_rotation_sigma_rad", SL_FIELD(loop_rotation_sigma_rad), "rad",
        "metric loop: rotation sigma");
  k.Add("loop_scale_sigma", SL_FIELD(loop_scale_sigma), "log-scale", "metric loop: scale sigma");
  k.Add("loop_information_from_estimate", SL_FIELD(loop_information_from_estimate), "",
        "PnP / Sim(3) loops use their own measured covariance");
  k.Add("loop_covariance_inflation", SL_FIELD(loop_covariance_inflation), "",
        "multiplier of a loop's measured covariance (>= 1)");
  k.Add("use_mapped_pixels", SL_FIELD(use_mapped_pixels), "",
        "read DIR/mapped/NNNNNN.txt (u v depth) when the dataset has it");
  k.Add("raw_association_max_dt", SL_FIELD(raw_association_max_dt), "s",
        "raw poses matched to frames by timestamp within this");
  k.Add("skip_unreadable_frames", SL_FIELD(skip_unreadable_frames), "",
        "skip (and count) a frame whose image cannot be read instead of failing");
}

#undef SL_FIELD

// Every proper prefix of a key path ("detector", "detector.features", ...): a JSON object.
const std::set<std::string>& Groups() {
  static const std::set<std::string> groups = [] {
    std::set<std::string> g;
    for (const ConfigKey& key : ConfigKeys()) {
      for (size_t dot = key.path.find('.'); dot != std::string::npos;
           dot = key.path.find('.', dot + 1)) {
        g.insert(key.path.substr(0, dot));
      }
    }
    return g;
  }();
  return groups;
}

// The registered key with this dotted path, or null.
const ConfigKey* FindKey(const std::string& path) {
  static const std::map<std::string, const ConfigKey*> by_path = [] {
    std::map<std::string, const ConfigKey*> m;
    for (const ConfigKey& key : ConfigKeys()) m[key.path] = &key;
    return m;
  }();
  const auto it = by_path.find(path);
  return it == by_path.end() ? nullptr : it->second;
}

// Options that mirror another option, set after every change of the configuration.
void SyncMirroredOptions(PipelineOptions* options) {
  options->detector.verify.seed = options->detector.seed;
}

void ReadObject(const nlohmann::json& j, const std::string& prefix, const std::string& source,
                PipelineOptions* options) {
  auto fail = [&](const std::string& path, const std::string& expected, const std::string& got) {
    throw FileError(source, 0, fmt::format("{} for \"{}\"", expected, path), got);
  };
  if (!j.is_object()) fail(prefix.empty() ? "<root>" : prefix, "a JSON object", "");
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string path = prefix.empty() ? it.key() : prefix + "." + it.key();
    if (const ConfigKey* key = FindKey(path)) {
      try {
        key->set(*it, options);
      } catch (const ConfigValueError& e) {
        fail(path, e.expected, e.got);
      }
    } else if (Groups().count(path)) {
      ReadObject(*it, path, source, options);
    } else if (path == "doc") {  // written by `config --dump`, not read
      if (!it->is_object()) fail(path, "a JSON object", "");
    } else {
      fail(path, "a known configuration key", "unknown key");
    }
  }
}

bool InScope(const ConfigKey& key, const std::string& scope) {
  return scope.empty() || key.path == scope || key.path.rfind(scope + ".", 0) == 0;
}

nlohmann::json::json_pointer Pointer(const std::string& path) {
  std::string p = "/" + path;
  std::replace(p.begin(), p.end(), '.', '/');
  return nlohmann::json::json_pointer(p);
}

// The values of the keys under `scope`, as a JSON tree (an unset value is left out).
nlohmann::json ConfigJson(const PipelineOptions& options, const std::string& scope) {
  nlohmann::json config = nlohmann::json::object();
  for (const ConfigKey& key : ConfigKeys()) {
    if (!InScope(key, scope)) continue;
    nlohmann::json value = key.get(options);
    if (!value.is_null()) config[Pointer(key.path)] = std::move(value);
  }
  return config;
}

}  // namespace

std::string ConfigKey::Doc() const {
  std::string doc = help;
  if (!choices.empty()) {
    doc += "; one of ";
    for (size_t i = 0; i < choices.size(); ++i) doc += (i ? "|" : "") + choices[i];
  }
  if (!unit.empty()) doc += " [" + unit + "]";
  return doc;
}

const std::vector<ConfigKey>& ConfigKeys() {
  static const std::vector<ConfigKey> keys = [] {
    KeyList k;
    AddDetectorKeys(k);
    AddOptimizerKeys(k);
    AddGraphKeys(k);
    return k.Take();
  }();
  return keys;
}

namespace {

// The key of `config` to blame for `message`, a failed Check() of `options`: the key whose return
// to its default changes the outcome, preferring one whose last part the message names (four keys
// end in rotation_sigma_rad). Empty when none does.
std::string BlamedKey(const nlohmann::json& config, const PipelineOptions& options,
                      const std::string& message) {
  const PipelineOptions defaults;
  std::string blamed;
  for (const ConfigKey& key : ConfigKeys()) {
    bool given = false;
    try {
      given = config.contains(Pointer(key.path));
    } catch (const nlohmann::json::exception&) {
      given = false;
    }
    if (!given) continue;
    PipelineOptions reverted = options;
    try {
      key.set(key.get(defaults), &reverted);
    } catch (const ConfigValueError&) {
      continue;
    }
    SyncMirroredOptions(&reverted);
    try {
      reverted.Check();
    } catch (const std::invalid_argument& e) {
      if (e.what() == message) continue;  // not this key
    }
    const std::string leaf = key.path.substr(key.path.rfind('.') + 1);
    if (message.find(leaf) != std::string::npos) return key.path;
    if (blamed.empty()) blamed = key.path;
  }
  return blamed;
}

}  // namespace

void ApplyConfig(const nlohmann::json& config, const std::string& source,
                 PipelineOptions* options) {
  ReadObject(config, "", source, options);
  SyncMirroredOptions(options);
  try {
    options->Check();
  } catch (const std::invalid_argument& e) {
    const std::string key = BlamedKey(config, *options, e.what());
    throw FileError(
        source, 0,
        key.empty() ? "valid option values" : fmt::format("a valid value for \"{}\"", key),
        e.what());
  }
}
void ApplyConfigOverride(const std::string& key, const std::string& value,
                         PipelineOptions* options) {
  const ConfigKey* found = FindKey(key);
  if (found == nullptr) {
    // The known keys whose last component matches, else those containing it (4+ characters).
    const auto& keys = ConfigKeys();
    const std::string leaf =
        key.substr(key.rfind('.') == std::string::npos ? 0 : key.rfind('.') + 1);
    std::vector<std::string> close;
    for (const ConfigKey& k : keys) {
      if (k.path.substr(k.path.rfind('.') + 1) == leaf) close.push_back(k.path);
    }
    if (close.empty() && leaf.size() >= 4) {
      for (const ConfigKey& k : keys) {
        if (k.path.find(leaf) != std::string::npos) close.push_back(k.path);
      }
    }
    if (close.size() > 5) close.resize(5);
    throw std::invalid_argument(fmt::format(
        "{}: expected a configuration key{}, got an unknown key (`sparseloop config --dump` "
        "lists them)",
        key, close.empty() ? "" : fmt::format(" such as {}", fmt::join(close, ", "))));
  }
  CheckJsonNesting(value, key, false);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(value);
  } catch (const nlohmann::json::exception&) {
    j = value;  // not JSON: a bare word, read as a string
  }
  try {
    found->set(j, options);
  } catch (const ConfigValueError& e) {
    throw std::invalid_argument(fmt::format("{}: expected {}, got {}", key, e.expected, e.got));
  }
  SyncMirroredOptions(options);
}

namespace {

// 1 + the number of line ends before `offset` ("\n", "\r\n" or a lone "\r").
int LineAt(const std::string& text, size_t offset) {
  offset = std::min(offset, text.size());
  int line = 1;
  for (size_t i = 0; i < offset; ++i) {
    if (text[i] == '\n' || (text[i] == '\r' && (i + 1 >= text.size() || text[i + 1] != '\n')))
      ++line;
  }
  return line;
}

// The 1-based column of byte `offset` on its line (line ends as LineAt counts them).
int ColumnAt(const std::string& text, size_t offset) {
  offset = std::min(offset, text.size());
  size_t start = offset;
  while (start > 0 && text[start - 1] != '\n' && text[start - 1] != '\r') --start;
  return static_cast<int>(offset - start) + 1;
}

// The JSON parser's message without its exception name and its own position
// ("[json.exception.parse_error.101] parse error at line 1, column 49: "): it counts "\n" only,
// so a CR-only file was all "line 1". What remains says what was wrong ("syntax error while
// parsing object key - unexpected '}'; expected string literal").
std::string ParserMessage(std::string what) {
  if (what.rfind("[json.exception.", 0) == 0) {
    const size_t close = what.find("] ");
    if (close != std::string::npos) what.erase(0, close + 2);
  }
  if (what.rfind("parse error", 0) == 0) {
    const size_t colon = what.find(": ");
    if (colon != std::string::npos) what.erase(0, colon + 2);
  }
  return what;
}

// The line of the `n`-th (0-based) `"key"` followed by a colon in `text`; 0 when not found (a key
// written with escapes).
int LineOfKey(const std::string& text, const std::string& key, size_t n) {
  const std::string quoted = "\"" + key + "\"";
  for (size_t pos = text.find(quoted); pos != std::string::npos; pos = text.find(quoted, pos + 1)) {
    const size_t after = text.find_first_not_of(" \t\r\n", pos + quoted.size());
    if (after == std::string::npos || text[after] != ':') continue;
    if (n-- == 0) return LineAt(text, pos);
  }
  return 0;
}

// Parses `text`, refusing a key given twice in one object (JSON allows it, and the last value
// would silently win): FileError with the key's dotted path and the line of the repeat.
nlohmann::json ParseWithoutDuplicateKeys(const std::string& text, const std::string& name) {
  std::vector<std::pair<std::string, std::set<std::string>>> objects;  // path, keys seen
  std::map<std::string, size_t> seen_anywhere;                         // key -> occurrences
  std::string last_key;
  const nlohmann::json::parser_callback_t check =
      [&](int /*depth*/, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
        using Event = nlohmann::json::parse_event_t;
        if (event == Event::object_start) {
          const std::string parent = objects.empty() ? "" : objects.back().first;
          const std::string path = objects.empty() || last_key.empty() ? parent
                                   : parent.empty()                    ? last_key
                                                                       : parent + "." + last_key;
          objects.push_back({path, {}});
          last_key.clear();
        } else if (event == Event::object_end) {
          if (!objects.empty()) objects.pop_back();
          last_key.clear();
        } else if (event == Event::key && parsed.is_string()) {
          last_key = parsed.get<std::string>();
          const size_t occurrence = seen_anywhere[last_key]++;
          if (!objects.empty() && !objects.back().second.insert(last_key).second) {
            const std::string& parent = objects.back().first;
            throw FileError(name, LineOfKey(text, last_key, occurrence), "each key once per object",
                            fmt::format("\"{}\" a second time",
                                        parent.empty() ? last_key : parent + "." + last_key));
          }
        } else if (event == Event::array_start || event == Event::value) {
          last_key.clear();
        }
        return true;
      };
  return nlohmann::json::parse(text, check);
}

}  // namespace

void CheckJsonNesting(const std::string& text, const std::string& source, bool source_is_file) {
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;  // the escaped character
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '{' || c == '[') {
      if (++depth > kMaxConfigJsonDepth) {
        const std::string expected = fmt::format("JSON nested at most {} deep at column {}",
                                                 kMaxConfigJsonDepth, ColumnAt(text, i));
        const std::string got = fmt::format("a level {} deep", depth);
        if (source_is_file) throw FileError(source, LineAt(text, i), expected, got);
        throw std::invalid_argument(fmt::format("{}: line {}: expected {}, got {}", source,
                                                LineAt(text, i), expected, got));
      }
    } else if (c == '}' || c == ']') {
      depth = std::max(depth - 1, 0);  // unbalanced text is the parser's error
    }
  }
}

void LoadConfigFile(const std::filesystem::path& path, PipelineOptions* options) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw FileError(path.string(), 0, "a JSON configuration file", "a directory");
  }
  std::ifstream in(path);
  if (!in) {
    throw FileError(path.string(), 0, "a readable JSON configuration file",
                    std::filesystem::exists(path, ec) ? std::strerror(errno) : "no such file");
  }
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  CheckJsonNesting(text, path.string(), true);
  nlohmann::json j;
  try {
    j = ParseWithoutDuplicateKeys(text, path.string());
  } catch (const nlohmann::json::parse_error& e) {
    // Our line and column of the last byte read (e.byte counts them from 1), every line end
    // counted.
    const size_t at = e.byte > 0 ? e.byte - 1 : 0;
    throw FileError(path.string(), LineAt(text, at),
                    fmt::format("valid JSON at column {}", ColumnAt(text, at)),
                    ParserMessage(e.what()));
  } catch (const nlohmann::json::exception& e) {
    // E.g. out_of_range 406, a number too large for a double (found by fuzz_config); the parser
    // gives no position for it.
    throw FileError(path.string(), 0, "valid JSON with representable numbers",
                    ParserMessage(e.what()));
  }
  ApplyConfig(j, path.string(), options);
}

nlohmann::json ConfigToJson(const PipelineOptions& options) { return ConfigJson(options, ""); }

nlohmann::json DumpConfig(const PipelineOptions& options, const std::string& scope) {
  nlohmann::json dump = ConfigJson(options, scope);
  nlohmann::json& doc = dump["doc"] = nlohmann::json::object();
  for (const ConfigKey& key : ConfigKeys()) {
    if (InScope(key, scope)) doc[key.path] = key.Doc();
  }
  return dump;
}

}  // namespace sparseloop
