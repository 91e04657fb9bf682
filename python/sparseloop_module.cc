// The Python module `sparseloop` (pybind11): the online LoopClosing with numpy images and poses,
// the trajectory readers / writers and the evaluation metrics. A thin binding: options come from
// the configuration registry (pipeline/config.h, the same keys as `--config`), results are numpy
// arrays and dicts, sparseloop's exceptions become sparseloop.Error (FileError: FileError, a
// subclass) or ValueError (std::invalid_argument) with the same message. The GIL is released while
// the library works (AddKeyframe, Finish, WaitForIdle, reading and evaluating) and re-acquired for
// the correction callback, which runs on the background thread.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <opencv2/imgcodecs.hpp>

#include "sparseloop/core/error.h"
#include "sparseloop/core/limits.h"
#include "sparseloop/eval/json.h"
#include "sparseloop/eval/metrics.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/pipeline/config.h"
#include "sparseloop/pipeline/dataset_source.h"
#include "sparseloop/pipeline/pipeline.h"
#include "sparseloop/runtime/loop_closing.h"

namespace py = pybind11;

namespace sparseloop {
namespace {

// A JSON value as a Python object through the json module (one conversion, exact for numbers).
py::object ToPython(const nlohmann::json& j) {
  return py::module_::import("json").attr("loads")(j.dump());
}
// "(3, 3)": the shape of an array, for messages.
std::string ShapeOf(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

// An argument as a float64 array; ValueError naming it when it is not numbers (None, a string).
py::array_t<double, py::array::c_style | py::array::forcecast> ArrayArgument(
    const py::object& o, const std::string& name) {
  try {
    if (o.is_none()) throw py::cast_error("None");
    return o.cast<py::array_t<double, py::array::c_style | py::array::forcecast>>();
  } catch (const py::cast_error&) {
  } catch (const py::error_already_set&) {  // numpy's own error, e.g. a string in the list
  }
  throw std::invalid_argument(fmt::format("{}: expected numbers (a list or numpy array), got {}",
                                          name, py::repr(o).cast<std::string>()));
}

// A value of a config dict as JSON. `path` is its key path ("detector.min_path_ratio"), which a
// ValueError names for what JSON cannot hold (NaN, an object); numpy scalars (np.float64,
// np.int64, np.bool_) and arrays are the Python values they hold (`tolist()`), as a float or
// int literal would be.
nlohmann::json JsonFromPython(const py::handle& o, const std::string& path,
                              const std::string& argument) {
  const auto refused = [&](const std::string& expected) {
    return std::invalid_argument(
        path.empty() ? fmt::format("{}: expected a dict of config keys, got {}", argument,
                                   py::repr(o).cast<std::string>())
                     : fmt::format("{}: expected {} for \"{}\", got {}", argument, expected, path,
                                   py::repr(o).cast<std::string>()));
  };
  if (o.is_none()) return nullptr;
  if (py::isinstance<py::bool_>(o)) return o.cast<bool>();
  if (py::isinstance<py::int_>(o)) {
    try {
      return o.cast<int64_t>();
    } catch (const py::cast_error&) {
    }
    try {
      return o.cast<uint64_t>();  // a seed above 2^63
    } catch (const py::cast_error&) {
      throw refused("an integer within 64 bits");
    }
  }
  if (py::isinstance<py::float_>(o)) {
    const double v = o.cast<double>();
    if (!std::isfinite(v)) {
      throw std::invalid_argument(fmt::format(
          "{}: expected a finite number for \"{}\", got NaN or infinity", argument, path));
    }
    return v;
  }
  if (py::isinstance<py::str>(o)) return o.cast<std::string>();
  if (py::isinstance<py::dict>(o)) {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& [key, value] : o.cast<py::dict>()) {
      if (!py::isinstance<py::str>(key)) throw refused("string keys");
      const std::string name = key.cast<std::string>();
      j[name] = JsonFromPython(value, path.empty() ? name : path + "." + name, argument);
    }
    return j;
  }
  if (py::isinstance<py::list>(o) || py::isinstance<py::tuple>(o)) {
    nlohmann::json j = nlohmann::json::array();
    const py::sequence items = o.cast<py::sequence>();
    for (size_t i = 0; i < items.size(); ++i) {
      const py::object item = items[i];
      j.push_back(JsonFromPython(item, fmt::format("{}[{}]", path, i), argument));
    }
    return j;
  }
  if (py::isinstance(o, py::module_::import("numpy").attr("generic")) ||
      py::isinstance<py::array>(o)) {
    return JsonFromPython(o.attr("tolist")(), path, argument);
  }
  throw refused("a number, string, boolean, list or dict");
}

// 4x4 row-major matrix [sR t; 0 1] (scale = cube root of det(sR)) -> Sim3d. `name` is the
// argument ("pose", "poses[3]") every error names. The rotation block is accepted as the CLI's
// trajectory reader accepts one (max |R^T R - I| <= kRotationTolerance, rounded files and float32
// poses) and replaced by its nearest rotation.
Sim3d PoseFromMatrix(const py::array_t<double, py::array::c_style | py::array::forcecast>& m,
                     const std::string& name) {
  if (m.ndim() != 2 || m.shape(0) < 3 || m.shape(0) > 4 || m.shape(1) != 4)
    throw std::invalid_argument(name + ": a pose must be a 4x4 or 3x4 matrix, got " +
                                std::to_string(m.ndim()) + " dimensions of sizes " +
                                std::to_string(m.ndim() > 0 ? m.shape(0) : 0) + ", " +
                                std::to_string(m.ndim() > 1 ? m.shape(1) : 0));
  for (py::ssize_t r = 0; r < m.shape(0); ++r)
    for (py::ssize_t c = 0; c < 4; ++c)
      if (!std::isfinite(m.at(r, c)))
        throw std::invalid_argument(fmt::format("{}: entry ({}, {}) is not finite", name, r, c));
  if (m.shape(0) == 4 &&
      !(m.at(3, 0) == 0.0 && m.at(3, 1) == 0.0 && m.at(3, 2) == 0.0 && m.at(3, 3) == 1.0)) {
    throw std::invalid_argument(fmt::format(
        "{}: expected a 4x4 pose with last row [0, 0, 0, 1] (world_from_cam = [sR t; 0 1]), got "
        "[{}, {}, {}, {}] (a transposed matrix? pass pose.T)",
        name, m.at(3, 0), m.at(3, 1), m.at(3, 2), m.at(3, 3)));
  }
  Eigen::Matrix3d sr;
  Eigen::Vector3d t;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) sr(r, c) = m.at(r, c);
    t(r) = m.at(r, 3);
  }
  if (t.cwiseAbs().maxCoeff() > kMaxCoordinate)
    throw std::invalid_argument(fmt::format("{}: translation beyond +-{:g}, got ({}, {}, {})", name,
                                            kMaxCoordinate, t.x(), t.y(), t.z()));
  const double det = sr.determinant();
  if (!(det > 0.0) || !std::isfinite(det))
    throw std::invalid_argument(name +
                                ": a pose's rotation block must have a positive determinant");
  const double scale = std::cbrt(det);
  const Eigen::Matrix3d r = sr / scale;
  const double deviation = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (deviation > kRotationTolerance)
    throw std::invalid_argument(fmt::format(
        "{}: a pose's rotation block is not a scaled rotation (max |R^T R - I| = {:.3g} > {})",
        name, deviation, kRotationTolerance));
  Matrix3x4d rt;
  rt << r, t;
  const Rigid3d nearest = Rigid3d::FromMatrix3x4(rt, kRotationTolerance);
  return Sim3d(scale, nearest.rotation, t);
}

// True when `o` is a tuple or list (R, t[, scale]): two or three items, the first a 2-D block. A
// nested list of rows ([[1, 0, 0, 0], ...], 3 or 4 rows) is a matrix instead.
bool IsRotationTranslationTuple(const py::object& o, const std::string& name) {
  if (!py::isinstance<py::tuple>(o) && !py::isinstance<py::list>(o)) return false;
  const py::sequence s = o.cast<py::sequence>();
  if (s.size() != 2 && s.size() != 3) return false;
  return ArrayArgument(s[0], name + "[0]").ndim() == 2;
}

// A pose argument: a 4x4 / 3x4 array or nested list, or a tuple (R 3x3, t 3[, scale]).
std::optional<Sim3d> PoseFromPython(const py::object& o, const std::string& name) {
  if (o.is_none()) return std::nullopt;
  if (IsRotationTranslationTuple(o, name)) {
    const py::sequence s = o.cast<py::sequence>();
    const auto r = s[0].cast<py::array_t<double, py::array::c_style | py::array::forcecast>>();
    const auto t = s[1].cast<py::array_t<double, py::array::c_style | py::array::forcecast>>();
    if (r.ndim() != 2 || r.shape(0) != 3 || r.shape(1) != 3 || t.size() != 3)
      throw std::invalid_argument(name +
                                  ": a pose tuple needs R of shape (3, 3) and t of 3 values");
    py::array_t<double> m({4, 4});
    auto w = m.mutable_unchecked<2>();
    const double scale = s.size() == 3 ? s[2].cast<double>() : 1.0;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) w(i, j) = scale * r.at(i, j);
      w(i, 3) = t.data()[i];
      w(3, i) = 0.0;
    }
    w(3, 3) = 1.0;
    return PoseFromMatrix(m, name);
  }
  return PoseFromMatrix(ArrayArgument(o, name), name);
}

py::array_t<double> ToNumpy(const Eigen::Matrix4d& m) {
  py::array_t<double> a({4, 4});
  auto w = a.mutable_unchecked<2>();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) w(r, c) = m(r, c);
  return a;
}

py::array_t<double> PosesToNumpy(const std::vector<Eigen::Matrix4d>& poses) {
  py::array_t<double> a({static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
  auto w = a.mutable_unchecked<3>();
  for (size_t i = 0; i < poses.size(); ++i)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) w(i, r, c) = poses[i](r, c);
  return a;
}

// A uint8 numpy image (H x W, or H x W x 1) -> a CV_8UC1 cv::Mat holding its own copy.
cv::Mat ImageFromNumpy(const py::array& image) {
  if (!py::isinstance<py::array_t<uint8_t>>(image))
    throw std::invalid_argument("the image must be a uint8 array, got dtype " +
                                std::string(py::str(image.dtype())));
  const auto a = py::array_t<uint8_t, py::array::c_style | py::array::forcecast>::ensure(image);
  if (!(a.ndim() == 2 || (a.ndim() == 3 && a.shape(2) == 1)))
    throw std::invalid_argument("the image must be grayscale, shape (H, W), got " +
                                std::to_string(a.ndim()) + " dimensions");
  cv::Mat view(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC1,
               const_cast<uint8_t*>(a.data()));
  return view.clone();
}

py::dict ResultToDict(const LoopResult& r) {
  py::dict d;
  d["status"] = ToString(r.status);
  d["detected"] = r.detected();
  d["query_id"] = r.query_id;
  d["match_id"] = r.match_id;
  d["candidates"] = r.candidates;
  d["matches"] = r.matches;
  d["inliers"] = r.inliers;
  d["score"] = r.score;
  d["match_session"] = r.match_session;
  d["source"] = ToString(r.source);
  d["relocalization"] = r.relocalization;
  d["pose_segment"] = r.pose_segment;
  d["pose_reset"] = ToString(r.pose_reset);
  d["match_from_query"] = ToNumpy(r.match_from_query.ToMatrix4());
  d["scale"] = r.match_from_query.scale;
  return d;
}

py::dict TrajectoryToDict(const Trajectory& t) {
  py::array_t<double> stamps(static_cast<py::ssize_t>(t.size()));
  py::array_t<int64_t> frames(static_cast<py::ssize_t>(t.size()));
  std::vector<Eigen::Matrix4d> poses;
  for (size_t i = 0; i < t.size(); ++i) {
    stamps.mutable_at(i) = t.poses[i].timestamp;
    frames.mutable_at(i) = t.poses[i].frame;
    poses.push_back(t.poses[i].world_from_cam.ToMatrix4());
  }
  py::dict d;
  d["timestamps"] = stamps;
  d["frames"] = frames;
  d["poses"] = PosesToNumpy(poses);
  d["has_rotation"] = t.has_rotation;
  d["has_timestamps"] = t.has_timestamps;
  return d;
}

// (N, 4, 4) poses [+ N timestamps] -> Trajectory (SE(3): a scaled rotation is an error).
Trajectory TrajectoryFromNumpy(
    const py::array_t<double, py::array::c_style | py::array::forcecast>& poses,
    const py::object& timestamps) {
  if (poses.ndim() != 3 || poses.shape(1) != 4 || poses.shape(2) != 4)
    throw std::invalid_argument("poses must have shape (N, 4, 4)");
  const size_t n = static_cast<size_t>(poses.shape(0));
  std::vector<double> stamps;
  if (!timestamps.is_none()) {
    stamps = timestamps.cast<std::vector<double>>();
    if (stamps.size() != n)
      throw std::invalid_argument("timestamps must have one value per pose (" + std::to_string(n) +
                                  "), got " + std::to_string(stamps.size()));
  }
  Trajectory t;
  t.has_timestamps = !stamps.empty();
  for (size_t i = 0; i < n; ++i) {
    py::array_t<double> m({4, 4});
    std::copy(poses.data() + 16 * i, poses.data() + 16 * (i + 1), m.mutable_data());
    const Sim3d pose = PoseFromMatrix(m, fmt::format("poses[{}]", i));
    if (std::abs(pose.scale - 1.0) > 1e-6)
      throw std::invalid_argument("pose " + std::to_string(i) + " is not rigid (scale " +
                                  std::to_string(pose.scale) + ")");
    StampedPose p;
    p.frame = static_cast<int64_t>(i);
    p.timestamp = stamps.empty() ? static_cast<double>(i) : stamps[i];
    p.world_from_cam = pose.ToRigid();
    t.poses.push_back(p);
  }
  return t;
}

// The `preset` argument applied on `options`; an unknown name is a ValueError naming the argument.
void ApplyPresetArgument(const std::string& name, PipelineOptions* options) {
  try {
    ApplyPreset(name, options);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("preset: ") + e.what());
  }
}

// PipelineOptions from a config dict (the `--config` keys, strict), then the LoopClosing options
// that compute what `run` computes (the mapping of tests/runtime/loop_closing_test.cc).
LoopClosing::Options ClosingOptions(const py::object& config, const py::object& preset,
                                    bool solve_while_running, bool optimize) {
  PipelineOptions p;
  if (!preset.is_none()) {
    if (!py::isinstance<py::str>(preset)) {
      throw std::invalid_argument(fmt::format("preset: expected a preset name ({}) or None, got {}",
                                              fmt::join(PresetNames(), " | "),
                                              py::repr(preset).cast<std::string>()));
    }
    ApplyPresetArgument(preset.cast<std::string>(), &p);
  }
  if (!config.is_none()) {
    if (py::isinstance<py::str>(config) || py::hasattr(config, "__fspath__"))
      LoadConfigFile(config.cast<std::filesystem::path>(), &p);
    else
      ApplyConfig(JsonFromPython(config, "", "config"), "config", &p);
  }
  LoopClosing::Options o = LoopClosingOptionsFor(p, solve_while_running);
  o.optimize = optimize;
  o.Check();
  return o;
}

py::dict CorrectionsToDict(const CorrectedKeyframes& c) {
  std::vector<Eigen::Matrix4d> poses;
  for (const Sim3d& p : c.world_from_keyframe) poses.push_back(p.ToMatrix4());
  py::dict d;
  d["revision"] = c.revision;
  d["ids"] = py::array_t<int64_t>(static_cast<py::ssize_t>(c.ids.size()), c.ids.data());
  d["poses"] = PosesToNumpy(poses);
  d["num_solved"] = c.num_solved;
  return d;
}

// LoopClosing plus the loops it sent to the graph (for loops() / accepted_loops()).
class PyLoopClosing {
 public:
  PyLoopClosing(const py::object& config, const py::object& preset, bool solve_while_running,
                bool optimize, py::object on_correction) {
    LoopClosing::CorrectionCallback cb;
    if (!on_correction.is_none() && !PyCallable_Check(on_correction.ptr())) {
      throw std::invalid_argument(fmt::format("on_correction: expected a callable or None, got {}",
                                              py::repr(on_correction).cast<std::string>()));
    }
    if (!on_correction.is_none()) {
      callback_ = std::make_shared<py::object>(std::move(on_correction));
      std::shared_ptr<py::object> f = callback_;
      cb = [f](const PoseCorrection& c) {
        py::gil_scoped_acquire gil;  // background thread
        try {
          py::dict d;
          d["revision"] = c.revision;
          d["num_loops"] = c.num_loops;
          d["ids"] = py::array_t<int64_t>(static_cast<py::ssize_t>(c.ids.size()), c.ids.data());
          (*f)(d);
        } catch (py::error_already_set& e) {
          e.discard_as_unraisable("sparseloop correction callback");
        }
      };
    }
    closing_ = std::make_unique<LoopClosing>(
        ClosingOptions(config, preset, solve_while_running, optimize), std::move(cb));
  }
  ~PyLoopClosing() {
    py::gil_scoped_release release;  // the destructor joins the thread, whose callback needs it
    closing_.reset();
  }

  py::dict AddKeyframe(int64_t id, double timestamp, const py::array& image,
                       const py::object& intrinsics, const py::object& pose,
                       const py::object& mapped_pixels, const py::object& mapped_depths,
                       const py::object& odometry_covariance, bool pose_reset) {
    KeyframeInput in;
    in.id = id;
    in.timestamp = timestamp;
    in.image = ImageFromNumpy(image);
    const auto k = ArrayArgument(intrinsics, "intrinsics");
    if (k.ndim() != 1 || k.size() != 4) {
      throw std::invalid_argument(fmt::format(
          "intrinsics: expected (fx, fy, cx, cy), got an array of shape {}{}", ShapeOf(k),
          k.ndim() == 2 && k.shape(0) == 3 && k.shape(1) == 3
              ? " (from a 3x3 K pass (K[0, 0], K[1, 1], K[0, 2], K[1, 2]))"
              : ""));
    }
    in.intrinsics.fx = k.at(0);
    in.intrinsics.fy = k.at(1);
    in.intrinsics.cx = k.at(2);
    in.intrinsics.cy = k.at(3);
    in.intrinsics.width = in.image.cols;
    in.intrinsics.height = in.image.rows;
    in.world_from_cam = PoseFromPython(pose, "pose");
    in.pose_reset = pose_reset;
    if (!mapped_pixels.is_none()) {
      const auto px = ArrayArgument(mapped_pixels, "mapped_pixels");
      if (px.ndim() != 2 || px.shape(1) != 2) {
        throw std::invalid_argument(fmt::format(
            "mapped_pixels: expected shape (N, 2) (u, v per row), got shape {}", ShapeOf(px)));
      }
      // Non-finite values are refused by LoopDetector's check, naming the row.
      for (py::ssize_t i = 0; i < px.shape(0); ++i) {
        in.mapped_pixels.emplace_back(static_cast<float>(px.at(i, 0)),
                                      static_cast<float>(px.at(i, 1)));
      }
    }
    if (!mapped_depths.is_none()) {
      const auto d = ArrayArgument(mapped_depths, "mapped_depths");
      if (d.ndim() != 1)
        throw std::invalid_argument(fmt::format(
            "mapped_depths: expected one depth per mapped pixel, shape (N,), got shape {}",
            ShapeOf(d)));
      for (py::ssize_t i = 0; i < d.size(); ++i) {
        if (!(d.at(i) > 0.0 && std::isfinite(d.at(i)))) {
          throw std::invalid_argument(fmt::format(
              "mapped_depths[{}]: expected a positive, finite depth (the pose's units), got {} "
              "(leave the argument out when depths are unknown)",
              i, d.at(i)));
        }
        in.mapped_depths.push_back(static_cast<float>(d.at(i)));
      }
    }
    if (!odometry_covariance.is_none()) {
      const auto c = odometry_covariance
                         .cast<py::array_t<double, py::array::c_style | py::array::forcecast>>();
      if (c.ndim() != 2 || c.shape(0) != 6 || c.shape(1) != 6)
        throw std::invalid_argument("odometry_covariance must have shape (6, 6)");
      Eigen::Matrix<double, 6, 6> m;
      for (int r = 0; r < 6; ++r)
        for (int col = 0; col < 6; ++col) m(r, col) = c.at(r, col);
      in.odometry_covariance = m;
    }
    LoopEvent e;
    {
      py::gil_scoped_release release;
      e = closing_->AddKeyframe(in);
    }
    if (e.loop_in_graph) loops_.push_back(e.result);
    py::dict d = ResultToDict(e.result);
    d["in_graph"] = e.in_graph;
    d["loop_in_graph"] = e.loop_in_graph;
    d["loop_index"] = e.loop_index;
    return d;
  }

  void Finish() {
    py::gil_scoped_release release;
    closing_->Finish();
  }
  void WaitForIdle() {
    py::gil_scoped_release release;
    closing_->WaitForIdle();
  }
  py::dict Corrections() const { return CorrectionsToDict(closing_->Corrections()); }
  py::object CorrectedPose(int64_t id) const {
    const auto p = closing_->CorrectedPose(id);
    if (!p) return py::none();
    return ToNumpy(p->world_from_keyframe.ToMatrix4());
  }
  // Loops sent to the graph: rows (query_id, match_id, inliers, accepted); accepted = 0 for the
  // loops the latest solve rejected (PCM), 1 otherwise.
  py::array_t<int64_t> Loops() const {
    std::vector<bool> rejected(loops_.size(), false);
    if (const auto latest = closing_->LatestSolve())
      for (size_t i : latest->summary.rejected_loops)
        if (i < rejected.size()) rejected[i] = true;
    py::array_t<int64_t> a({static_cast<py::ssize_t>(loops_.size()), py::ssize_t{4}});
    auto w = a.mutable_unchecked<2>();
    for (size_t i = 0; i < loops_.size(); ++i) {
      w(i, 0) = loops_[i].query_id;
      w(i, 1) = loops_[i].match_id;
      w(i, 2) = loops_[i].inliers;
      w(i, 3) = rejected[i] ? 0 : 1;
    }
    return a;
  }
  const LoopClosing& closing() const { return *closing_; }

 private:
  std::shared_ptr<py::object> callback_;
  std::unique_ptr<LoopClosing> closing_;
  std::vector<LoopResult> loops_;
};

}  // namespace
}  // namespace sparseloop

PYBIND11_MODULE(_sparseloop, m) {
  using namespace sparseloop;
  m.doc() = "sparseloop: loop closure for monocular visual SLAM (see README, 'Python')";

  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  static py::exception<FileError> file_error(m, "FileError", error.ptr());
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const FileError& e) {
      PyErr_SetString(file_error.ptr(), e.what());
    } catch (const Error& e) {
      PyErr_SetString(error.ptr(), e.what());
    } catch (const ConfigValueError& e) {
      PyErr_SetString(PyExc_ValueError, ("expected " + e.expected + ", got " + e.got).c_str());
    }
  });  // std::invalid_argument -> ValueError: pybind11's own translation, message unchanged

  py::class_<PyLoopClosing>(m, "LoopClosing", R"doc(
The online loop closer (C++ runtime::LoopClosing).

config: None, a dict of `--config` keys ({"detector": {"features": {"max_features": 15}}}) or
the path of a JSON config file. preset: a shipped preset applied before config ("sparse",
"dense"; sparseloop.presets()). solve_while_running=False solves once, in finish(), as
`sparseloop run` does. on_correction(dict) runs on the background thread after each solve.)doc")
      .def(py::init<const py::object&, const py::object&, bool, bool, py::object>(),
           py::arg("config") = py::none(), py::arg("preset") = py::none(),
           py::arg("solve_while_running") = true, py::arg("optimize") = true,
           py::arg("on_correction") = py::none())
      .def("add_keyframe", &PyLoopClosing::AddKeyframe, py::arg("id"), py::arg("timestamp"),
           py::arg("image"), py::arg("intrinsics"), py::arg("pose") = py::none(),
           py::arg("mapped_pixels") = py::none(), py::arg("mapped_depths") = py::none(),
           py::arg("odometry_covariance") = py::none(), py::arg("pose_reset") = false,
           "Detects a loop for the keyframe (uint8 (H, W) image; intrinsics (fx, fy, cx, cy); "
           "pose: 4x4 or 3x4 world_from_cam, array or nested list, or (R, t[, scale]); None = "
           "tracking lost) and queues it for "
           "the background solve. odometry_covariance: (6, 6) covariance of the raw step from the "
           "previous keyframe with a pose, order [translation, rotation] (None: the default "
           "model). pose_reset=True: the vSLAM re-initialised, this pose is in a new world frame "
           "(the result's pose_segment / pose_reset say what the detector made of it). Returns "
           "the loop event as a dict.")
      .def("finish", &PyLoopClosing::Finish, "Final solve; joins the background thread.")
      .def("wait_for_idle", &PyLoopClosing::WaitForIdle)
      .def("corrections", &PyLoopClosing::Corrections,
           "{'revision', 'ids' (N,), 'poses' (N, 4, 4) corrected world_from_keyframe, "
           "'num_solved'}")
      .def("corrected_pose", &PyLoopClosing::CorrectedPose, py::arg("id"))
      .def("loops", &PyLoopClosing::Loops,
           "Loops sent to the graph, int64 (M, 4): query_id, match_id, inliers, accepted")
      .def_property_readonly("num_keyframes",
                             [](const PyLoopClosing& c) { return c.closing().num_keyframes(); })
      .def_property_readonly("num_loops",
                             [](const PyLoopClosing& c) { return c.closing().num_loops(); })
      .def_property_readonly("num_solves",
                             [](const PyLoopClosing& c) { return c.closing().num_solves(); })
      .def_property_readonly(
          "num_interrupted_solves",
          [](const PyLoopClosing& c) { return c.closing().num_interrupted_solves(); },
          "solves a newer loop interrupted (no callback; num_solves counts them)")
      .def_property_readonly("finished",
                             [](const PyLoopClosing& c) { return c.closing().finished(); });

  m.def(
      "default_config",
      [](const std::string& scope, const std::string& preset) {
        // The CLI's names: "run" (every key, also "") and "detect" (the detector object).
        if (scope != "" && scope != "run" && scope != "detect") {
          throw std::invalid_argument(
              fmt::format("scope: expected 'run' (every key) or 'detect', got '{}'", scope));
        }
        PipelineOptions options;
        if (!preset.empty()) ApplyPresetArgument(preset, &options);
        return ToPython(DumpConfig(options, scope == "detect" ? "detector" : ""));
      },
      py::arg("scope") = "run", py::arg("preset") = "",
      "Every config key with its default (or the preset's value), plus 'doc' (as `sparseloop "
      "config --dump [run|detect] [--preset NAME]`).");
  m.def("presets", &PresetNames, "The names of the shipped presets (LoopClosing(preset=...)).");

  m.def(
      "read_trajectory",
      [](const std::filesystem::path& path, const std::string& format) {
        Trajectory t;
        {
          py::gil_scoped_release release;
          t = ReadTrajectory(path, ParseTrajectoryFormat(format));
        }
        return TrajectoryToDict(t);
      },
      py::arg("path"), py::arg("format") = "auto",
      "TUM / KITTI / EuRoC / positions file -> {'timestamps', 'frames', 'poses' (N, 4, 4), "
      "'has_rotation', 'has_timestamps'}");
  m.def(
      "write_trajectory",
      [](const std::filesystem::path& path,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& poses,
         const py::object& timestamps, const std::string& format) {
        const Trajectory t = TrajectoryFromNumpy(poses, timestamps);
        py::gil_scoped_release release;
        WriteTrajectory(path, t, ParseTrajectoryFormat(format));
      },
      py::arg("path"), py::arg("poses"), py::arg("timestamps") = py::none(),
      py::arg("format") = "tum");
  m.def(
      "evaluate_trajectory",
      [](const std::filesystem::path& gt_path, const std::filesystem::path& est_path,
         const std::string& alignment) {
        nlohmann::json j;
        {
          py::gil_scoped_release release;
          EvaluationOptions options;
          options.alignment = ParseAlignment(alignment);
          const Trajectory gt = ReadTrajectory(gt_path), est = ReadTrajectory(est_path);
          j = ToJson(EvaluateTrajectory(gt, est, options), gt, est);
        }
        return ToPython(j);
      },
      py::arg("gt"), py::arg("est"), py::arg("alignment") = "sim3",
      "ATE / RPE / KITTI metrics of two trajectory files, the dict `sparseloop eval --json` "
      "writes for a trajectory.");
  m.def(
      "read_image",
      [](const std::filesystem::path& path) {
        // Read as `run` reads a frame: a file that cannot be opened is not handed to OpenCV (its
        // warning line), and the error says why.
        DatasetFrame frame;
        frame.image_path = path;
        const cv::Mat img = ReadFrameGray(Dataset{}, frame);
        if (img.empty()) throw FileError(path.string(), 0, "an image file", ImageReadProblem(path));
        py::array_t<uint8_t> a({img.rows, img.cols});
        for (int r = 0; r < img.rows; ++r)
          std::copy(img.ptr<uint8_t>(r), img.ptr<uint8_t>(r) + img.cols, a.mutable_data(r, 0));
        return a;
      },
      py::arg("path"), "An image file as a uint8 (H, W) grayscale array.");
  m.def(
      "read_mapped_pixels",
      [](const std::filesystem::path& path) {
        const MappedPixels mp = ReadMappedPixels(path);
        py::array_t<float> px({static_cast<py::ssize_t>(mp.pixels.size()), py::ssize_t{2}});
        for (size_t i = 0; i < mp.pixels.size(); ++i) {
          px.mutable_at(i, 0) = mp.pixels[i].x;
          px.mutable_at(i, 1) = mp.pixels[i].y;
        }
        py::array_t<float> depths(static_cast<py::ssize_t>(mp.depths.size()), mp.depths.data());
        return py::make_tuple(px, depths);
      },
      py::arg("path"),
      "A mapped/NNNNNN.txt file ('u v depth' per line) -> (pixels (N, 2), depths)");
}
