// sparseloop convert: read a trajectory in any supported format, write it in another.
// Parses arguments, calls io, prints a one-line summary. Malformed input exits 2 with file:line.
#include <iostream>
#include <string>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "sparseloop/core/check.h"
#include "sparseloop/io/trajectory_io.h"

namespace sparseloop::cli {

int RunConvert(int argc, char** argv) {
  CLI::App app{"Convert a trajectory between TUM, KITTI, EuRoC CSV and positions formats"};
  std::string in;
  std::string out;
  std::string from = "auto";
  std::string to;
  TrajectoryReadOptions read_options;
  app.add_option("--in", in, "input trajectory file")->required();
  app.add_option("--out", out, "output file (written atomically)")->required();
  app.add_option("--to", to, "output format: tum, kitti, euroc, positions")->required();
  app.add_option("--from", from, "input format: auto (default), tum, kitti, euroc, positions");
  app.add_flag("--drop-duplicates", read_options.drop_duplicate_timestamps,
               "keep the first of repeated timestamps / frame indices instead of failing");
  Parse(app, argc, argv);
  CheckOutputsAreNotInputs({{"--out", out}}, {{"--in", in}});
  CheckOutputFileFlag("--out", out);

  const TrajectoryFormat in_format = ParseTrajectoryFormat(from);
  const TrajectoryFormat out_format = ParseTrajectoryFormat(to);
  SL_CHECK_MSG(out_format != TrajectoryFormat::kAuto, "--to needs an explicit format, not 'auto'");
  // One read (detection included): --in may be a pipe or /dev/stdin.
  const TrajectoryFile read = ReadTrajectoryFile(in, in_format, read_options);
  WriteTrajectory(out, read.trajectory, out_format);
  std::cout << fmt::format("wrote {} poses ({} -> {}) to {}\n", read.trajectory.size(),
                           ToString(read.format), ToString(out_format), out);
  return 0;
}

SPARSELOOP_REGISTER_COMMAND("convert", "convert a trajectory file between formats", RunConvert);

}  // namespace sparseloop::cli
