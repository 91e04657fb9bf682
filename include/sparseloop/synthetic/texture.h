#pragma once
// Grayscale textures with a mip chain and trilinear sampling, loaded from a folder of photos or
// generated procedurally (seeded, no external files needed).
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace sparseloop::synthetic {

// An 8-bit texture with its mip chain (2x2 box filter per level). Addressing is mirrored-repeat,
// so a texture tiles without seams. Texel (i, j) of level 0 covers [i, i+1) x [j, j+1); texel
// centres are at half-integers.
class MipTexture {
 public:
  MipTexture() = default;
  // `pixels` is row-major width x height. Throws std::invalid_argument when sizes do not match.
  MipTexture(int width, int height, std::vector<uint8_t> pixels);

  int width() const { return levels_.empty() ? 0 : levels_[0].width; }
  int height() const { return levels_.empty() ? 0 : levels_[0].height; }
  int num_levels() const { return static_cast<int>(levels_.size()); }

  // Bilinear sample of one mip level at level-0 texel coordinates (x, y).
  float SampleLevel(double x, double y, int level) const;
  // Trilinear sample: `footprint` is the size of one screen pixel in level-0 texels; the level is
  // log2(footprint) and the two neighbouring levels are blended (footprint <= 1: level 0 only).
  float Sample(double x, double y, double footprint) const;

 private:
  struct Level {
    int width = 0;
    int height = 0;
    std::vector<uint8_t> pixels;
  };
  std::vector<Level> levels_;
};

struct TextureSet {
  std::vector<MipTexture> textures;
  std::vector<std::string> names;  // file stem or "procedural_<k>"

  size_t size() const { return textures.size(); }
  bool empty() const { return textures.empty(); }
};

struct TextureFolderOptions {
  // Keep only files whose name contains one of these substrings (empty: keep every image).
  std::vector<std::string> name_filter;
  int max_size = 1024;  // pixels; larger images are downscaled (area filter) to this longer side
  void Check() const;
};

// Loads every *.png/*.jpg/*.jpeg/*.bmp/*.pgm in `dir` (sorted by file name, so the order and
// hence the world is deterministic) as grayscale. Throws FileError when the folder is missing,
// an image cannot be decoded, or no image passes the filter.
std::shared_ptr<const TextureSet> LoadTextureFolder(const std::filesystem::path& dir,
                                                    const TextureFolderOptions& options = {});

struct ProceduralTextureOptions {
  int count = 12;       // number of textures
  int size = 512;       // pixels, square
  int octaves = 5;      // value-noise octaves (coarsest cell = size / 4)
  int rectangles = 60;  // random filled rectangles per texture (corners for ORB)
  int discs = 25;       // random filled discs per texture
  int lines = 20;       // random line segments per texture
  uint64_t seed = 7;    // everything is a function of this seed
  void Check() const;
};

// Multi-octave value noise + random rectangles, discs and lines: corner-rich, non-periodic
// within a texture, different for every texture index.
std::shared_ptr<const TextureSet> MakeProceduralTextures(
    const ProceduralTextureOptions& options = {});

}  // namespace sparseloop::synthetic
