#include "sparseloop/io/mapped_pixels.h"

#include <string>

#include <gtest/gtest.h>

#include "io/io_test_util.h"
#include "sparseloop/core/error.h"
#include "test_util.h"

namespace sparseloop {
namespace {

// Text as people write it: a BOM, comments, blank lines, CR-only and CRLF line ends all read as a
// plain "\n" file does (the reader used to take a BOM for part of the first number and a CR-only
// file for one line).
TEST(MappedPixelRows, ReadsAnyLineEndAndABom) {
  const auto dir = test::TempDir();
  const std::string plain = "# u v depth\n10.5 20 3.25\n\n11 21 -1\n";
  const auto expect_plain = [](const std::vector<MappedPixelRow>& rows) {
    ASSERT_EQ(rows.size(), 2u);
    EXPECT_FLOAT_EQ(rows[0].u, 10.5f);
    EXPECT_FLOAT_EQ(rows[0].v, 20.0f);
    EXPECT_FLOAT_EQ(rows[0].depth, 3.25f);
    EXPECT_FLOAT_EQ(rows[1].depth, -1.0f);
  };
  expect_plain(ReadMappedPixelRows(test::WriteText(dir / "plain.txt", plain)));
  expect_plain(ReadMappedPixelRows(
      test::WriteText(dir / "bom_cr.txt", "\xEF\xBB\xBF# u v depth\r10.5 20 3.25\r\r11 21 -1\r")));
  expect_plain(
      ReadMappedPixelRows(test::WriteText(dir / "crlf.txt", "10.5\t20 3.25\r\n11 21 -1\r\n")));
}

TEST(MappedPixelRows, NamesTheLineOfAMalformedRow) {
  const auto dir = test::TempDir();
  const auto expect_error = [&](const std::string& text, int line, const std::string& says) {
    try {
      ReadMappedPixelRows(test::WriteText(dir / "bad.txt", text));
      ADD_FAILURE() << "no error for " << text;
    } catch (const FileError& e) {
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad.txt"), std::string::npos) << e.what();
    }
  };
  expect_error("1 2 3\n4 5\n", 2, "3 numbers 'u v depth'");
  expect_error("1 2 3 4\n", 1, "4 columns");
  expect_error("# c\n1 2 nan\n", 2, "depth");
  expect_error("1 x 3\n", 1, "for v");
  // Finite as a double, inf as a float: the run failed later on "mapped_depths[0] ... got inf"
  // without the file or the line.
  expect_error("1 2 3\n1 2 1e39\n", 2,
               "expected a depth within float range (|x| <= 3.40282e+38), got 1e39");
  expect_error("1 2 3\n1 2 1e308\n", 2, "depth within float range");
  expect_error("-1e300 2 3\n", 1, "u within float range");
  EXPECT_FLOAT_EQ(ReadMappedPixelRows(test::WriteText(dir / "big.txt", "1 2 3e38\n"))[0].depth,
                  3e38f);
  EXPECT_THROW(ReadMappedPixelRows(dir / "missing.txt"), FileError);
}

}  // namespace
}  // namespace sparseloop
