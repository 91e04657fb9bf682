#include "sparseloop/io/step_covariance.h"

#include <gtest/gtest.h>

#include "io/io_test_util.h"
#include "sparseloop/core/error.h"
#include "test_util.h"

namespace sparseloop {
namespace {

// The upper-triangle (21) and full (36) forms of one covariance read to the same matrix.
TEST(StepCovariance, UpperTriangleAndFullMatrixReadTheSame) {
  Eigen::Matrix<double, 6, 6> c;
  c << 4, 1, 0, 0, 0, 0.5,  //
      1, 3, 0, 0, 0, 0,     //
      0, 0, 2, 0.1, 0, 0,   //
      0, 0, 0.1, 1, 0, 0,   //
      0, 0, 0, 0, 1, 0,     //
      0.5, 0, 0, 0, 0, 2;
  std::string upper = "10.5", full = "11.5";
  for (int r = 0; r < 6; ++r) {
    for (int k = 0; k < 6; ++k) {
      full += " " + std::to_string(c(r, k));
      if (k >= r) upper += " " + std::to_string(c(r, k));
    }
  }
  const auto path =
      test::WriteText(test::TempDir() / "cov.txt", "# key c...\n\n" + upper + "\n" + full + "\r\n");
  const auto read = ReadStepCovariances(path);
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[0].key, 10.5);
  EXPECT_EQ(read[1].key, 11.5);
  EXPECT_EQ(read[0].covariance, c);
  EXPECT_EQ(read[1].covariance, c);
}

TEST(StepCovariance, MalformedLinesNameFileAndLine) {
  const std::string id21 = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1";
  std::string asym36;
  for (int r = 0; r < 6; ++r) {
    for (int k = 0; k < 6; ++k) asym36 += r == k ? " 1" : (r == 0 && k == 1 ? " 0.5" : " 0");
  }
  struct Case {
    std::string content;
    int line;
    const char* expected;
  };
  const Case cases[] = {
      {"0" + id21 + "\n1 1 0\n", 2, "22 columns"},
      {"0" + id21 + "\nx" + id21 + "\n", 2, "key"},
      {"0" + id21 + "\n0" + id21 + "\n", 2, "above the previous"},
      {"# c\n3" + id21.substr(0, id21.size() - 2) + " nan\n", 2, "finite"},
      {"0" + asym36 + "\n", 1, "symmetric"},
      {"0 -1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n", 1, "positive definite"},
      {"0 1 2 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n", 1, "positive definite"},
      // Variances of 1e-30 (or 1e-308): an information the solver cannot use (it aborted).
      {"0 1e-30 0 0 0 0 0 1e-30 0 0 0 0 1e-30 0 0 0 1e-30 0 0 1e-30 0 1e-30\n", 1,
       "eigenvalues of at least 1e-18"},
      {"0 1e-308 0 0 0 0 0 1e-308 0 0 0 0 1e-308 0 0 0 1e-308 0 0 1e-308 0 1e-308\n", 1,
       "eigenvalues of at least 1e-18"},
  };
  const auto dir = test::TempDir();
  int k = 0;
  for (const auto& c : cases) {
    const auto path = test::WriteText(dir / ("case" + std::to_string(k++) + ".txt"), c.content);
    try {
      ReadStepCovariances(path);
      ADD_FAILURE() << "no FileError for: " << c.content;
    } catch (const FileError& e) {
      EXPECT_EQ(e.file(), path.string());
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_NE(e.expected().find(c.expected), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(ReadStepCovariances(dir / "missing.txt"), FileError);
}

}  // namespace
}  // namespace sparseloop
