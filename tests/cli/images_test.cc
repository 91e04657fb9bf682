// Bad images in a dataset folder (docs/ROBUSTNESS.md): refused by name, exit 2, before any frame
// is processed, instead of a raw OpenCV assertion that names no file.
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli/cli_runner.h"
#include "io/io_test_util.h"
#include "test_util.h"

namespace sparseloop::test {
namespace {

namespace fs = std::filesystem;

// A folder of three 64x48 noise images, the raw poses for them, and an output folder.
struct Folder {
  fs::path images, poses, out;
};
Folder MakeFolder() {
  const auto dir = TempDir();
  Folder f{dir / "images", dir / "raw.txt", dir / "out"};
  fs::create_directories(f.images);
  cv::Mat image(48, 64, CV_8UC1);
  cv::RNG rng(3);
  std::ofstream poses(f.poses);
  for (int i = 0; i < 3; ++i) {
    rng.fill(image, cv::RNG::UNIFORM, 0, 256);
    cv::imwrite((f.images / (std::to_string(i) + ".png")).string(), image);
    poses << i << " " << i << " 0 0 0 0 0 1\n";
  }
  return f;
}

CliResult Detect(const Folder& f, const std::string& intrinsics = "50,50,32,24") {
  return RunCli({"detect", "--dataset", "images:" + f.images.string(), "--intrinsics", intrinsics,
                 "--out", f.out.string()});
}

void ExpectNamed(const CliResult& r, const std::string& what) {
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("OpenCV"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(".cc:"), std::string::npos) << r.err;  // no source path
}

TEST(CliImages, TinyImageAndHugePngHeaderExit2NamingTheFile) {
  const Folder f = MakeFolder();
  ASSERT_EQ(Detect(f).exit_code, 0);
  const auto tiny = f.images / "3.png";
  cv::imwrite(tiny.string(), cv::Mat(1, 1, CV_8UC1, cv::Scalar(0)));
  ExpectNamed(Detect(f), tiny.string() + ": expected an image of at least 32x32 pixels");
  WritePngHeader(tiny, 100000, 100000);
  ExpectNamed(Detect(f), tiny.string() + ": expected an image of at most");
  // run: the same, before the first frame.
  ExpectNamed(RunCli({"run", "--dataset", "images:" + f.images.string(), "--intrinsics",
                      "50,50,32,24", "--poses", f.poses.string(), "--out", f.out.string()}),
              tiny.string());
}

TEST(CliImages, MixedSizesAndPrincipalPointOutsideNameTheFileOrFlag) {
  const Folder f = MakeFolder();
  ExpectNamed(Detect(f, "50,50,500,24"), "--intrinsics: principal point (500, 24) outside");
  cv::imwrite((f.images / "3.png").string(), cv::Mat(60, 80, CV_8UC1, cv::Scalar(0)));
  ExpectNamed(Detect(f), (f.images / "3.png").string() + ": expected every image of the sequence");
}

TEST(CliImages, TruncatedJpegExit2NamingTheFile) {
  const Folder f = MakeFolder();
  std::vector<uchar> bytes;
  ASSERT_TRUE(cv::imencode(".jpg", cv::imread((f.images / "0.png").string()), bytes));
  const auto cut = f.images / "3.jpg";
  std::ofstream(cut, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), bytes.size() - 40);
  ExpectNamed(Detect(f), cut.string() + ": expected a complete JPEG file");
}

}  // namespace
}  // namespace sparseloop::test
