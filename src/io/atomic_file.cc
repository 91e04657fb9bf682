#include "sparseloop/io/atomic_file.h"
#include "sparseloop/io/output_paths.h"

#include <limits.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <system_error>

#include <fmt/format.h>

#include "sparseloop/core/error.h"

namespace sparseloop {

namespace fs = std::filesystem;

namespace {

// "a directory", "a FIFO", ... for anything that is not a regular file; empty otherwise.
std::string NotRegularKind(fs::file_type type) {
  switch (type) {
    case fs::file_type::directory:
      return "a directory";
    case fs::file_type::fifo:
      return "a FIFO (named pipe)";
    case fs::file_type::socket:
      return "a socket";
    case fs::file_type::character:
      return "a character device";
    case fs::file_type::block:
      return "a block device";
    case fs::file_type::regular:
    case fs::file_type::not_found:
      return {};
    default:
      return "not a regular file";
  }
}

// A directory we can create files in, or the reason why not (empty when fine).
std::string DirectoryProblem(const fs::path& dir) {
  std::error_code ec;
  const fs::file_status status = fs::status(dir, ec);
  if (status.type() == fs::file_type::not_found) return dir.string() + " is missing";
  if (status.type() != fs::file_type::directory) return dir.string() + " is not a directory";
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    return fmt::format("{} is not writable: {}", dir.string(), std::strerror(errno));
  }
  return {};
}

// /dev/stdout, /dev/fd/N, /proc/self/fd/N: links to a process's open files. Renaming over their
// target would replace the file behind the descriptor (or fail for a pipe), so they are refused.
bool InProcFileSystem(const fs::path& path) {
  std::error_code ec;
  const fs::path dir =
      fs::weakly_canonical(path.has_parent_path() ? path.parent_path() : fs::path("."), ec);
  const auto first = dir.begin() == dir.end() ? dir.end() : std::next(dir.begin());
  return !ec && first != dir.end() && *first == "proc";
}

// The longest suffix WriteFileAtomically adds to a file name: ".tmp.<pid>" (pid < 2^22).
constexpr size_t kTemporarySuffix = 12;

// Why the file system would refuse `path` for its length (empty when it fits): a name longer than
// NAME_MAX bytes or a whole path longer than PATH_MAX, counting `extra` bytes added to the last
// name (the temporary's suffix).
std::string LengthProblem(const fs::path& path, size_t extra) {
  std::error_code ec;
  const fs::path abs = fs::absolute(path, ec).lexically_normal();
  if (abs.native().size() + extra >= PATH_MAX) {
    return fmt::format("a path of {} characters (at most {} fit)", abs.native().size(),
                       PATH_MAX - 1 - extra);
  }
  size_t i = 0;
  const size_t parts = static_cast<size_t>(std::distance(abs.begin(), abs.end()));
  for (const fs::path& part : abs) {
    const size_t limit = NAME_MAX - (++i == parts ? extra : 0);
    if (part.native().size() > limit) {
      return fmt::format("a name of {} characters ('{}...'; at most {} fit)", part.native().size(),
                         part.native().substr(0, 20), limit);
    }
  }
  return {};
}

}  // namespace

fs::path ResolvedPath(const fs::path& path) {
  std::error_code ec;
  const fs::path abs = fs::absolute(path, ec).lexically_normal();
  fs::path resolved = fs::weakly_canonical(abs, ec);
  return ec ? abs : resolved;
}

bool SamePath(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec) && !ec;
  return ResolvedPath(a) == ResolvedPath(b);
}

void CheckOutputsAreNotInputs(const std::vector<NamedPath>& outputs,
                              const std::vector<NamedPath>& inputs) {
  for (const NamedPath& out : outputs) {
    if (out.path.empty()) continue;
    for (const NamedPath& in : inputs) {
      if (in.path.empty() || !SamePath(out.path, in.path)) continue;
      throw std::invalid_argument(fmt::format(
          "{} {}: expected an output file other than the inputs, got the file of {} {} (writing "
          "it would replace that input)",
          out.name, out.path.string(), in.name, in.path.string()));
    }
  }
}

fs::path CheckOutputFile(const fs::path& path) {
  const std::string name = path.string();
  if (path.empty() || !path.has_filename()) {
    throw FileError(name, 0, "a file path with a file name", "'" + name + "'");
  }
  if (const std::string problem = LengthProblem(path, kTemporarySuffix); !problem.empty()) {
    throw FileError(name, 0, "a path the file system accepts", problem);
  }
  // Follow symbolic links to the file that will be replaced; the links stay as they are.
  fs::path target = path;
  std::error_code ec;
  for (int hops = 0; fs::is_symlink(fs::symlink_status(target, ec)); ++hops) {
    if (hops == 40) throw FileError(name, 0, "a symbolic link that ends", "a loop of links");
    if (InProcFileSystem(target)) {
      throw FileError(name, 0, "a regular file or a new file name",
                      "a link to an open file descriptor (" + target.string() + ")");
    }
    const fs::path link = fs::read_symlink(target, ec);
    if (ec) throw FileError(name, 0, "a readable symbolic link", ec.message());
    target = (link.is_absolute() ? link : target.parent_path() / link).lexically_normal();
  }
  const std::string via = target == path ? std::string() : " (the target of the link)";
  if (const std::string kind = NotRegularKind(fs::status(target, ec).type()); !kind.empty()) {
    throw FileError(name, 0, "a regular file or a new file name",
                    target == path ? kind : target.string() + via + " is " + kind);
  }
  const fs::path parent = target.has_parent_path() ? target.parent_path() : fs::path(".");
  if (const std::string problem = DirectoryProblem(parent); !problem.empty()) {
    throw FileError(name, 0, "an existing, writable output directory", problem);
  }
  return target;
}

void CheckOutputDirectory(const fs::path& dir, const std::vector<std::string>& file_names) {
  const std::string name = dir.string();
  if (dir.empty()) throw FileError(name, 0, "an output directory", "an empty path");
  for (const std::string& file : file_names) {
    if (const std::string problem = LengthProblem(dir / file, kTemporarySuffix); !problem.empty()) {
      throw FileError(name, 0, "a path the file system accepts", problem + " for " + file);
    }
  }
  if (const std::string problem = LengthProblem(dir, 0); !problem.empty()) {
    throw FileError(name, 0, "a path the file system accepts", problem);
  }
  // `DIR/missing/..` is DIR: checked (and later written) as the file system will resolve it.
  const fs::path resolved = ResolvedPath(dir);
  std::error_code ec;
  if (fs::exists(resolved, ec)) {
    if (const std::string problem = DirectoryProblem(resolved); !problem.empty()) {
      throw FileError(name, 0, "a writable output directory", problem);
    }
    for (const auto& file : file_names) CheckOutputFile(resolved / file);
    return;
  }
  // A new directory: its nearest existing parent must be a writable directory.
  fs::path parent = resolved;
  while (parent.has_relative_path() && !fs::exists(parent, ec)) parent = parent.parent_path();
  if (const std::string problem = DirectoryProblem(parent); !problem.empty()) {
    throw FileError(name, 0, "an output directory that can be created", problem);
  }
}

void WriteFileAtomically(const fs::path& path, const std::function<void(std::ostream&)>& writer) {
  const std::string name = path.string();
  const fs::path target = CheckOutputFile(path);
  const fs::path tmp =
      fs::path(target.string() + fmt::format(".tmp.{}", static_cast<long>(::getpid())));
  auto remove_tmp = [&tmp] {
    std::error_code ignored;
    fs::remove(tmp, ignored);
  };
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) {
      throw FileError(name, 0, "a writable file",
                      fmt::format("cannot create {}: {}", tmp.string(), std::strerror(errno)));
    }
    errno = 0;
    try {
      writer(out);
    } catch (...) {
      out.close();
      remove_tmp();
      throw;
    }
    out.flush();
    const bool good = out.good();
    out.close();
    // errno holds the failed write's reason ("No space left on device", a quota, an I/O error).
    const int error = errno;
    if (!good || out.fail()) {
      remove_tmp();
      throw FileError(name, 0, "a complete write",
                      fmt::format("writing {} failed: {}", tmp.string(),
                                  error != 0 ? std::strerror(error) : "stream error"));
    }
  }
  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (ec) {
    remove_tmp();
    throw FileError(name, 0, "a successful rename from " + tmp.string(), ec.message());
  }
}

}  // namespace sparseloop
