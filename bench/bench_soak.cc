// Soak benchmark (not a unit test, no Google Benchmark main): pushes N keyframes of cheap
// synthetic images through LoopClosing (the online API: LoopDetector, loop edges as `run` makes
// them, BackgroundOptimizer), and records memory and time as the map grows. docs/ROBUSTNESS.md,
// "Soak". --no-optimizer: LoopClosing::Options::optimize = false (detection only).
//
//   bench_soak [--keyframes 100000] [--k 300] [--out soak.csv] [--period 400] [--check-every 10]
//              [--window 1000] [--no-optimizer] [--rejection pcm|none] [--keep-heap]
//              [--full-graph]
//   --keep-heap: BackgroundOptimizerOptions::release_memory_after_solve = false (the comparison).
//   --full-graph: PoseGraphOptions::reduce_chains = false (every vertex in each solve).
//
// Images: 320x240 crops of one 2400x2400 procedural texture (value noise + rectangles + discs,
// corner-rich for ORB), seen by a nadir camera (fx = 300 px) at 10 m over the plane, so a crop
// shift of 30 px is 1 m. Trajectory: a circle of 24 m radius flown every `period` keyframes, with
// a slow radial wobble so that laps do not repeat exactly; every lap revisits the first one.
// Raw poses: the true poses (the soak measures resources, not accuracy).
//
// Every `window` keyframes one CSV row: keyframes, peak RSS (VmHWM) and current RSS (VmRSS) in KiB
// from /proc/self/status, mean and p99 ms per keyframe (Process + pushes) in the window, loops
// so far, optimizer solves so far, detector record bytes (sum of the stored
// PackedKeyframe::Bytes()). At the end the RSS slope over the second half (bytes per keyframe,
// least squares) and a JSON summary go to stdout.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "sparseloop/core/statistics.h"
#include "sparseloop/runtime/loop_closing.h"

namespace {

using sparseloop::Sim3d;

long StatusKiB(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string k = std::string(key) + ":";
  while (std::getline(in, line)) {
    if (line.rfind(k, 0) == 0) return std::atol(line.c_str() + k.size());
  }
  return -1;
}

cv::Mat MakeTexture(int size, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat acc(size, size, CV_32F, cv::Scalar(0));
  for (int cell = size / 4, w = 1; cell >= 4; cell /= 2, ++w) {
    cv::Mat small(size / cell + 2, size / cell + 2, CV_32F);
    rng.fill(small, cv::RNG::UNIFORM, 0.0, 1.0);
    cv::Mat up;
    cv::resize(small, up, cv::Size(), cell, cell, cv::INTER_CUBIC);
    acc += up(cv::Rect(0, 0, size, size)) * (1.0 / w);
  }
  cv::Mat img;
  cv::normalize(acc, acc, 40, 200, cv::NORM_MINMAX);
  acc.convertTo(img, CV_8U);
  const int shapes = size * size / 2500;
  for (int i = 0; i < shapes; ++i) {
    const cv::Point p(rng.uniform(0, size), rng.uniform(0, size));
    const int r = rng.uniform(3, 25);
    const cv::Scalar c(rng.uniform(0, 256));
    if (i % 2)
      cv::rectangle(img, p, p + cv::Point(r, rng.uniform(3, 25)), c, cv::FILLED);
    else
      cv::circle(img, p, r / 2 + 2, c, cv::FILLED);
  }
  return img;
}

}  // namespace

int main(int argc, char** argv) {
  long keyframes = 100000;
  int k = 300;
  int period = 400;
  int check_every = 10;
  int window = 1000;
  bool use_optimizer = true;
  bool keep_heap = false;
  bool full_graph = false;
  std::string rejection = "pcm";
  std::string out_path = "soak.csv";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "bench_soak: " << a << " needs a value\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--keyframes")
      keyframes = std::atol(next().c_str());
    else if (a == "--k")
      k = std::atoi(next().c_str());
    else if (a == "--period")
      period = std::atoi(next().c_str());
    else if (a == "--check-every")
      check_every = std::atoi(next().c_str());
    else if (a == "--window")
      window = std::atoi(next().c_str());
    else if (a == "--out")
      out_path = next();
    else if (a == "--no-optimizer")
      use_optimizer = false;
    else if (a == "--rejection")
      rejection = next();
    else if (a == "--keep-heap")
      keep_heap = true;
    else if (a == "--full-graph")
      full_graph = true;
    else {
      std::cerr << "usage: bench_soak [--keyframes N] [--k K] [--out CSV] [--period P] "
                   "[--check-every N] [--window W] [--no-optimizer] [--rejection pcm|none] "
                   "[--keep-heap] [--full-graph]\n";
      return a == "--help" ? 0 : 2;
    }
  }
  if (keyframes < 2 * window || k < 5 || period < 20 || window < 1 || check_every < 1 ||
      (rejection != "pcm" && rejection != "none")) {
    std::cerr << "bench_soak: need keyframes >= 2 x window, k >= 5, period >= 20, "
                 "rejection pcm|none\n";
    return 2;
  }
  cv::setNumThreads(1);

  const int width = 320, height = 240, tex_size = 2400;
  const double fx = 300.0, altitude = 10.0, px_per_m = fx / altitude;
  const cv::Mat texture = MakeTexture(tex_size, 7);
  sparseloop::CameraIntrinsics cam;
  cam.fx = cam.fy = fx;
  cam.cx = (width - 1) / 2.0;
  cam.cy = (height - 1) / 2.0;
  cam.width = width;
  cam.height = height;

  // Loop edges weighted as `sparseloop run` does it (LoopEdgeOptions defaults).
  sparseloop::LoopClosing::Options lopt;
  lopt.detector.features.max_features = k;
  lopt.detector.check_every = check_every;
  lopt.optimize = use_optimizer;
  lopt.optimizer.solve.rejection =
      rejection == "pcm" ? sparseloop::OutlierRejection::kPcm : sparseloop::OutlierRejection::kNone;
  lopt.optimizer.solve.max_iterations = 20;
  lopt.optimizer.solve.reduce_chains = !full_graph;
  lopt.optimizer.release_memory_after_solve = !keep_heap;
  sparseloop::LoopClosing closing(lopt);

  // Nadir camera: x right = world x, y down = world -y, z forward = world -z.
  Eigen::Matrix3d r_nadir;
  r_nadir << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  const Eigen::Quaterniond q_nadir(r_nadir);
  const double radius_m = 24.0;
  const double centre_m = tex_size / 2.0 / px_per_m;
  auto pose_of = [&](long i) {
    const double phase = 2.0 * M_PI * static_cast<double>(i % period) / period;
    const double lap = static_cast<double>(i / period);
    const double r = radius_m + 0.5 * std::sin(0.7 * lap);  // laps differ by up to 1 m
    return Sim3d(
        1.0, q_nadir,
        Eigen::Vector3d(centre_m + r * std::cos(phase), centre_m + r * std::sin(phase), altitude));
  };

  std::ofstream csv(out_path);
  csv << "keyframes,peak_rss_kib,rss_kib,mean_ms,p99_ms,loops,solves,record_bytes\n";
  std::vector<double> window_ms;
  std::vector<std::pair<double, double>> rss_points;  // (keyframes, RSS bytes)
  long loops = 0;
  size_t record_bytes = 0;
  const long rss_start_kib = StatusKiB("VmRSS");
  const auto t0 = std::chrono::steady_clock::now();
  cv::Mat image(height, width, CV_8UC1);
  cv::RNG noise(3);
  for (long i = 0; i < keyframes; ++i) {
    const Sim3d pose = pose_of(i);
    // The crop the nadir camera sees (texture row = +y north flipped: row = tex - y * px).
    const int u0 = static_cast<int>(std::lround(pose.translation.x() * px_per_m)) - width / 2;
    const int v0 =
        tex_size - static_cast<int>(std::lround(pose.translation.y() * px_per_m)) - height / 2;
    texture(cv::Rect(u0, v0, width, height)).copyTo(image);
    cv::Mat n(height, width, CV_8S);
    noise.fill(n, cv::RNG::NORMAL, 0, 2);
    cv::add(image, n, image, cv::noArray(), CV_8U);

    const auto start = std::chrono::steady_clock::now();
    sparseloop::KeyframeInput in;
    in.id = i;
    in.timestamp = 0.1 * static_cast<double>(i + 1);
    in.image = image;
    in.intrinsics = cam;
    in.world_from_cam = pose;
    const sparseloop::LoopEvent e = closing.AddKeyframe(in);
    record_bytes += closing.detector().packed_record(i).Bytes();
    if (e.result.detected()) ++loops;
    window_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count());
    if ((i + 1) % window == 0) {
      const long hwm = StatusKiB("VmHWM"), rss = StatusKiB("VmRSS");
      double mean = 0.0;
      for (double v : window_ms) mean += v;
      mean /= static_cast<double>(window_ms.size());
      const uint64_t solves = closing.num_solves();
      csv << (i + 1) << ',' << hwm << ',' << rss << ',' << mean << ','
          << sparseloop::Percentile(window_ms, 0.99) << ',' << loops << ',' << solves << ','
          << record_bytes << '\n'
          << std::flush;
      rss_points.emplace_back(static_cast<double>(i + 1), 1024.0 * static_cast<double>(rss));
      std::fprintf(stderr, "soak: %ld keyframes, RSS %.1f MiB, %.2f ms/kf, %ld loops, %lu solves\n",
                   i + 1, rss / 1024.0, mean, loops, static_cast<unsigned long>(solves));
      window_ms.clear();
    }
  }
  const double loop_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  closing.Finish();
  const double total_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  // Least-squares slope of RSS over the second half of the windows.
  double sx = 0, sy = 0, sxx = 0, sxy = 0, n = 0;
  for (size_t j = rss_points.size() / 2; j < rss_points.size(); ++j) {
    const auto [x, y] = rss_points[j];
    sx += x, sy += y, sxx += x * x, sxy += x * y, n += 1;
  }
  const double slope = n >= 2 ? (n * sxy - sx * sy) / (n * sxx - sx * sx) : 0.0;
  const long final_rss = StatusKiB("VmRSS"), peak = StatusKiB("VmHWM");
  std::printf(
      "{\"keyframes\": %ld, \"k\": %d, \"check_every\": %d, \"period\": %d, \"optimizer\": %s, "
      "\"rejection\": \"%s\", \"release_memory_after_solve\": %s, \"reduce_chains\": %s, "
      "\"loops\": %ld, "
      "\"solves\": %lu, "
      "\"rss_bytes_per_keyframe_second_half\": %.1f, \"record_bytes_per_keyframe\": %.1f, "
      "\"rss_start_kib\": %ld, \"rss_end_kib\": %ld, \"peak_rss_kib\": %ld, "
      "\"loop_seconds\": %.1f, \"total_seconds\": %.1f, \"ms_per_keyframe\": %.3f, "
      "\"csv\": \"%s\"}\n",
      keyframes, k, check_every, period, use_optimizer ? "true" : "false", rejection.c_str(),
      keep_heap ? "false" : "true", full_graph ? "false" : "true", loops,
      static_cast<unsigned long>(closing.num_solves()), slope,
      static_cast<double>(record_bytes) / static_cast<double>(keyframes), rss_start_kib, final_rss,
      peak, loop_seconds, total_seconds, 1000.0 * loop_seconds / keyframes, out_path.c_str());
  return 0;
}
