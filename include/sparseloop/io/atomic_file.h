#pragma once
// Atomic file output: a reader never sees a half-written file.
#include <filesystem>
#include <functional>
#include <ostream>

namespace sparseloop {

// Calls `writer` on a stream to "<path>.tmp.<pid>" in the same directory, flushes and closes it,
// then renames it over `path` (atomic on POSIX file systems). On any failure (directory missing or
// not writable, stream error, rename failure) the temporary file is removed and FileError(path, 0,
// ...) is thrown; an exception thrown by `writer` also removes the temporary and is rethrown as is.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& writer);

}  // namespace sparseloop
