#include "sparseloop/io/loop_pairs.h"

#include <gtest/gtest.h>

#include "io/io_test_util.h"
#include "sparseloop/core/error.h"
#include "test_util.h"

namespace sparseloop {
namespace {

TEST(LoopPairs, ReadsPairsSkippingCommentsAndOrderingQueryLater) {
  const auto path =
      test::WriteText(test::TempDir() / "pairs.txt", "# header\n\n10 2\n  3 7\r\n# mid\n100\t99\n");
  const auto pairs = ReadLoopPairs(path);
  ASSERT_EQ(pairs.size(), 3u);
  EXPECT_EQ(pairs[0], (LoopPair{10, 2}));
  EXPECT_EQ(pairs[1], (LoopPair{7, 3}));  // written "3 7": the later frame becomes the query
  EXPECT_EQ(pairs[2], (LoopPair{100, 99}));
}

TEST(LoopPairs, ATrailingCommentEndsTheLine) {
  const auto path =
      test::WriteText(test::TempDir() / "pairs.txt", "10 2  # revisit of the start\n7 3\t#\n");
  const auto pairs = ReadLoopPairs(path);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[1], (LoopPair{7, 3}));
}

TEST(LoopPairs, CommentOnlyFileHasNoPairs) {
  const auto path = test::WriteText(test::TempDir() / "pairs.txt", "# no loops here\n");
  EXPECT_TRUE(ReadLoopPairs(path).empty());
}

TEST(LoopPairs, MalformedLinesNameFileAndLine) {
  struct Case {
    const char* content;
    int line;
    const char* expected;
  };
  const Case cases[] = {
      {"1 0\n2 1 5\n", 2, "2 columns"},   {"# c\n1 0\n\n4 x\n", 4, "integer"},
      {"1 0\n2.5 1\n", 2, "integer"},     {"-1 3\n", 1, "non-negative"},
      {"1 0\n3 3\n", 2, "two different"}, {"7\n", 1, "2 columns"},
  };
  const auto dir = test::TempDir();
  int k = 0;
  for (const auto& c : cases) {
    const auto path = test::WriteText(dir / ("case" + std::to_string(k++) + ".txt"), c.content);
    try {
      ReadLoopPairs(path);
      ADD_FAILURE() << "no FileError for: " << c.content;
    } catch (const FileError& e) {
      EXPECT_EQ(e.file(), path.string());
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_NE(std::string(e.what()).find(path.string() + ":" + std::to_string(c.line) + ":"),
                std::string::npos)
          << e.what();
      EXPECT_NE(e.expected().find(c.expected), std::string::npos) << e.what();
    }
  }
}

TEST(LoopPairs, IdsPastTheTrajectoryAreAFileErrorWithTheLine) {
  const auto path = test::WriteText(test::TempDir() / "pairs.txt", "# c\n9 0\n3 10\n");
  LoopPairReadOptions options;
  options.num_frames = 10;
  try {
    ReadLoopPairs(path, options);
    ADD_FAILURE() << "no FileError";
  } catch (const FileError& e) {
    EXPECT_EQ(e.line(), 3) << e.what();
    EXPECT_NE(e.expected().find("0..9"), std::string::npos) << e.what();
  }
  options.num_frames = 11;
  EXPECT_EQ(ReadLoopPairs(path, options).size(), 2u);
}

TEST(LoopPairs, MissingFileIsFileError) {
  EXPECT_THROW(ReadLoopPairs(test::TempDir() / "none.txt"), FileError);
}

TEST(LoopPairs, RealKittiLoopGroundTruth) {
  SL_REQUIRE_DATA("kitti_loop_gt");
  const auto pairs = ReadLoopPairs(test::DataDir() / "kitti_loop_gt/z014xw_kitti00GroundTruth.txt");
  ASSERT_FALSE(pairs.empty());
  EXPECT_EQ(pairs.front(), (LoopPair{1557, 110}));  // first data line of the file
  for (const auto& p : pairs) {
    EXPECT_GT(p.query, p.match);
    EXPECT_LT(p.query, 4541);  // KITTI 00 has 4541 frames
  }
}

}  // namespace
}  // namespace sparseloop
