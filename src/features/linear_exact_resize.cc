#include "linear_exact_resize.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "sparseloop/core/check.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define SPARSELOOP_RESIZE_X86 1
#endif

namespace sparseloop::internal {
namespace {

constexpr int kOne = 256;  // OpenCV's ufixedpoint16 for 8-bit images: 8 fractional bits

// Tap offsets and coefficients of one direction, as OpenCV's interpolationLinear::getCoeffs
// computes them: source coordinate f = scale * (v + 0.5) - 0.5 with scale = 1 / (dst / src),
// coefficient of the right tap round-half-even((f - floor(f)) * 256). Outputs before `min` take
// the first source pixel, outputs from `max` on the last one.
struct Axis {
  std::vector<int> ofst;
  std::vector<uint16_t> c0, c1;
  int min = 0, max = 0;
};

Axis MakeAxis(int src, int dst) {
  Axis a;
  a.ofst.assign(dst, 0);
  a.c0.assign(dst, kOne);
  a.c1.assign(dst, 0);
  a.max = dst;
  const double inv_scale = static_cast<double>(dst) / src;  // as cv::resize passes it
  const double scale = 1.0 / inv_scale;
  for (int v = 0; v < dst; ++v) {
    // Two separately rounded operations, as cv::softdouble does them (no fused multiply-add).
    volatile double product = scale * (static_cast<double>(v) + 0.5);
    const double f = product - 0.5;
    const int i = static_cast<int>(std::floor(f));
    if (i >= 0 && src > 1) {
      if (i < src - 1) {
        a.ofst[v] = i;
        const double frac = f - static_cast<double>(i);
        const auto c1 = static_cast<uint16_t>(frac > 0.0 ? std::nearbyint(frac * kOne) : 0.0);
        a.c1[v] = c1;
        a.c0[v] = static_cast<uint16_t>(kOne - c1);
      } else {
        a.ofst[v] = src - 1;
        a.max = std::min(a.max, v);
      }
    } else {
      a.min = std::max(a.min, v + 1);
    }
  }
  a.max = std::max(a.max, a.min);
  return a;
}

}  // namespace

struct LinearExactResizer::Tables {
  cv::Size src, dst;
  Axis x, y;
  // Horizontal blocks of 8 output columns from x.min on, while their taps fit one 16-byte load
  // inside the row: per block its load offset, a 32-byte shuffle pattern (the tap pairs of the
  // low and the high 4 outputs as 16-bit lanes) and the 16 coefficients in the same order.
  int blocks = 0;
  std::vector<int> base;
  std::vector<uint8_t> shuffle;
  std::vector<int16_t> coef;
};

namespace {

void BuildBlocks(LinearExactResizer::Tables* t) {
  const Axis& x = t->x;
  for (int b = x.min; b + 8 <= x.max; b += 8) {
    const int base = x.ofst[b];
    if (x.ofst[b + 7] + 1 - base > 15 || base + 16 > t->src.width) break;
    t->base.push_back(base);
    for (int j = 0; j < 8; ++j) {
      const auto o = static_cast<uint8_t>(x.ofst[b + j] - base);
      t->shuffle.insert(t->shuffle.end(), {o, 0x80, static_cast<uint8_t>(o + 1), 0x80});
      t->coef.push_back(static_cast<int16_t>(x.c0[b + j]));
      t->coef.push_back(static_cast<int16_t>(x.c1[b + j]));
    }
    ++t->blocks;
  }
}

// Output columns [from, x.max): the two-tap sum in 8.8 fixed point (at most 256 * 255).
void HorizontalTaps(const uint8_t* s, const Axis& x, int from, uint16_t* h) {
  for (int i = from; i < x.max; ++i) {
    const uint8_t* p = s + x.ofst[i];
    h[i] = static_cast<uint16_t>(x.c0[i] * p[0] + x.c1[i] * p[1]);
  }
}

void HorizontalBorders(const uint8_t* s, const Axis& x, int width, uint16_t* h) {
  const auto first = static_cast<uint16_t>(s[0] << 8);
  for (int i = 0; i < x.min; ++i) h[i] = first;
  const auto last = static_cast<uint16_t>(s[x.ofst[width - 1]] << 8);
  for (int i = x.max; i < width; ++i) h[i] = last;
}

void HorizontalScalar(const uint8_t* s, const LinearExactResizer::Tables& t, uint16_t* h) {
  HorizontalBorders(s, t.x, t.dst.width, h);
  HorizontalTaps(s, t.x, t.x.min, h);
}

// Output = (h0 * c0 + h1 * c1 + 2^15) >> 16 (c0 + c1 = 256).
void VerticalScalar(const uint16_t* h0, const uint16_t* h1, uint32_t c0, uint32_t c1, uint8_t* out,
                    int from, int width) {
  for (int i = from; i < width; ++i) {
    out[i] = static_cast<uint8_t>((h0[i] * c0 + h1[i] * c1 + (1u << 15)) >> 16);
  }
}

// A border row: one source row, rounded from 8.8 fixed point.
void RowFromOne(const uint16_t* h, uint8_t* out, int width) {
  for (int i = 0; i < width; ++i) out[i] = static_cast<uint8_t>((h[i] + 128u) >> 8);
}

#ifdef SPARSELOOP_RESIZE_X86
__attribute__((target("ssse3,sse4.1"))) void HorizontalSse41(const uint8_t* s,
                                                             const LinearExactResizer::Tables& t,
                                                             uint16_t* h) {
  HorizontalBorders(s, t.x, t.dst.width, h);
  int i = t.x.min;
  for (int k = 0; k < t.blocks; ++k, i += 8) {
    const __m128i px = _mm_loadu_si128(reinterpret_cast<const __m128i*>(s + t.base[k]));
    const auto* pattern = reinterpret_cast<const __m128i*>(t.shuffle.data() + 32 * k);
    const auto* coef = reinterpret_cast<const __m128i*>(t.coef.data() + 16 * k);
    const __m128i lo =
        _mm_madd_epi16(_mm_shuffle_epi8(px, _mm_loadu_si128(pattern)), _mm_loadu_si128(coef));
    const __m128i hi = _mm_madd_epi16(_mm_shuffle_epi8(px, _mm_loadu_si128(pattern + 1)),
                                      _mm_loadu_si128(coef + 1));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(h + i), _mm_packus_epi32(lo, hi));
  }
  HorizontalTaps(s, t.x, i, h);
}

// SSE2 (x86-64 baseline). pmaddwd is signed: the rows are biased by -2^15 and the sum corrected by
// 2^15 * (c0 + c1) = 2^23, as OpenCV's own vector loop does.
void VerticalSse2(const uint16_t* h0, const uint16_t* h1, uint32_t c0, uint32_t c1, uint8_t* out,
                  int width) {
  const __m128i bias = _mm_set1_epi16(static_cast<int16_t>(0x8000));
  const __m128i coef = _mm_set1_epi32(static_cast<int32_t>((c1 << 16) | c0));
  const __m128i offset = _mm_set1_epi32((1 << 23) + (1 << 15));
  int i = 0;
  for (; i + 16 <= width; i += 16) {
    __m128i r[4];
    for (int half = 0; half < 2; ++half) {
      const __m128i a =
          _mm_xor_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(h0 + i + 8 * half)), bias);
      const __m128i b =
          _mm_xor_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(h1 + i + 8 * half)), bias);
      r[2 * half] =
          _mm_srli_epi32(_mm_add_epi32(_mm_madd_epi16(_mm_unpacklo_epi16(a, b), coef), offset), 16);
      r[2 * half + 1] =
          _mm_srli_epi32(_mm_add_epi32(_mm_madd_epi16(_mm_unpackhi_epi16(a, b), coef), offset), 16);
    }
    const __m128i bytes =
        _mm_packus_epi16(_mm_packs_epi32(r[0], r[1]), _mm_packs_epi32(r[2], r[3]));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i), bytes);
  }
  VerticalScalar(h0, h1, c0, c1, out, i, width);
}

bool CpuHasSse41() {
  static const bool has = __builtin_cpu_supports("ssse3") && __builtin_cpu_supports("sse4.1");
  return has;
}
#endif

}  // namespace

LinearExactResizer::LinearExactResizer(bool simd) : simd_(simd) {}
LinearExactResizer::~LinearExactResizer() = default;

const LinearExactResizer::Tables& LinearExactResizer::TablesFor(cv::Size src, cv::Size dst) {
  for (const auto& t : tables_) {
    if (t->src == src && t->dst == dst) return *t;
  }
  if (tables_.size() >= 64) tables_.clear();  // bound the cache for callers with many sizes
  auto t = std::make_unique<Tables>();
  t->src = src;
  t->dst = dst;
  t->x = MakeAxis(src.width, dst.width);
  t->y = MakeAxis(src.height, dst.height);
  BuildBlocks(t.get());
  tables_.push_back(std::move(t));
  return *tables_.back();
}

void LinearExactResizer::Resize(const cv::Mat& src, cv::Size size, cv::Mat* dst) {
  SL_CHECK(dst != nullptr);
  // Where OpenCV does not run its bit-exact linear code, or for other types: OpenCV itself.
  const bool half = size.width * 2 == src.cols && size.height * 2 == src.rows;
  if (src.type() != CV_8UC1 || src.empty() || size.width <= 0 || size.height <= 0 ||
      size == src.size() || half) {
    cv::resize(src, *dst, size, 0, 0, cv::INTER_LINEAR_EXACT);
    return;
  }
  if (dst == &src || (dst->data != nullptr && dst->datastart == src.datastart)) {
    cv::Mat out;
    Resize(src, size, &out);
    *dst = out;
    return;
  }
  const Tables& t = TablesFor(src.size(), size);
  dst->create(size, CV_8UC1);
  const int w = size.width;
  rows_.resize(2 * static_cast<size_t>(w));
  uint16_t* buf[2] = {rows_.data(), rows_.data() + w};
  int held[2] = {-1, -1};  // source row in each buffer; rows are requested in increasing order
  auto horizontal = HorizontalScalar;
#ifdef SPARSELOOP_RESIZE_X86
  if (simd_ && CpuHasSse41()) horizontal = HorizontalSse41;
#endif
  const auto row = [&](int r) -> const uint16_t* {
    for (int k = 0; k < 2; ++k) {
      if (held[k] == r) return buf[k];
    }
    const int k = held[0] < held[1] ? 0 : 1;  // the older one
    horizontal(src.ptr<uint8_t>(r), t, buf[k]);
    held[k] = r;
    return buf[k];
  };
  const Axis& y = t.y;
  for (int dy = 0; dy < size.height; ++dy) {
    uint8_t* out = dst->ptr<uint8_t>(dy);
    if (dy < y.min || dy >= y.max) {
      RowFromOne(row(dy < y.min ? 0 : src.rows - 1), out, w);
      continue;
    }
    const uint16_t* h0 = row(y.ofst[dy]);
    const uint16_t* h1 = row(y.ofst[dy] + 1);
#ifdef SPARSELOOP_RESIZE_X86
    if (simd_) {
      VerticalSse2(h0, h1, y.c0[dy], y.c1[dy], out, w);
      continue;
    }
#endif
    VerticalScalar(h0, h1, y.c0[dy], y.c1[dy], out, 0, w);
  }
}

}  // namespace sparseloop::internal
