#include "sparseloop/io/atomic_file.h"

#include <stdexcept>

#include <gtest/gtest.h>

#include "io/io_test_util.h"
#include "sparseloop/core/error.h"
#include "test_util.h"

namespace sparseloop {
namespace {

size_t CountEntries(const std::filesystem::path& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++n;
  return n;
}

TEST(AtomicFile, WritesAndOverwritesWithoutLeavingTemporaries) {
  const auto dir = test::TempDir();
  const auto path = dir / "out.txt";
  WriteFileAtomically(path, [](std::ostream& os) { os << "first\n"; });
  EXPECT_EQ(test::ReadText(path), "first\n");
  WriteFileAtomically(path, [](std::ostream& os) { os << "second"; });
  EXPECT_EQ(test::ReadText(path), "second");
  EXPECT_EQ(CountEntries(dir), 1u);
}

TEST(AtomicFile, WriterExceptionKeepsOldContentAndRemovesTemporary) {
  const auto dir = test::TempDir();
  const auto path = test::WriteText(dir / "out.txt", "old");
  EXPECT_THROW(WriteFileAtomically(path,
                                   [](std::ostream& os) {
                                     os << "partial";
                                     throw std::runtime_error("boom");
                                   }),
               std::runtime_error);
  EXPECT_EQ(test::ReadText(path), "old");
  EXPECT_EQ(CountEntries(dir), 1u);
}

TEST(AtomicFile, MissingDirectoryIsFileErrorNamingThePath) {
  const auto dir = test::TempDir();
  const auto path = dir / "no_such_dir" / "out.txt";
  try {
    WriteFileAtomically(path, [](std::ostream& os) { os << "x"; });
    FAIL() << "expected FileError";
  } catch (const FileError& e) {
    EXPECT_EQ(e.file(), path.string());
    EXPECT_EQ(e.line(), 0);
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "no_such_dir"));
}

TEST(AtomicFile, TargetThatIsADirectoryIsFileError) {
  const auto dir = test::TempDir();
  std::filesystem::create_directories(dir / "sub");
  EXPECT_THROW(WriteFileAtomically(dir / "sub", [](std::ostream& os) { os << "x"; }), FileError);
  EXPECT_TRUE(std::filesystem::is_directory(dir / "sub"));
  EXPECT_EQ(CountEntries(dir), 1u);
}

}  // namespace
}  // namespace sparseloop
