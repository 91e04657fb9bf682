// sparseloop render: synthetic sequence (images + GT + drifting raw trajectory) in KITTI layout.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "sparseloop/core/check.h"
#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/trajectory_io.h"
#include "sparseloop/synthetic/sequence.h"
#include "sparseloop/synthetic/texture.h"
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

}  // namespace

int RunRender(int argc, char** argv) {
  namespace syn = sparseloop::synthetic;
  CLI::App app{"Render a synthetic sequence (KITTI folder layout) with exact ground truth"};
  std::string world_name, trajectory_path, plan_name = "circuit", textures_dir, texture_filter;
  std::string raw_path, out_dir, raw_format = "auto";
  int frames = 0, threads = 2, kitti_sequence = -1, start = 0, step = 1;
  uint64_t seed = 1;
  syn::FlightPlanOptions plan;
  syn::SequenceOptions seq;
  bool no_photometric = false, no_mapped = false, poses_only = false;
  double drift_scale = 1.0, photometric_scale = 1.0;
  app.add_option("--world", world_name, "aerial or street")
      ->required()
      ->check(CLI::IsMember({"aerial", "street"}));
  app.add_option("--trajectory", trajectory_path,
                 "GT trajectory file (street: required; aerial: replaces --plan)");
  app.add_option("--plan", plan_name, "aerial flight plan: circuit, figure8, lawnmower")
      ->capture_default_str();
  app.add_option("--textures", textures_dir, "texture folder (default: procedural textures)");
  app.add_option("--texture-filter", texture_filter,
                 "comma-separated substrings; only matching texture file names are used");
  app.add_option("--frames", frames, "frames to render (0: all poses / the plan's default)")
      ->check(IntegerAtLeast(0))
      ->capture_default_str();
  app.add_option("--start", start,
                 "first pose of --trajectory to render (the world is still "
                 "built from the whole trajectory)")
      ->check(IntegerAtLeast(0))
      ->capture_default_str();
  app.add_option("--step", step, "render every step-th pose")
      ->check(IntegerAtLeast(1))
      ->capture_default_str();
  app.add_option("--seed", seed, "seed of the world, noise and drift")->capture_default_str();
  app.add_option("--threads", threads, "frames rendered in parallel")
      ->check(IntegerAtLeast(1))
      ->capture_default_str();
  app.add_option("--altitude", plan.altitude, "aerial: metres above ground")->capture_default_str();
  app.add_option("--tilt", plan.tilt_deg, "aerial: camera tilt from nadir, degrees")
      ->capture_default_str();
  app.add_option("--size", plan.size, "aerial: side of the flown area, metres")
      ->capture_default_str();
  app.add_option("--laps", plan.laps, "aerial: laps of circuit/figure8")->capture_default_str();
  app.add_option("--kitti-sequence", kitti_sequence,
                 "street: KITTI sequence whose cam0 intrinsics to use (default: from the file "
                 "name, else 0)");
  app.add_option("--noise", seq.render.noise_sigma, "sensor noise std-dev, gray levels")
      ->capture_default_str();
  app.add_option("--blur", seq.render.blur_sigma, "Gaussian blur std-dev, pixels")
      ->capture_default_str();
  app.add_flag("--no-photometric", no_photometric, "constant exposure and gamma");
  app.add_option("--raw", raw_path,
                 "real estimate (associated by index) instead of simulated "
                 "drift");
  app.add_option("--raw-format", raw_format, "format of --raw")->capture_default_str();
  app.add_flag("--depth", seq.write_depth, "also write depth_0/NNNNNN.png (metres * 256)");
  app.add_flag("--no-mapped", no_mapped, "do not write mapped/NNNNNN.txt");
  app.add_option("--drift", drift_scale,
                 "multiplies every simulated drift rate (rotation, translation, scale); 0: none")
      ->capture_default_str();
  app.add_option("--photometric", photometric_scale,
                 "multiplies the exposure/gamma change amplitudes")
      ->capture_default_str();
  app.add_flag(
      "--poses-only", poses_only,
      "write only poses_gt.txt and poses_raw.txt (no images; same drift as a full render)");
  app.add_option("--out", out_dir, "output folder")->required();
  Parse(app, argc, argv);
  CheckOutputDirFlag("--out", out_dir,
                     {"poses_gt.txt", "poses_raw.txt", "poses.txt", "times.txt", "render.json"});

  seq.num_threads = threads;
  seq.photometric_drift = !no_photometric;
  seq.write_mapped = !no_mapped;
  seq.render.seed = syn::HashCombine(seed, 1);
  seq.drift.seed = syn::HashCombine(seed, 2);
  seq.photometric.seed = syn::HashCombine(seed, 3);
  SL_CHECK_MSG(drift_scale >= 0.0 && std::isfinite(drift_scale), "--drift must be >= 0, got {}",
               drift_scale);
  SL_CHECK_MSG(photometric_scale >= 0.0 && std::isfinite(photometric_scale),
               "--photometric must be >= 0, got {}", photometric_scale);
  seq.drift.rotation_noise_deg_per_sqrt_m *= drift_scale;
  seq.drift.rotation_bias_deg_per_100m *= drift_scale;
  seq.drift.translation_noise *= drift_scale;
  seq.drift.scale_noise_per_sqrt_m *= drift_scale;
  seq.drift.scale_bias_per_100m *= drift_scale;
  seq.photometric.gain_amplitude *= photometric_scale;
  seq.photometric.gamma_amplitude *= photometric_scale;
  if (frames > 0) plan.frames = frames;
  CheckNamingFlags({{"altitude", "--altitude"},
                    {"tilt_deg", "--tilt"},
                    {"size", "--size"},
                    {"laps", "--laps"},
                    {"frames", "--frames"},
                    {"noise_sigma", "--noise"},
                    {"blur_sigma", "--blur"},
                    {"gain_amplitude", "--photometric"},
                    {"gamma_amplitude", "--photometric"}},
                   [&] {
                     plan.Check();
                     seq.Check();
                   });

  std::shared_ptr<const syn::TextureSet> textures;
  if (textures_dir.empty()) {
    syn::ProceduralTextureOptions tex;
    tex.seed = syn::HashCombine(seed, 4);
    textures = syn::MakeProceduralTextures(tex);
  } else {
    syn::TextureFolderOptions tex;
    tex.name_filter = SplitComma(texture_filter);
    textures = syn::LoadTextureFolder(textures_dir, tex);
  }

  Trajectory gt;
  syn::World world;
  CameraIntrinsics camera;
  if (world_name == "aerial") {
    if (!trajectory_path.empty()) {
      gt = ReadTrajectory(trajectory_path);
    } else {
      plan.plan = syn::ParseFlightPlan(plan_name);
      gt = syn::MakeFlightTrajectory(plan);
    }
    syn::AerialWorldOptions options;
    options.seed = syn::HashCombine(seed, 5);
    world = syn::MakeAerialWorld(textures, options);
    camera = syn::DefaultAerialCamera();
  } else {
    SL_CHECK_MSG(!trajectory_path.empty(), "--world street needs --trajectory FILE");
    gt = ReadTrajectory(trajectory_path);
    if (kitti_sequence < 0) {
      const std::string stem = std::filesystem::path(trajectory_path).stem().string();
      kitti_sequence = (!stem.empty() && stem.size() <= 2 &&
                        stem.find_first_not_of("0123456789") == std::string::npos)
                           ? std::stoi(stem)
                           : 0;
    }
    camera = syn::KittiCam0Intrinsics(kitti_sequence);
    syn::StreetWorldOptions options;
    options.seed = syn::HashCombine(seed, 6);
    world = syn::MakeStreetWorld(gt, textures, options);  // the whole trajectory shapes the world
  }
  SL_CHECK_MSG(start >= 0 && static_cast<size_t>(start) < gt.size(),
               "--start {} outside the trajectory of {} poses", start, gt.size());
  SL_CHECK_MSG(step >= 1, "--step must be >= 1, got {}", step);
  if (start > 0 || step > 1) {
    Trajectory picked = gt;
    picked.poses.clear();
    for (size_t i = start; i < gt.size(); i += step) picked.poses.push_back(gt.poses[i]);
    gt = std::move(picked);
  }
  if (frames > 0 && static_cast<size_t>(frames) < gt.size()) gt.poses.resize(frames);
  std::optional<Trajectory> raw;
  if (!raw_path.empty()) {
    raw = ReadTrajectory(raw_path, ParseTrajectoryFormat(raw_format));
    if (raw->size() > gt.size()) raw->poses.resize(gt.size());
  }

  // render.json: what was rendered, so a --start / --step slice is known from the folder itself
  // (frame k of the folder is pose start + k * step of the trajectory).
  const auto write_render_json = [&] {
    nlohmann::json j = {
        {"command", "render"},
        {"world", world_name},
        {"trajectory",
         trajectory_path.empty() ? nlohmann::json(nullptr) : nlohmann::json(trajectory_path)},
        {"plan", trajectory_path.empty() && world_name == "aerial" ? nlohmann::json(plan_name)
                                                                   : nlohmann::json(nullptr)},
        {"start", start},
        {"step", step},
        {"frames", gt.size()},
        {"seed", seed},
        {"raw", raw_path.empty() ? nlohmann::json(nullptr) : nlohmann::json(raw_path)},
        {"drift", drift_scale},
        {"photometric", photometric_scale},
        {"poses_only", poses_only}};
    WriteFileAtomically(std::filesystem::path(out_dir) / "render.json",
                        [&](std::ostream& os) { os << j.dump(2) << "\n"; });
  };
  if (poses_only) {
    SL_CHECK_MSG(!raw, "--poses-only simulates the drift; it cannot be combined with --raw");
    const syn::DriftResult drift = syn::SimulateDrift(gt, seq.drift);
    std::filesystem::create_directories(out_dir);
    WriteTrajectory(std::filesystem::path(out_dir) / "poses_gt.txt", gt, TrajectoryFormat::kKitti);
    WriteTrajectory(std::filesystem::path(out_dir) / "poses_raw.txt", drift.raw,
                    TrajectoryFormat::kKitti);
    write_render_json();
    std::cout << fmt::format("wrote poses_gt.txt and poses_raw.txt ({} poses) to {}\n", gt.size(),
                             out_dir);
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
  const auto result = syn::WriteKittiSequence(out_dir, world, camera, gt, seq, raw, progress);
  write_render_json();
  std::cout << fmt::format("wrote {} frames ({}x{}) to {} in {:.1f} s ({:.1f} frames/s)\n",
                           result.frames, camera.width, camera.height, out_dir, result.seconds,
                           result.frames_per_second);
  return 0;
}

SPARSELOOP_REGISTER_COMMAND("render", "render a synthetic sequence with ground truth", RunRender);

}  // namespace sparseloop::cli
