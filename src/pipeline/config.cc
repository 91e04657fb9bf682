#include "sparseloop/pipeline/config.h"

#include <fstream>
#include <set>
#include <sstream>

#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"

namespace sparseloop {
namespace {

// Reads the keys of one JSON object strictly: every key must be consumed by a Get/Object call,
// else Finish() throws naming the unknown key.
class ObjectReader {
 public:
  ObjectReader(const nlohmann::json& j, std::string path, const std::string& source)
      : j_(j), path_(std::move(path)), source_(source) {
    if (!j_.is_object()) Fail(path_.empty() ? "<root>" : path_, "a JSON object");
  }

  template <typename T>
  void Get(const std::string& key, T* value) {
    auto it = j_.find(key);
    if (it == j_.end()) return;
    seen_.insert(key);
    try {
      if constexpr (std::is_same_v<T, bool>) {
        if (!it->is_boolean()) throw std::runtime_error("type");
      } else if constexpr (std::is_integral_v<T>) {
        if (!it->is_number_integer()) throw std::runtime_error("type");
      } else if constexpr (std::is_floating_point_v<T>) {
        if (!it->is_number()) throw std::runtime_error("type");
      } else {
        if (!it->is_string()) throw std::runtime_error("type");
      }
      *value = it->get<T>();
    } catch (const std::exception&) {
      Fail(Join(key), std::is_same_v<T, bool>       ? "a boolean"
                      : std::is_integral_v<T>       ? "an integer"
                      : std::is_floating_point_v<T> ? "a number"
                                                    : "a string");
    }
  }

  // An enum given by name, parsed by `parse` (which throws std::invalid_argument).
  template <typename E, typename Parse>
  void GetEnum(const std::string& key, E* value, Parse parse, const char* expected) {
    std::string name;
    if (!j_.contains(key)) return;
    Get(key, &name);
    try {
      *value = parse(name);
    } catch (const std::invalid_argument&) {
      Fail(Join(key), expected, "\"" + name + "\"");
    }
  }

  // The raw value of `key` (marked as read), or nullptr when absent.
  const nlohmann::json* Raw(const std::string& key) {
    auto it = j_.find(key);
    if (it == j_.end()) return nullptr;
    seen_.insert(key);
    return &*it;
  }

  std::optional<ObjectReader> Object(const std::string& key) {
    auto it = j_.find(key);
    if (it == j_.end()) return std::nullopt;
    seen_.insert(key);
    return ObjectReader(*it, Join(key), source_);
  }

  void Finish() const {
    for (auto it = j_.begin(); it != j_.end(); ++it) {
      if (!seen_.count(it.key())) Fail(Join(it.key()), "a known configuration key", "unknown key");
    }
  }

  [[noreturn]] void Fail(const std::string& key, const std::string& expected,
                         const std::string& got = "") const {
    throw FileError(source_, 0, fmt::format("{} for \"{}\"", expected, key), got);
  }

 private:
  std::string Join(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  const nlohmann::json& j_;
  std::string path_;
  const std::string& source_;
  std::set<std::string> seen_;
};

template <typename E>
E ParseByName(const std::string& name, std::initializer_list<std::pair<const char*, E>> table) {
  for (const auto& [n, e] : table) {
    if (name == n) return e;
  }
  throw std::invalid_argument(name);
}

RobustLoss ParseLoss(const std::string& n) {
  return ParseByName<RobustLoss>(n, {{"trivial", RobustLoss::kTrivial},
                                     {"huber", RobustLoss::kHuber},
                                     {"cauchy", RobustLoss::kCauchy}});
}
const char* LossName(RobustLoss l) {
  return l == RobustLoss::kTrivial ? "trivial" : l == RobustLoss::kHuber ? "huber" : "cauchy";
}
OutlierRejection ParseRejection(const std::string& n) {
  return ParseByName<OutlierRejection>(n,
                                       {{"none", OutlierRejection::kNone},
                                        {"pcm", OutlierRejection::kPcm},
                                        {"switchable", OutlierRejection::kSwitchable},
                                        {"pcm+switchable", OutlierRejection::kPcmAndSwitchable}});
}
const char* RejectionName(OutlierRejection r) {
  switch (r) {
    case OutlierRejection::kNone:
      return "none";
    case OutlierRejection::kPcm:
      return "pcm";
    case OutlierRejection::kSwitchable:
      return "switchable";
    case OutlierRejection::kPcmAndSwitchable:
      return "pcm+switchable";
  }
  return "pcm";
}
VertexType ParseVertex(const std::string& n) {
  return ParseByName<VertexType>(
      n, {{"sim3", VertexType::kSim3}, {"se3", VertexType::kSe3}, {"4dof", VertexType::kFourDof}});
}
const char* VertexName(VertexType v) {
  return v == VertexType::kSim3      ? "sim3"
         : v == VertexType::kSe3     ? "se3"
         : v == VertexType::kFourDof ? "4dof"
                                     : "se2";
}

}  // namespace

void ApplyConfig(const nlohmann::json& config, const std::string& source,
                 PipelineOptions* options) {
  ObjectReader root(config, "", source);
  if (auto d = root.Object("detector")) {
    LoopDetector::Options& o = options->detector;
    if (auto f = d->Object("features")) {
      f->Get("max_features", &o.features.max_features);
      f->GetEnum("ranking", &o.features.ranking, ParseFeatureRanking,
                 "one of popcount|response|grid");
      f->Get("orb_candidates", &o.features.orb_candidates);
      f->Get("orb_levels", &o.features.orb_levels);
      f->Get("orb_scale_factor", &o.features.orb_scale_factor);
      f->Get("orb_fast_threshold", &o.features.orb_fast_threshold);
      f->Get("grid_cols", &o.features.grid_cols);
      f->Get("grid_rows", &o.features.grid_rows);
      f->Get("use_gradient_mask", &o.features.use_gradient_mask);
      f->Finish();
    }
    if (auto s = d->Object("search")) {
      s->GetEnum("strategy", &o.search.strategy, ParseSearchStrategy, "one of paper|radius|global");
      s->Get("alpha_deg", &o.search.alpha_deg);
      s->Get("exclude_recent", &o.search.exclude_recent);
      s->Get("radius", &o.search.radius);
      s->Get("radius_in_plane", &o.search.radius_in_plane);
      s->Get("drift_tolerance", &o.search.drift_tolerance);
      s->Get("fallback_count", &o.search.fallback_count);
      if (const nlohmann::json* normal = s->Raw("plane_normal")) {
        const auto& n = *normal;
        if (!n.is_array() || n.size() != 3 || !n[0].is_number() || !n[1].is_number() ||
            !n[2].is_number()) {
          s->Fail("detector.search.plane_normal", "an array of 3 numbers");
        }
        o.search.plane_normal =
            Eigen::Vector3d(n[0].get<double>(), n[1].get<double>(), n[2].get<double>());
      }
      s->Finish();
    }
    if (auto m = d->Object("match")) {
      m->Get("max_distance", &o.match.max_distance);
      m->Get("ratio", &o.match.ratio);
      m->Get("mutual", &o.match.mutual);
      m->Finish();
    }
    if (auto v = d->Object("verify")) {
      v->Get("threshold_px", &o.verify.threshold_px);
      v->Get("confidence", &o.verify.confidence);
      v->Get("max_iterations", &o.verify.max_iterations);
      v->Get("min_inliers", &o.verify.min_inliers);
      v->Get("min_inlier_ratio", &o.verify.min_inlier_ratio);
      v->Get("use_fundamental", &o.verify.use_fundamental);
      v->Get("use_depths", &o.verify.use_depths);
      v->Finish();
    }
    if (auto l = d->Object("local_map")) {
      l->Get("enabled", &o.local_map.enabled);
      l->Get("window", &o.local_map.window);
      l->Get("neighbours", &o.local_map.neighbours);
      l->Get("max_reprojection_px", &o.local_map.triangulation.max_reprojection_px);
      l->Get("min_parallax_deg", &o.local_map.triangulation.min_parallax_deg);
      l->Finish();
    }
    d->Get("check_every", &o.check_every);
    d->Get("min_matches", &o.min_matches);
    d->Get("small_k_fraction", &o.small_k_fraction);
    d->Get("small_k_floor", &o.small_k_floor);
    d->Get("max_verify", &o.max_verify);
    d->Get("min_inlier_fraction_of_k", &o.min_inlier_fraction_of_k);
    d->Get("min_path_ratio", &o.min_path_ratio);
    d->Get("check_consistency", &o.check_consistency);
    d->Get("planar_alternatives", &o.planar_alternatives);
    d->Get("planar_alternative_tolerance", &o.planar_alternative_tolerance);
    d->Get("consistency_base_deg", &o.consistency_base_deg);
    d->Get("consistency_per_keyframe_deg", &o.consistency_per_keyframe_deg);
    d->Get("two_view_consistency_per_keyframe_deg", &o.two_view_consistency_per_keyframe_deg);
    d->Get("consistency_max_deg", &o.consistency_max_deg);
    d->Get("temporal_check", &o.temporal_check);
    d->Get("temporal_window", &o.temporal_window);
    d->GetEnum("retrieval", &o.retrieval, ParseCandidateRetrieval, "one of brute_force|ann");
    if (auto a = d->Object("ann")) {
      a->Get("hnsw_m", &o.ann.hnsw_m);
      a->Get("ef_construction", &o.ann.ef_construction);
      a->Get("ef_search", &o.ann.ef_search);
      a->Get("neighbors", &o.ann.neighbors);
      a->Get("max_distance", &o.ann.max_distance);
      a->Get("max_candidates", &o.ann.max_candidates);
      a->Get("num_threads", &o.ann.num_threads);
      a->Finish();
    }
    d->Get("seed", &o.seed);
    d->Finish();
  }
  if (auto p = root.Object("optimizer")) {
    PoseGraphOptions& o = options->optimizer;
    p->Get("max_iterations", &o.max_iterations);
    p->Get("function_tolerance", &o.function_tolerance);
    p->GetEnum("loop_loss", &o.loop_loss, ParseLoss, "one of trivial|huber|cauchy");
    p->GetEnum("edge_loss", &o.edge_loss, ParseLoss, "one of trivial|huber|cauchy");
    p->Get("loss_scale", &o.loss_scale);
    p->GetEnum("rejection", &o.rejection, ParseRejection,
               "one of none|pcm|switchable|pcm+switchable");
    p->Get("pcm_confidence", &o.pcm.confidence);
    p->Get("num_threads", &o.num_threads);
    p->Get("reduce_chains", &o.reduce_chains);
    p->Get("max_chain_length", &o.max_chain_length);
    p->Finish();
  }
  if (auto p = root.Object("odometry")) {
    OdometryWeighting& o = options->odometry;
    p->Get("translation_fraction", &o.translation_fraction);
    p->Get("min_translation_sigma", &o.min_translation_sigma);
    p->Get("rotation_sigma_rad", &o.rotation_sigma_rad);
    p->Get("scale_sigma", &o.scale_sigma);
    p->Finish();
  }
  root.GetEnum("vertex_type", &options->vertex_type, ParseVertex, "one of sim3|se3|4dof");
  root.Get("loop_translation_sigma_steps", &options->loop_translation_sigma_steps);
  root.Get("loop_rotation_sigma_rad", &options->loop_rotation_sigma_rad);
  root.Get("loop_scale_sigma", &options->loop_scale_sigma);
  root.Get("loop_information_from_estimate", &options->loop_information_from_estimate);
  root.Get("loop_covariance_inflation", &options->loop_covariance_inflation);
  root.Get("loop_min_translation_sigma_steps", &options->loop_min_translation_sigma_steps);
  root.Get("loop_min_rotation_sigma_rad", &options->loop_min_rotation_sigma_rad);
  root.Get("loop_min_scale_sigma", &options->loop_min_scale_sigma);
  root.Get("use_mapped_pixels", &options->use_mapped_pixels);
  root.Get("raw_association_max_dt", &options->raw_association_max_dt);
  root.Get("skip_unreadable_frames", &options->skip_unreadable_frames);
  root.Finish();
  options->detector.verify.seed = options->detector.seed;
  try {
    options->Check();
  } catch (const std::invalid_argument& e) {
    throw FileError(source, 0, "valid option values", e.what());
  }
}

void LoadConfigFile(const std::filesystem::path& path, PipelineOptions* options) {
  std::ifstream in(path);
  if (!in) throw FileError(path.string(), 0, "a readable JSON configuration file");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    // Convert the byte offset into a line number.
    const size_t offset = std::min<size_t>(e.byte, text.size());
    const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + offset, '\n'));
    throw FileError(path.string(), line, "valid JSON", e.what());
  } catch (const nlohmann::json::exception& e) {
    // E.g. out_of_range 406, a number too large for a double (found by fuzz_config); the parser
    // gives no position for it.
    throw FileError(path.string(), 0, "valid JSON with representable numbers", e.what());
  }
  ApplyConfig(j, path.string(), options);
}

nlohmann::json ConfigToJson(const PipelineOptions& options) {
  const LoopDetector::Options& d = options.detector;
  nlohmann::json search = {
      {"strategy", ToString(d.search.strategy)},     {"alpha_deg", d.search.alpha_deg},
      {"exclude_recent", d.search.exclude_recent},   {"radius", d.search.radius},
      {"radius_in_plane", d.search.radius_in_plane}, {"drift_tolerance", d.search.drift_tolerance},
      {"fallback_count", d.search.fallback_count}};
  if (d.search.plane_normal) {
    search["plane_normal"] = {d.search.plane_normal->x(), d.search.plane_normal->y(),
                              d.search.plane_normal->z()};
  }
  return {{"detector",
           {{"features",
             {{"max_features", d.features.max_features},
              {"ranking", ToString(d.features.ranking)},
              {"orb_candidates", d.features.orb_candidates},
              {"orb_levels", d.features.orb_levels},
              {"orb_scale_factor", d.features.orb_scale_factor},
              {"orb_fast_threshold", d.features.orb_fast_threshold},
              {"grid_cols", d.features.grid_cols},
              {"grid_rows", d.features.grid_rows},
              {"use_gradient_mask", d.features.use_gradient_mask}}},
            {"search", search},
            {"match",
             {{"max_distance", d.match.max_distance},
              {"ratio", d.match.ratio},
              {"mutual", d.match.mutual}}},
            {"verify",
             {{"threshold_px", d.verify.threshold_px},
              {"confidence", d.verify.confidence},
              {"max_iterations", d.verify.max_iterations},
              {"min_inliers", d.verify.min_inliers},
              {"min_inlier_ratio", d.verify.min_inlier_ratio},
              {"use_fundamental", d.verify.use_fundamental},
              {"use_depths", d.verify.use_depths}}},
            {"local_map",
             {{"enabled", d.local_map.enabled},
              {"window", d.local_map.window},
              {"neighbours", d.local_map.neighbours},
              {"max_reprojection_px", d.local_map.triangulation.max_reprojection_px},
              {"min_parallax_deg", d.local_map.triangulation.min_parallax_deg}}},
            {"check_every", d.check_every},
            {"min_matches", d.min_matches},
            {"small_k_fraction", d.small_k_fraction},
            {"small_k_floor", d.small_k_floor},
            {"max_verify", d.max_verify},
            {"min_inlier_fraction_of_k", d.min_inlier_fraction_of_k},
            {"min_path_ratio", d.min_path_ratio},
            {"check_consistency", d.check_consistency},
            {"planar_alternatives", d.planar_alternatives},
            {"planar_alternative_tolerance", d.planar_alternative_tolerance},
            {"consistency_base_deg", d.consistency_base_deg},
            {"consistency_per_keyframe_deg", d.consistency_per_keyframe_deg},
            {"two_view_consistency_per_keyframe_deg", d.two_view_consistency_per_keyframe_deg},
            {"consistency_max_deg", d.consistency_max_deg},
            {"temporal_check", d.temporal_check},
            {"temporal_window", d.temporal_window},
            {"retrieval", ToString(d.retrieval)},
            {"ann",
             {{"hnsw_m", d.ann.hnsw_m},
              {"ef_construction", d.ann.ef_construction},
              {"ef_search", d.ann.ef_search},
              {"neighbors", d.ann.neighbors},
              {"max_distance", d.ann.max_distance},
              {"max_candidates", d.ann.max_candidates},
              {"num_threads", d.ann.num_threads}}},
            {"seed", d.seed}}},
          {"optimizer",
           {{"max_iterations", options.optimizer.max_iterations},
            {"function_tolerance", options.optimizer.function_tolerance},
            {"loop_loss", LossName(options.optimizer.loop_loss)},
            {"edge_loss", LossName(options.optimizer.edge_loss)},
            {"loss_scale", options.optimizer.loss_scale},
            {"rejection", RejectionName(options.optimizer.rejection)},
            {"pcm_confidence", options.optimizer.pcm.confidence},
            {"num_threads", options.optimizer.num_threads},
            {"reduce_chains", options.optimizer.reduce_chains},
            {"max_chain_length", options.optimizer.max_chain_length}}},
          {"odometry",
           {{"translation_fraction", options.odometry.translation_fraction},
            {"min_translation_sigma", options.odometry.min_translation_sigma},
            {"rotation_sigma_rad", options.odometry.rotation_sigma_rad},
            {"scale_sigma", options.odometry.scale_sigma}}},
          {"vertex_type", VertexName(options.vertex_type)},
          {"loop_translation_sigma_steps", options.loop_translation_sigma_steps},
          {"loop_rotation_sigma_rad", options.loop_rotation_sigma_rad},
          {"loop_scale_sigma", options.loop_scale_sigma},
          {"loop_information_from_estimate", options.loop_information_from_estimate},
          {"loop_covariance_inflation", options.loop_covariance_inflation},
          {"loop_min_translation_sigma_steps", options.loop_min_translation_sigma_steps},
          {"loop_min_rotation_sigma_rad", options.loop_min_rotation_sigma_rad},
          {"loop_min_scale_sigma", options.loop_min_scale_sigma},
          {"use_mapped_pixels", options.use_mapped_pixels},
          {"raw_association_max_dt", options.raw_association_max_dt},
          {"skip_unreadable_frames", options.skip_unreadable_frames}};
}

}  // namespace sparseloop
