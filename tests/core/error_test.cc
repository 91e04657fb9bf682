#include <gtest/gtest.h>

#include "sparseloop/core/check.h"
#include "sparseloop/core/error.h"

namespace sparseloop {
namespace {

TEST(Error, FileErrorNamesFileLineAndExpectation) {
  const FileError e("traj.txt", 12, "8 columns", "7");
  EXPECT_STREQ(e.what(), "traj.txt:12: expected 8 columns, got 7");
  EXPECT_EQ(e.line(), 12);
  const FileError whole("missing.txt", 0, "an existing file");
  EXPECT_STREQ(whole.what(), "missing.txt: expected an existing file");
}

TEST(Error, CheckThrowsInvalidArgumentWithMessage) {
  try {
    const int k = -3;
    SL_CHECK_MSG(k > 0, "K must be positive, got {}", k);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("K must be positive, got -3"), std::string::npos);
  }
  EXPECT_NO_THROW(SL_CHECK(1 + 1 == 2));
}

// Users read the message only; the expression and the location stay available to developers.
TEST(Error, CheckMessageIsReadableAndKeepsTheLocationForDevelopers) {
  try {
    const double loss_scale = -1;
    SL_CHECK_MSG(loss_scale > 0, "loss_scale must be > 0, got {}", loss_scale);
    FAIL() << "no throw";
  } catch (const CheckError& e) {
    EXPECT_STREQ(e.what(), "loss_scale must be > 0, got -1");
    EXPECT_STREQ(e.condition(), "loss_scale > 0");
    EXPECT_NE(std::string(e.file()).find("error_test.cc"), std::string::npos);
    EXPECT_GT(e.line(), 0);
  }
  try {
    SL_CHECK(2 + 2 == 5);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "check failed: 2 + 2 == 5");  // no source path
  }
}

}  // namespace
}  // namespace sparseloop
