// sparseloop render: synthetic sequence (images + GT + drifting raw trajectory) in KITTI layout.
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "cli/run_output.h"
#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/pipeline/kitti_sequence.h"
#include "sparseloop/synthetic/texture.h"
#include "sparseloop/synthetic/vslam_sim.h"
#include "sparseloop/synthetic/worlds.h"

namespace sparseloop::cli {

namespace {

std::vector<std::string> SplitComma(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

namespace syn = sparseloop::synthetic;

struct RenderFlags {
  std::string world_name, trajectory_path, plan_name = "circuit", textures_dir, texture_filter;
  std::string raw_path, out_dir, raw_format = "auto";
  int frames = 0, threads = 2, kitti_sequence = -1, start = 0, step = 1;
  uint64_t seed = 1;
  syn::FlightPlanOptions plan;
  SequenceOptions seq;
  bool no_photometric = false, no_mapped = false, poses_only = false;
  double drift_scale = 1.0, photometric_scale = 1.0;
  // PITCH,YAW,ROLL in degrees (camera x, y, z); empty: the DriftOptions default.
  std::string rotation_bias, rotation_bias_per_frame;
};

// "PITCH,YAW,ROLL": three finite numbers, degrees about camera x, y, z. Anything else is an
// std::invalid_argument (exit 2) naming `flag`.
Eigen::Vector3d ParseAxesFlag(const std::string& flag, const std::string& text) {
  const std::vector<std::string> items = SplitComma(text);
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  bool ok = items.size() == 3 && std::count(text.begin(), text.end(), ',') == 2;
  for (size_t i = 0; ok && i < 3; ++i) {
    const char* end = items[i].data() + items[i].size();
    const auto [ptr, ec] = std::from_chars(items[i].data(), end, v[i]);
    ok = ec == std::errc() && ptr == end && std::isfinite(v[i]);
  }
  SL_CHECK_MSG(ok,
               "{} expects PITCH,YAW,ROLL (3 finite numbers, degrees about camera x, y, z), "
               "got '{}'",
               flag, text);
  return v;
}

void AddRenderFlags(CLI::App& app, RenderFlags* f) {
  app.add_option("--world", f->world_name, "aerial or street")
      ->required()
      ->check(CLI::IsMember({"aerial", "street"}));
  app.add_option("--trajectory", f->trajectory_path,
                 "GT trajectory file (street: required; aerial: replaces --plan)");
  app.add_option("--plan", f->plan_name, "aerial flight plan: circuit, figure8, lawnmower")
      ->capture_default_str();
  app.add_option("--textures", f->textures_dir, "texture folder (default: procedural textures)");
  app.add_option("--texture-filter", f->texture_filter,
                 "comma-separated substrings; only matching texture file names are used");
  app.add_option("--frames", f->frames, "frames to render (0: all poses / the plan's default)")
      ->check(IntegerAtLeast(0))
      ->capture_default_str();
  app.add_option("--start", f->start,
                 "first pose of --trajectory to render (the world is still "
                 "built from the whole trajectory)")
      ->check(IntegerAtLeast(0))
      ->capture_default_str();
  app.add_option("--step", f->step, "render every step-th pose")
      ->check(IntegerAtLeast(1))
      ->capture_default_str();
  app.add_option("--seed", f->seed, "seed of the world, noise and drift")
      ->check(IntegerAtLeast(0))  // -1 was read as 18446744073709551615
      ->capture_default_str();
  app.add_option("--threads", f->threads, "frames rendered in parallel")
      ->check(IntegerAtLeast(1))
      ->capture_default_str();
  app.add_option("--altitude", f->plan.altitude, "aerial: metres above ground")
      ->capture_default_str();
  app.add_option("--tilt", f->plan.tilt_deg, "aerial: camera tilt from nadir, degrees")
      ->capture_default_str();
  app.add_option("--size", f->plan.size, "aerial: side of the flown area, metres")
      ->capture_default_str();
  app.add_option("--laps", f->plan.laps, "aerial: laps of circuit/figure8")->capture_default_str();
  app.add_option("--kitti-sequence", f->kitti_sequence,
                 "street: KITTI sequence whose cam0 intrinsics to use (default: from the file "
                 "name, else 0)");
  app.add_option("--noise", f->seq.render.noise_sigma, "sensor noise std-dev, gray levels")
      ->capture_default_str();
  app.add_option("--blur", f->seq.render.blur_sigma, "Gaussian blur std-dev, pixels")
      ->capture_default_str();
  app.add_flag("--no-photometric", f->no_photometric, "constant exposure and gamma");
  app.add_option("--raw", f->raw_path,
                 "real estimate (associated by index) instead of simulated "
                 "drift");
  app.add_option("--raw-format", f->raw_format, "format of --raw")->capture_default_str();
  app.add_flag("--depth", f->seq.write_depth, "also write depth_0/NNNNNN.png (metres * 256)");
  app.add_flag("--no-mapped", f->no_mapped, "do not write mapped/NNNNNN.txt");
  app.add_option("--drift", f->drift_scale,
                 "multiplies every simulated drift rate per metre (rotation noise and "
                 "--rotation-bias, translation, scale; not --rotation-bias-per-frame); 0: none")
      ->capture_default_str();
  const syn::DriftOptions drift;
  app.add_option(
      "--rotation-bias", f->rotation_bias,
      fmt::format("PITCH,YAW,ROLL: rotation bias of the raw trajectory in degrees per "
                  "100 m about camera x (pitch), y (yaw, heading), z (roll; optical "
                  "axis), times --drift [default: {:g},{:g},{:g}]",
                  drift.rotation_bias_deg_per_100m.x(), drift.rotation_bias_deg_per_100m.y(),
                  drift.rotation_bias_deg_per_100m.z()));
  app.add_option("--rotation-bias-per-frame", f->rotation_bias_per_frame,
                 "PITCH,YAW,ROLL: extra rotation bias in degrees per frame (each raw step is "
                 "rotated by exactly this about camera x, y, z), not scaled by --drift "
                 "[default: 0,0,0]");
  app.add_option("--photometric", f->photometric_scale,
                 "multiplies the exposure/gamma change amplitudes")
      ->capture_default_str();
  app.add_flag(
      "--poses-only", f->poses_only,
      "write only poses_gt.txt and poses_raw.txt (no images; same drift as a full render)");
  app.add_option("--out", f->out_dir, "output folder")->required();
}

// The sequence and plan options from the flags (seeds, drift and photometric scales), checked;
// an invalid value names its flag.
void ApplyRenderFlags(RenderFlags* f) {
  SequenceOptions& seq = f->seq;
  seq.num_threads = f->threads;
  seq.photometric_drift = !f->no_photometric;
  seq.write_mapped = !f->no_mapped;
  seq.render.seed = syn::HashCombine(f->seed, 1);
  seq.drift.seed = syn::HashCombine(f->seed, 2);
  seq.photometric.seed = syn::HashCombine(f->seed, 3);
  // 50 x the default drift is a raw trajectory that no longer resembles the path; beyond it the
  // simulator's own bounds would fail with their field names.
  SL_CHECK_MSG(f->drift_scale >= 0.0 && f->drift_scale <= 50.0,
               "--drift must be in [0, 50], got {}", f->drift_scale);
  SL_CHECK_MSG(f->photometric_scale >= 0.0 && std::isfinite(f->photometric_scale),
               "--photometric must be >= 0, got {}", f->photometric_scale);
  SL_CHECK_MSG(
      f->raw_path.empty() || (f->rotation_bias.empty() && f->rotation_bias_per_frame.empty()),
      "--rotation-bias and --rotation-bias-per-frame simulate drift; they cannot be "
      "combined with --raw");
  if (!f->rotation_bias.empty())
    seq.drift.rotation_bias_deg_per_100m = ParseAxesFlag("--rotation-bias", f->rotation_bias);
  if (!f->rotation_bias_per_frame.empty()) {
    seq.drift.rotation_bias_deg_per_frame =
        ParseAxesFlag("--rotation-bias-per-frame", f->rotation_bias_per_frame);
  }
  seq.drift.rotation_noise_deg_per_sqrt_m *= f->drift_scale;
  seq.drift.rotation_bias_deg_per_100m *= f->drift_scale;
  seq.drift.translation_noise *= f->drift_scale;
  seq.drift.scale_noise_per_sqrt_m *= f->drift_scale;
  seq.drift.scale_bias_per_100m *= f->drift_scale;
  seq.photometric.gain_amplitude *= f->photometric_scale;
  seq.photometric.gamma_amplitude *= f->photometric_scale;
  if (f->frames > 0) f->plan.frames = f->frames;
  CheckNamingFlags({{"altitude", "--altitude"},
                    {"tilt_deg", "--tilt"},
                    {"size", "--size"},
                    {"laps", "--laps"},
                    {"frames", "--frames"},
                    {"noise_sigma", "--noise"},
                    {"blur_sigma", "--blur"},
                    {"gain_amplitude", "--photometric"},
                    {"gamma_amplitude", "--photometric"},
                    {"rotation_bias", "--rotation-bias"},
                    {"rotation_bias_per_frame", "--rotation-bias-per-frame"}},
                   [&] {
                     f->plan.Check();
                     seq.Check();
                   });
}

std::shared_ptr<const syn::TextureSet> MakeTextures(const RenderFlags& f) {
  if (f.textures_dir.empty()) {
    syn::ProceduralTextureOptions tex;
    tex.seed = syn::HashCombine(f.seed, 4);
    return syn::MakeProceduralTextures(tex);
  }
  syn::TextureFolderOptions tex;
  tex.name_filter = SplitComma(f.texture_filter);
  return syn::LoadTextureFolder(f.textures_dir, tex);
}

// The world, its camera and the whole GT trajectory (the street world is shaped by all of it).
struct Scene {
  Trajectory gt;
  syn::World world;
  CameraIntrinsics camera;
};

// The poses of a trajectory flag (--trajectory, --raw): every pose needs its rotation (the
// camera follows it, poses_raw.txt is KITTI). A FileError names the flag: "--trajectory F:2:
// expected a trajectory with orientations ..., got a positions-only line ...".
Trajectory ReadPosesFlag(const std::string& flag, const std::string& path,
                         TrajectoryFormat format) {
  TrajectoryReadOptions options;
  options.require_rotation = true;
  Trajectory poses;
  NameTheFlag(flag, [&] { poses = ReadTrajectory(path, format, options); });
  return poses;
}

Scene BuildScene(const RenderFlags& f, std::shared_ptr<const syn::TextureSet> textures) {
  Scene scene;
  if (f.world_name == "aerial") {
    if (!f.trajectory_path.empty()) {
      scene.gt = ReadPosesFlag("--trajectory", f.trajectory_path, TrajectoryFormat::kAuto);
    } else {
      syn::FlightPlanOptions plan = f.plan;
      plan.plan = syn::ParseFlightPlan(f.plan_name);
      scene.gt = syn::MakeFlightTrajectory(plan);
    }
    syn::AerialWorldOptions options;
    options.seed = syn::HashCombine(f.seed, 5);
    scene.world = syn::MakeAerialWorld(textures, options);
    scene.camera = syn::DefaultAerialCamera();
    return scene;
  }
  SL_CHECK_MSG(!f.trajectory_path.empty(), "--world street needs --trajectory FILE");
  scene.gt = ReadPosesFlag("--trajectory", f.trajectory_path, TrajectoryFormat::kAuto);
  SL_CHECK_MSG(scene.gt.size() >= 2,
               "--trajectory {}: expected at least 2 poses for --world street (its streets run "
               "along the path), got {}",
               f.trajectory_path, scene.gt.size());
  int kitti_sequence = f.kitti_sequence;
  if (kitti_sequence < 0) {
    const std::string stem = std::filesystem::path(f.trajectory_path).stem().string();
    kitti_sequence = (!stem.empty() && stem.size() <= 2 &&
                      stem.find_first_not_of("0123456789") == std::string::npos)
                         ? std::stoi(stem)
                         : 0;
  }
  scene.camera = syn::KittiCam0Intrinsics(kitti_sequence);
  syn::StreetWorldOptions options;
  options.seed = syn::HashCombine(f.seed, 6);
  scene.world = syn::MakeStreetWorld(scene.gt, textures, options);
  return scene;
}

// --start, --step and --frames applied to the GT trajectory.
Trajectory SliceTrajectory(const RenderFlags& f, const Trajectory& gt) {
  SL_CHECK_MSG(f.start >= 0 && static_cast<size_t>(f.start) < gt.size(),
               "--start {} outside the trajectory of {} poses", f.start, gt.size());
  SL_CHECK_MSG(f.step >= 1, "--step must be >= 1, got {}", f.step);
  Trajectory picked = gt;
  picked.poses.clear();
  for (size_t i = f.start; i < gt.size(); i += f.step) picked.poses.push_back(gt.poses[i]);
  if (f.frames > 0 && static_cast<size_t>(f.frames) < picked.size()) picked.poses.resize(f.frames);
  return picked;
}

// render.json: what was rendered, so a --start / --step slice is known from the folder itself
// (frame k of the folder is pose start + k * step of the trajectory).
// The biases are those simulated (--rotation-bias times --drift), null with --raw.
void WriteRenderJson(const RenderFlags& f, size_t frames) {
  const auto axes = [&](const Eigen::Vector3d& v) {
    return f.raw_path.empty() ? nlohmann::json{v.x(), v.y(), v.z()} : nlohmann::json(nullptr);
  };
  nlohmann::json j = {
      {"command", "render"},
      {"world", f.world_name},
      {"trajectory",
       f.trajectory_path.empty() ? nlohmann::json(nullptr) : nlohmann::json(f.trajectory_path)},
      {"plan", f.trajectory_path.empty() && f.world_name == "aerial" ? nlohmann::json(f.plan_name)
                                                                     : nlohmann::json(nullptr)},
      {"start", f.start},
      {"step", f.step},
      {"frames", frames},
      {"seed", f.seed},
      {"raw", f.raw_path.empty() ? nlohmann::json(nullptr) : nlohmann::json(f.raw_path)},
      {"drift", f.drift_scale},
      {"rotation_bias_deg_per_100m", axes(f.seq.drift.rotation_bias_deg_per_100m)},
      {"rotation_bias_deg_per_frame", axes(f.seq.drift.rotation_bias_deg_per_frame)},
      {"photometric", f.photometric_scale},
      {"poses_only", f.poses_only}};
  WriteFileAtomically(std::filesystem::path(f.out_dir) / "render.json",
                      [&](std::ostream& os) { os << JsonText(j); });
}

// The folders render writes frames into (kitti_sequence.h), beside its files.
const std::vector<std::string> kFrameFolders = {"image_0", "mapped", "depth_0"};

// --out: a new or empty folder, or an earlier render (it holds render.json and only what render
// writes: `files`, calib.txt and the frame folders), which is removed first. A shorter render into
// a longer one left the longer one's images beside the new poses, a folder `run` then refused; a
// copy of a real sequence had its poses and calib.txt replaced. Anything else is refused before
// any work.
void PrepareRenderFolder(const std::string& out, std::vector<std::string> own) {
  namespace fs = std::filesystem;
  const fs::path dir = ResolvedPath(out);
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;  // created later; CheckOutputDirFlag checked it
  own.push_back("calib.txt");
  own.insert(own.end(), kFrameFolders.begin(), kFrameFolders.end());
  std::vector<std::string> entries, foreign;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    entries.push_back(name);
    if (std::find(own.begin(), own.end(), name) == own.end()) foreign.push_back(name);
  }
  if (entries.empty()) return;
  if (!foreign.empty()) throw NotAnEarlierOutput(out, "render", OtherEntries(foreign));
  if (!fs::is_regular_file(dir / "render.json", ec))
    throw NotAnEarlierOutput(out, "render", "a folder without render.json");
  for (const std::string& name : entries) fs::remove_all(dir / name, ec);
  Logger().info("render: removed the earlier render in {} ({} entries)", dir.string(),
                entries.size());
}

}  // namespace

int RunRender(int argc, char** argv) {
  CLI::App app{"Render a synthetic sequence (KITTI folder layout) with exact ground truth"};
  RenderFlags f;
  AddRenderFlags(app, &f);
  Parse(app, argc, argv);
  const std::vector<std::string> files = {"poses_gt.txt", "poses_raw.txt", "raw_scale.txt",
                                          "poses.txt",    "times.txt",     "render.json"};
  // The frame folders too: `--textures DIR/image_0 --out DIR` would write frames over textures.
  std::vector<NamedPath> outputs = FilesIn("--out", f.out_dir, files);
  std::vector<std::string> folders = {""};  // --out itself
  folders.insert(folders.end(), kFrameFolders.begin(), kFrameFolders.end());
  for (const NamedPath& folder : FilesIn("--out", f.out_dir, folders)) outputs.push_back(folder);
  CheckOutputsAreNotInputs(
      outputs,
      {{"--trajectory", f.trajectory_path}, {"--raw", f.raw_path}, {"--textures", f.textures_dir}});
  CheckOutputDirFlag("--out", f.out_dir, files);
  f.out_dir = ResolvedPath(f.out_dir).string();  // DIR/missing/.. is DIR
  ApplyRenderFlags(&f);
  SL_CHECK_MSG(!f.poses_only || f.raw_path.empty(),
               "--poses-only simulates the drift; it cannot be combined with --raw");

  // Every input is read and checked before --out is touched: a render that fails here keeps an
  // earlier render in --out, and creates nothing.
  const Scene scene = BuildScene(f, MakeTextures(f));
  const Trajectory gt = SliceTrajectory(f, scene.gt);
  std::optional<Trajectory> raw;
  if (!f.raw_path.empty()) {
    raw = ReadPosesFlag("--raw", f.raw_path, ParseTrajectoryFormat(f.raw_format));
    SL_CHECK_MSG(raw->size() >= gt.size(),
                 "--raw {}: expected a pose for each of the {} frames to render (associated by "
                 "index), got {} poses",
                 f.raw_path, gt.size(), raw->size());
    raw->poses.resize(gt.size());
  }
  PrepareRenderFolder(f.out_dir, files);

  if (f.poses_only) {
    const syn::DriftResult drift = syn::SimulateDrift(gt, f.seq.drift);
    std::filesystem::create_directories(f.out_dir);
    WriteTrajectory(std::filesystem::path(f.out_dir) / "poses_gt.txt", gt,
                    TrajectoryFormat::kKitti);
    WriteTrajectory(std::filesystem::path(f.out_dir) / "poses_raw.txt", drift.raw,
                    TrajectoryFormat::kKitti);
    WriteRawScale(std::filesystem::path(f.out_dir) / "raw_scale.txt", drift.scale);
    WriteRenderJson(f, gt.size());
    std::cout << fmt::format(
        "wrote poses_gt.txt, poses_raw.txt and raw_scale.txt ({} poses) to {}\n", gt.size(),
        f.out_dir);
    return 0;
  }
  const bool tty = isatty(fileno(stderr));
  auto progress = [&](int64_t done, int64_t total) {
    if (tty && (done % 10 == 0 || done == total)) {
      std::fprintf(stderr, "\rrendered %lld/%lld frames", static_cast<long long>(done),
                   static_cast<long long>(total));
      if (done == total) std::fprintf(stderr, "\n");
    }
  };
  const auto result =
      WriteKittiSequence(f.out_dir, scene.world, scene.camera, gt, f.seq, raw, progress);
  WriteRenderJson(f, gt.size());
  std::cout << fmt::format("wrote {} frames ({}x{}) to {} in {:.1f} s ({:.1f} frames/s)\n",
                           result.frames, scene.camera.width, scene.camera.height, f.out_dir,
                           result.seconds, result.frames_per_second);
  return 0;
}

SPARSELOOP_REGISTER_COMMAND("render", "render a synthetic sequence with ground truth", RunRender);

}  // namespace sparseloop::cli
