#include "sparseloop/io/atomic_file.h"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include <fmt/format.h>

#include "sparseloop/core/error.h"

namespace sparseloop {

void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& writer) {
  namespace fs = std::filesystem;
  const std::string name = path.string();
  if (path.empty() || !path.has_filename()) {
    throw FileError(name, 0, "a file path with a file name", "'" + name + "'");
  }
  const fs::path parent = path.has_parent_path() ? path.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(parent, ec)) {
    throw FileError(name, 0, "an existing output directory", parent.string() + " is missing");
  }
  if (fs::is_directory(path, ec)) throw FileError(name, 0, "a file path", "a directory");
  const fs::path tmp = fs::path(name + fmt::format(".tmp.{}", static_cast<long>(::getpid())));
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
    if (!good || out.fail()) {
      remove_tmp();
      throw FileError(name, 0, "a complete write", "stream error while writing " + tmp.string());
    }
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    remove_tmp();
    throw FileError(name, 0, "a successful rename from " + tmp.string(), ec.message());
  }
}

}  // namespace sparseloop
