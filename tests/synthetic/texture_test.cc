#include <cmath>

#include <gtest/gtest.h>

#include "sparseloop/core/error.h"
#include "sparseloop/synthetic/image.h"
#include "sparseloop/synthetic/texture.h"
#include "test_util.h"

namespace sparseloop::synthetic {
namespace {

TEST(MipTexture, ConstantTextureSamplesToConstantAtEveryLevel) {
  MipTexture t(37, 21, std::vector<uint8_t>(37 * 21, 93));
  EXPECT_EQ(t.num_levels(), 7);  // 37 -> 19 -> 10 -> 5 -> 3 -> 2 -> 1
  for (double f : {0.5, 1.0, 3.0, 17.0, 1e4}) {
    EXPECT_FLOAT_EQ(t.Sample(12.3, -40.7, f), 93.0f) << f;
  }
}

TEST(MipTexture, BilinearKnownAnswers) {
  // 2x2 texture: [0 100; 200 40].
  MipTexture t(2, 2, {0, 100, 200, 40});
  EXPECT_FLOAT_EQ(t.SampleLevel(0.5, 0.5, 0), 0.0f);    // texel centre
  EXPECT_FLOAT_EQ(t.SampleLevel(1.5, 0.5, 0), 100.0f);  // texel centre
  EXPECT_FLOAT_EQ(t.SampleLevel(1.0, 0.5, 0), 50.0f);   // halfway between 0 and 100
  EXPECT_FLOAT_EQ(t.SampleLevel(1.0, 1.0, 0), 85.0f);   // mean of the four
  // Mirrored repeat: just left of texel 0 is texel 0 again, so (0, 0.5) == texel 0's value.
  EXPECT_FLOAT_EQ(t.SampleLevel(0.0, 0.5, 0), 0.0f);
  // Level 1 is the 2x2 box average (rounded): (0 + 100 + 200 + 40 + 2) / 4 = 85.
  EXPECT_FLOAT_EQ(t.SampleLevel(0.3, 1.7, 1), 85.0f);
  // Trilinear half-way between level 0 and 1 at a texel centre: (0 + 85) / 2.
  EXPECT_NEAR(t.Sample(0.5, 0.5, std::sqrt(2.0)), 42.5f, 1e-4);
}

TEST(MipTexture, RejectsMismatchedSizes) {
  EXPECT_THROW(MipTexture(4, 4, std::vector<uint8_t>(15)), std::invalid_argument);
  EXPECT_THROW(MipTexture(0, 4, {}), std::invalid_argument);
}

TEST(ProceduralTextures, DeterministicDistinctAndCornerRich) {
  ProceduralTextureOptions o;
  o.count = 3;
  o.size = 128;
  const auto a = MakeProceduralTextures(o);
  const auto b = MakeProceduralTextures(o);
  ASSERT_EQ(a->size(), 3u);
  for (int k = 0; k < 3; ++k) {
    int differ = 0;
    for (int y = 0; y < 128; ++y)
      for (int x = 0; x < 128; ++x) {
        const double pa = a->textures[k].SampleLevel(x + 0.5, y + 0.5, 0);
        EXPECT_EQ(pa, b->textures[k].SampleLevel(x + 0.5, y + 0.5, 0));
        if (k > 0 && std::abs(pa - a->textures[0].SampleLevel(x + 0.5, y + 0.5, 0)) > 10) ++differ;
      }
    if (k > 0) {
      EXPECT_GT(differ, 128 * 128 / 2) << "textures 0 and " << k << " look alike";
    }
  }
  o.seed += 1;
  const auto c = MakeProceduralTextures(o);
  EXPECT_NE(
      c->textures[0].SampleLevel(10.5, 10.5, 0) * 1000 + c->textures[0].SampleLevel(70.5, 3.5, 0),
      a->textures[0].SampleLevel(10.5, 10.5, 0) * 1000 + a->textures[0].SampleLevel(70.5, 3.5, 0));
  // Structure: a good share of pixels carry a strong gradient in both directions (corners/edges).
  int strong = 0;
  const auto& t = a->textures[0];
  for (int y = 1; y < 127; ++y)
    for (int x = 1; x < 127; ++x) {
      const double gx = t.SampleLevel(x + 1.5, y + 0.5, 0) - t.SampleLevel(x - 0.5, y + 0.5, 0);
      const double gy = t.SampleLevel(x + 0.5, y + 1.5, 0) - t.SampleLevel(x + 0.5, y - 0.5, 0);
      if (std::abs(gx) > 30 && std::abs(gy) > 30) ++strong;
    }
  EXPECT_GT(strong, 30);
}

TEST(TextureFolder, LoadsSortedFilteredImages) {
  SL_REQUIRE_DATA("textures");
  TextureFolderOptions o;
  o.name_filter = {"aero"};
  o.max_size = 256;
  const auto set = LoadTextureFolder(test::DataDir() / "textures", o);
  ASSERT_EQ(set->size(), 2u);
  EXPECT_EQ(set->names[0], "aero1");
  EXPECT_EQ(set->names[1], "aero3");
  EXPECT_LE(std::max(set->textures[0].width(), set->textures[0].height()), 256);
}

TEST(TextureFolder, MissingFolderIsFileError) {
  EXPECT_THROW(LoadTextureFolder("/nonexistent/textures"), FileError);
}

TEST(SplitMix64, UniformAndNormalMoments) {
  SplitMix64 rng(42);
  double s = 0, s2 = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double x = rng.Normal();
    s += x, s2 += x * x;
  }
  EXPECT_NEAR(s / n, 0.0, 0.01);
  EXPECT_NEAR(s2 / n, 1.0, 0.02);
  EXPECT_NE(HashCombine(1, 2, 3), HashCombine(1, 3, 2));
}

}  // namespace
}  // namespace sparseloop::synthetic
