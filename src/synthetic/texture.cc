#include "sparseloop/synthetic/texture.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/synthetic/image.h"

namespace sparseloop::synthetic {

double SplitMix64::Normal() {
  const double u1 = std::max(Uniform(), 1e-300);
  const double u2 = Uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

uint64_t HashCombine(uint64_t seed, int64_t a, int64_t b, int64_t c) {
  SplitMix64 h(seed ^ 0x51ED270B3A9F4C1DULL);
  uint64_t x = h.Next();
  for (int64_t v : {a, b, c}) {
    SplitMix64 g(x ^ static_cast<uint64_t>(v) * 0xD6E8FEB86659FD93ULL);
    x = g.Next();
  }
  return x;
}

namespace {

// Mirrored-repeat index into [0, n).
inline int Mirror(int i, int n) {
  const int period = 2 * n;
  int m = i % period;
  if (m < 0) m += period;
  return m < n ? m : period - 1 - m;
}

}  // namespace

MipTexture::MipTexture(int width, int height, std::vector<uint8_t> pixels) {
  SL_CHECK_MSG(width > 0 && height > 0, "texture size must be positive, got {}x{}", width, height);
  SL_CHECK_MSG(pixels.size() == static_cast<size_t>(width) * height,
               "texture pixel count {} does not match {}x{}", pixels.size(), width, height);
  levels_.push_back({width, height, std::move(pixels)});
  while (levels_.back().width > 1 || levels_.back().height > 1) {
    const Level& prev = levels_.back();
    Level next;
    next.width = std::max(1, (prev.width + 1) / 2);
    next.height = std::max(1, (prev.height + 1) / 2);
    next.pixels.resize(static_cast<size_t>(next.width) * next.height);
    for (int y = 0; y < next.height; ++y) {
      const int y0 = std::min(2 * y, prev.height - 1), y1 = std::min(2 * y + 1, prev.height - 1);
      for (int x = 0; x < next.width; ++x) {
        const int x0 = std::min(2 * x, prev.width - 1), x1 = std::min(2 * x + 1, prev.width - 1);
        const int sum = prev.pixels[y0 * prev.width + x0] + prev.pixels[y0 * prev.width + x1] +
                        prev.pixels[y1 * prev.width + x0] + prev.pixels[y1 * prev.width + x1];
        next.pixels[y * next.width + x] = static_cast<uint8_t>((sum + 2) / 4);
      }
    }
    levels_.push_back(std::move(next));
  }
}

float MipTexture::SampleLevel(double x, double y, int level) const {
  level = std::clamp(level, 0, num_levels() - 1);
  const Level& l = levels_[level];
  const double inv = 1.0 / static_cast<double>(1 << level);
  const double fx = x * inv - 0.5, fy = y * inv - 0.5;
  const double x0f = std::floor(fx), y0f = std::floor(fy);
  const float ax = static_cast<float>(fx - x0f), ay = static_cast<float>(fy - y0f);
  // Keep the integer part small before the modulo (coordinates can be large on big worlds).
  const int x0 = static_cast<int>(std::fmod(x0f, 2.0 * l.width));
  const int y0 = static_cast<int>(std::fmod(y0f, 2.0 * l.height));
  const int xa = Mirror(x0, l.width), xb = Mirror(x0 + 1, l.width);
  const int ya = Mirror(y0, l.height), yb = Mirror(y0 + 1, l.height);
  const uint8_t* row_a = &l.pixels[static_cast<size_t>(ya) * l.width];
  const uint8_t* row_b = &l.pixels[static_cast<size_t>(yb) * l.width];
  const float top = row_a[xa] + ax * (row_a[xb] - row_a[xa]);
  const float bottom = row_b[xa] + ax * (row_b[xb] - row_b[xa]);
  return top + ay * (bottom - top);
}

float MipTexture::Sample(double x, double y, double footprint) const {
  if (!(footprint > 1.0)) return SampleLevel(x, y, 0);
  const double lod = std::min(std::log2(footprint), static_cast<double>(num_levels() - 1));
  const int l0 = static_cast<int>(std::floor(lod));
  const float w = static_cast<float>(lod - l0);
  const float a = SampleLevel(x, y, l0);
  if (w <= 0.0f || l0 + 1 >= num_levels()) return a;
  return a + w * (SampleLevel(x, y, l0 + 1) - a);
}

void TextureFolderOptions::Check() const {
  SL_CHECK_MSG(max_size >= 16, "max_size must be >= 16 pixels, got {}", max_size);
}

std::shared_ptr<const TextureSet> LoadTextureFolder(const std::filesystem::path& dir,
                                                    const TextureFolderOptions& options) {
  options.Check();
  if (!std::filesystem::is_directory(dir)) {
    throw FileError(dir.string(), 0, "a folder of texture images", "no such folder");
  }
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext != ".png" && ext != ".jpg" && ext != ".jpeg" && ext != ".bmp" && ext != ".pgm") {
      continue;
    }
    const std::string name = entry.path().filename().string();
    bool keep = options.name_filter.empty();
    for (const auto& f : options.name_filter) keep = keep || name.find(f) != std::string::npos;
    if (keep) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) {
    throw FileError(dir.string(), 0, "at least one image matching the texture filter",
                    "none found");
  }
  auto set = std::make_shared<TextureSet>();
  for (const auto& file : files) {
    cv::Mat img = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    if (img.empty()) throw FileError(file.string(), 0, "a decodable image", "decoding failed");
    const int longer = std::max(img.cols, img.rows);
    if (longer > options.max_size) {
      const double f = static_cast<double>(options.max_size) / longer;
      cv::Mat small;
      cv::resize(img, small, cv::Size(), f, f, cv::INTER_AREA);
      img = small;
    }
    if (!img.isContinuous()) img = img.clone();
    set->textures.emplace_back(img.cols, img.rows,
                               std::vector<uint8_t>(img.data, img.data + img.total()));
    set->names.push_back(file.stem().string());
  }
  Logger().info("loaded {} textures from {}", set->size(), dir.string());
  return set;
}

void ProceduralTextureOptions::Check() const {
  SL_CHECK_MSG(count >= 1, "count must be >= 1, got {}", count);
  SL_CHECK_MSG(size >= 16 && size <= 4096, "size must be in [16, 4096] pixels, got {}", size);
  SL_CHECK_MSG(octaves >= 1 && octaves <= 10, "octaves must be in [1, 10], got {}", octaves);
  SL_CHECK_MSG(rectangles >= 0 && discs >= 0 && lines >= 0,
               "shape counts must be non-negative, got {} {} {}", rectangles, discs, lines);
}

namespace {

float SmoothStep(float t) { return t * t * (3.0f - 2.0f * t); }

// Periodic value noise on a lattice of `cells` x `cells`, evaluated on size x size pixels.
void AddValueNoise(std::vector<float>& img, int size, int cells, float amplitude, uint64_t seed) {
  std::vector<float> lattice(static_cast<size_t>(cells) * cells);
  SplitMix64 rng(seed);
  for (auto& v : lattice) v = static_cast<float>(rng.Uniform(-1.0, 1.0));
  const float scale = static_cast<float>(cells) / size;
  for (int y = 0; y < size; ++y) {
    const float fy = (y + 0.5f) * scale;
    const int y0 = static_cast<int>(fy) % cells, y1 = (y0 + 1) % cells;
    const float ty = SmoothStep(fy - std::floor(fy));
    for (int x = 0; x < size; ++x) {
      const float fx = (x + 0.5f) * scale;
      const int x0 = static_cast<int>(fx) % cells, x1 = (x0 + 1) % cells;
      const float tx = SmoothStep(fx - std::floor(fx));
      const float a =
          lattice[y0 * cells + x0] + tx * (lattice[y0 * cells + x1] - lattice[y0 * cells + x0]);
      const float b =
          lattice[y1 * cells + x0] + tx * (lattice[y1 * cells + x1] - lattice[y1 * cells + x0]);
      img[static_cast<size_t>(y) * size + x] += amplitude * (a + ty * (b - a));
    }
  }
}

}  // namespace

std::shared_ptr<const TextureSet> MakeProceduralTextures(const ProceduralTextureOptions& options) {
  options.Check();
  auto set = std::make_shared<TextureSet>();
  const int n = options.size;
  for (int k = 0; k < options.count; ++k) {
    SplitMix64 rng(HashCombine(options.seed, k));
    std::vector<float> img(static_cast<size_t>(n) * n, 128.0f);
    float amplitude = 60.0f;
    for (int o = 0, cells = 4; o < options.octaves && cells <= n; ++o, cells *= 2) {
      AddValueNoise(img, n, cells, amplitude, rng.Next());
      amplitude *= 0.55f;
    }
    auto set_pixel = [&](int x, int y, float value, float alpha) {
      x = ((x % n) + n) % n;  // shapes wrap around so the texture tiles
      y = ((y % n) + n) % n;
      float& p = img[static_cast<size_t>(y) * n + x];
      p = (1.0f - alpha) * p + alpha * value;
    };
    for (int r = 0; r < options.rectangles; ++r) {
      const int w = static_cast<int>(rng.Uniform(0.02, 0.18) * n);
      const int h = static_cast<int>(rng.Uniform(0.02, 0.18) * n);
      const int x0 = static_cast<int>(rng.Uniform() * n), y0 = static_cast<int>(rng.Uniform() * n);
      const float value = static_cast<float>(rng.Uniform(10.0, 245.0));
      const float alpha = static_cast<float>(rng.Uniform(0.5, 0.9));
      for (int y = y0; y < y0 + h; ++y)
        for (int x = x0; x < x0 + w; ++x) set_pixel(x, y, value, alpha);
    }
    for (int d = 0; d < options.discs; ++d) {
      const double radius = rng.Uniform(0.01, 0.07) * n;
      const double cx = rng.Uniform() * n, cy = rng.Uniform() * n;
      const float value = static_cast<float>(rng.Uniform(10.0, 245.0));
      const int r = static_cast<int>(std::ceil(radius));
      for (int y = -r; y <= r; ++y)
        for (int x = -r; x <= r; ++x)
          if (x * x + y * y <= radius * radius)
            set_pixel(static_cast<int>(cx) + x, static_cast<int>(cy) + y, value, 0.85f);
    }
    for (int l = 0; l < options.lines; ++l) {
      const double x0 = rng.Uniform() * n, y0 = rng.Uniform() * n;
      const double angle = rng.Uniform(0.0, M_PI);
      const double length = rng.Uniform(0.1, 0.5) * n;
      const int thickness = 1 + static_cast<int>(rng.Uniform() * 3.0);
      const float value = rng.Uniform() < 0.5 ? 20.0f : 235.0f;
      for (double s = 0; s < length; s += 0.5) {
        const int x = static_cast<int>(x0 + s * std::cos(angle));
        const int y = static_cast<int>(y0 + s * std::sin(angle));
        for (int t = 0; t < thickness; ++t) set_pixel(x, y + t, value, 1.0f);
      }
    }
    // Fine grain so that even flat shapes carry some texture.
    AddValueNoise(img, n, std::min(n, 128), 8.0f, rng.Next());
    std::vector<uint8_t> pixels(img.size());
    for (size_t i = 0; i < img.size(); ++i) {
      pixels[i] = static_cast<uint8_t>(std::clamp(std::lround(img[i]), 0L, 255L));
    }
    set->textures.emplace_back(n, n, std::move(pixels));
    set->names.push_back("procedural_" + std::to_string(k));
  }
  return set;
}

}  // namespace sparseloop::synthetic
