#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/output_paths.h"

#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
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

// A write the file system refuses part-way (a full disk, a quota) is a FileError with the system's
// reason (it said "stream error"), and the old file stays. A full file system needs root to make;
// the file-size limit (RLIMIT_FSIZE, SIGXFSZ ignored) fails the same write() the same way, EFBIG.
TEST(AtomicFile, AWriteTheSystemRefusesNamesItsReasonAndKeepsTheOldFile) {
  const auto dir = test::TempDir();
  const auto path = test::WriteText(dir / "out.txt", "old");
  rlimit before{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &before), 0);
  rlimit limited = before;
  limited.rlim_cur = 4096;
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limited), 0);
  std::string message;
  try {
    WriteFileAtomically(path, [](std::ostream& os) { os << std::string(1 << 20, 'x'); });
  } catch (const FileError& e) {
    message = e.what();
  }
  ::setrlimit(RLIMIT_FSIZE, &before);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_NE(message.find(std::strerror(EFBIG)), std::string::npos) << message;
  EXPECT_NE(message.find("out.txt"), std::string::npos) << message;
  EXPECT_EQ(message.find("stream error"), std::string::npos) << message;
  EXPECT_EQ(test::ReadText(path), "old");
  EXPECT_EQ(CountEntries(dir), 1u);  // the temporary is gone
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

// Outputs are regular files only: a FIFO, a socket or a directory given as the output path is
// refused with a FileError naming the path, and is still there, untouched, afterwards.
void ExpectRefused(const std::filesystem::path& path, const std::string& kind) {
  try {
    WriteFileAtomically(path, [](std::ostream& os) { os << "x"; });
    ADD_FAILURE() << "wrote over " << kind << " " << path;
  } catch (const FileError& e) {
    EXPECT_EQ(e.file(), path.string());
    EXPECT_NE(std::string(e.what()).find(kind), std::string::npos) << e.what();
  }
  EXPECT_THROW(CheckOutputFile(path), FileError);
}

TEST(AtomicFile, FifoSocketAndDirectoryAreRefusedAndKept) {
  const auto dir = test::TempDir();
  const auto fifo = dir / "out.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
  ExpectRefused(fifo, "FIFO");
  EXPECT_TRUE(std::filesystem::is_fifo(fifo));

  const auto sock_path = dir / "out.sock";
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  ASSERT_LT(sock_path.string().size(), sizeof(addr.sun_path));
  std::strcpy(addr.sun_path, sock_path.c_str());
  ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)), 0);
  ExpectRefused(sock_path, "socket");
  EXPECT_TRUE(std::filesystem::is_socket(sock_path));
  ::close(fd);

  std::filesystem::create_directories(dir / "sub");
  ExpectRefused(dir / "sub", "directory");
  EXPECT_EQ(CountEntries(dir), 3u);  // no temporaries left
}

TEST(AtomicFile, SymlinkIsWrittenThroughToItsTarget) {
  const auto dir = test::TempDir();
  std::filesystem::create_directories(dir / "real");
  const auto target = test::WriteText(dir / "real" / "out.txt", "old");
  std::filesystem::create_symlink("real/out.txt", dir / "link.txt");     // relative link
  std::filesystem::create_symlink(dir / "link.txt", dir / "link2.txt");  // link to a link
  EXPECT_EQ(CheckOutputFile(dir / "link2.txt"), target);
  WriteFileAtomically(dir / "link2.txt", [](std::ostream& os) { os << "new"; });
  EXPECT_TRUE(std::filesystem::is_symlink(dir / "link.txt"));
  EXPECT_TRUE(std::filesystem::is_symlink(dir / "link2.txt"));
  EXPECT_EQ(test::ReadText(target), "new");
  EXPECT_EQ(CountEntries(dir / "real"), 1u);

  // A dangling link creates its target; a link to a FIFO is refused like the FIFO.
  std::filesystem::create_symlink("real/created.txt", dir / "dangling.txt");
  WriteFileAtomically(dir / "dangling.txt", [](std::ostream& os) { os << "made"; });
  EXPECT_TRUE(std::filesystem::is_symlink(dir / "dangling.txt"));
  EXPECT_EQ(test::ReadText(dir / "real" / "created.txt"), "made");
  ASSERT_EQ(::mkfifo((dir / "real" / "pipe").c_str(), 0600), 0);
  std::filesystem::create_symlink("real/pipe", dir / "to_pipe");
  ExpectRefused(dir / "to_pipe", "FIFO");
  EXPECT_TRUE(std::filesystem::is_fifo(dir / "real" / "pipe"));

  // Links to a process's open files are refused: renaming over their target would replace the
  // file behind the descriptor (the shell's redirection target) or fail for a pipe.
  for (const char* path : {"/dev/stdout", "/dev/fd/1", "/proc/self/fd/2"}) {
    if (!std::filesystem::is_symlink(std::filesystem::symlink_status(path))) continue;
    try {
      CheckOutputFile(path);
      ADD_FAILURE() << "accepted " << path;
    } catch (const FileError& e) {
      EXPECT_NE(std::string(e.what()).find("open file descriptor"), std::string::npos) << e.what();
    }
  }

  // A loop of links is an error, not a hang.
  std::filesystem::create_symlink("loop_b", dir / "loop_a");
  std::filesystem::create_symlink("loop_a", dir / "loop_b");
  EXPECT_THROW(CheckOutputFile(dir / "loop_a"), FileError);
}

TEST(AtomicFile, CheckOutputDirectory) {
  const auto dir = test::TempDir();
  EXPECT_NO_THROW(CheckOutputDirectory(dir, {"a.txt"}));
  EXPECT_NO_THROW(CheckOutputDirectory(dir / "new" / "deeper"));  // created later
  EXPECT_FALSE(std::filesystem::exists(dir / "new"));
  const auto file = test::WriteText(dir / "file.txt", "x");
  EXPECT_THROW(CheckOutputDirectory(file), FileError);
  EXPECT_THROW(CheckOutputDirectory(file / "sub"), FileError);
  ASSERT_EQ(::mkfifo((dir / "loops.csv").c_str(), 0600), 0);
  try {
    CheckOutputDirectory(dir, {"summary.json", "loops.csv"});
    ADD_FAILURE() << "accepted a FIFO inside the output directory";
  } catch (const FileError& e) {
    EXPECT_EQ(e.file(), (dir / "loops.csv").string());
  }
}

// `DIR/missing/..` is DIR (where create_directories + a write put the files): the folder checked
// is the one written to; links and `..` are resolved before paths are compared.
TEST(AtomicFile, ResolvedPathAndSamePathSeeThroughLinksAndDotDot) {
  namespace fs = std::filesystem;
  const auto dir = fs::weakly_canonical(test::TempDir());
  EXPECT_EQ(ResolvedPath(dir / "missing" / ".."), dir);
  EXPECT_EQ(ResolvedPath(dir / "a" / "b" / ".." / "c.txt"), dir / "a" / "c.txt");
  const auto gt = test::WriteText(dir / "gt.txt", "x");
  fs::create_symlink(gt, dir / "link.txt");
  ASSERT_EQ(::link(gt.c_str(), (dir / "hard.txt").c_str()), 0);
  EXPECT_TRUE(SamePath(gt, dir / "link.txt"));
  EXPECT_TRUE(SamePath(gt, dir / "hard.txt"));
  EXPECT_TRUE(SamePath(gt, dir / "missing" / ".." / "gt.txt"));
  EXPECT_TRUE(SamePath(dir / "new.txt", dir / "." / "new.txt"));
  EXPECT_FALSE(SamePath(gt, dir / "other.txt"));
}

// An output that is an input is refused before anything is written, naming both; empty paths are
// not compared.
TEST(AtomicFile, AnOutputThatIsAnInputIsRefusedNamingBoth) {
  namespace fs = std::filesystem;
  const auto dir = test::TempDir();
  const auto gt = test::WriteText(dir / "g.txt", "keep");
  fs::create_symlink(gt, dir / "via_link.json");
  for (const fs::path& out : {gt, dir / "via_link.json", dir / "sub" / ".." / "g.txt"}) {
    SCOPED_TRACE(out.string());
    try {
      CheckOutputsAreNotInputs({{"--json", out}}, {{"--est", dir / "e.txt"}, {"--gt", gt}});
      ADD_FAILURE() << "accepted an output that is an input";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("--json " + out.string()), std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("--gt " + gt.string()), std::string::npos) << e.what();
    }
  }
  EXPECT_NO_THROW(CheckOutputsAreNotInputs({{"--json", dir / "m.json"}, {"--out", ""}},
                                           {{"--gt", gt}, {"--loops", ""}}));
  EXPECT_EQ(test::ReadText(gt), "keep");
}

// A path longer than the file system takes is refused when checked, not after the work
// ("File name too long"): a name over NAME_MAX, a path over PATH_MAX, the temporary's suffix
// included.
TEST(AtomicFile, OverlongPathsAreRefusedWhenChecked) {
  const auto dir = test::TempDir();
  const std::string long_name(250, 'n');  // fits, but not with ".tmp.<pid>"
  EXPECT_THROW(CheckOutputFile(dir / long_name), FileError);
  EXPECT_NO_THROW(CheckOutputFile(dir / std::string(200, 'n')));
  std::filesystem::path deep = dir;
  for (int i = 0; i < 22; ++i) deep /= std::string(200, 'd');  // 4,400 characters
  try {
    CheckOutputDirectory(deep, {"trajectory.txt"});
    ADD_FAILURE() << "accepted a 4,400-character folder";
  } catch (const FileError& e) {
    EXPECT_EQ(e.file(), deep.string());
    EXPECT_NE(e.got().find("characters"), std::string::npos) << e.what();
  }
  EXPECT_THROW(CheckOutputDirectory(dir / std::string(300, 'x')), FileError);
}

}  // namespace
}  // namespace sparseloop
