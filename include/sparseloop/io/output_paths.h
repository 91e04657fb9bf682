#pragma once
// Output paths compared with input paths: no command writes over one of its inputs.
#include <filesystem>
#include <string>
#include <vector>

namespace sparseloop {

// `path` as the file system resolves it, without touching anything: absolute, symbolic links
// followed and `.` / `..` resolved; the part that does not exist yet is resolved lexically
// (`DIR/missing/..` is DIR, where `create_directories` followed by a write would put the files).
std::filesystem::path ResolvedPath(const std::filesystem::path& path);

// True when `a` and `b` name the same file or folder: the same inode when both exist (hard links,
// symbolic links), else the same ResolvedPath.
bool SamePath(const std::filesystem::path& a, const std::filesystem::path& b);

// A file a command reads or writes, with the name the user gave it (a flag such as "--gt", or a
// ROS parameter such as "~trajectory_file").
struct NamedPath {
  std::string name;
  std::filesystem::path path;
};

// Refuses, before any work, an output that is one of the inputs (SamePath): std::invalid_argument
// "--json g.txt: expected an output file other than the inputs, got the file of --gt g.txt
// (writing it would replace that input)". Entries with an empty path are skipped.
void CheckOutputsAreNotInputs(const std::vector<NamedPath>& outputs,
                              const std::vector<NamedPath>& inputs);

}  // namespace sparseloop
