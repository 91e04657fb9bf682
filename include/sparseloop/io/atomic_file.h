#pragma once
// Atomic file output: a reader never sees a half-written file. Outputs are regular files only.
#include <filesystem>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

namespace sparseloop {

// Checks, without writing anything, that WriteFileAtomically(path, ...) can write `path`, and
// returns the file it will replace: `path` itself, or, when `path` is a symbolic link (a chain of
// links is followed), the link's final target (the link itself is never replaced). Throws
// FileError(path, 0, ...) when the path (or the target) is a directory, FIFO, socket or device, a
// link to an open file descriptor (/dev/stdout, /dev/fd/N, /proc/self/fd/N), in a missing or
// unwritable directory, a loop of links, or longer than NAME_MAX / PATH_MAX (with ".tmp.<pid>").
std::filesystem::path CheckOutputFile(const std::filesystem::path& path);

// Checks, without creating anything, that `dir` can hold output files: an existing writable
// directory, or a new path whose nearest existing parent is a writable directory, as ResolvedPath
// gives it (output_paths.h). Each of `file_names` must fit NAME_MAX / PATH_MAX inside it and, when
// `dir` exists, pass CheckOutputFile. FileError naming the directory or the file otherwise.
void CheckOutputDirectory(const std::filesystem::path& dir,
                          const std::vector<std::string>& file_names = {});

// Calls `writer` on a stream to "<target>.tmp.<pid>" in the target's directory, flushes and
// closes it, then renames it over the target (atomic on POSIX file systems). The target is the
// one CheckOutputFile returns (a symlink is written through to its target). On any failure (path
// not a regular file, directory missing or not writable, stream error, rename failure) the
// temporary file is removed and FileError(path, 0, ...) is thrown; an exception thrown by
// `writer` also removes the temporary and is rethrown as is.
void WriteFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& writer);

}  // namespace sparseloop
