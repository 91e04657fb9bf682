// sparseloop config --dump [detect|run] [--preset NAME]: the default (or a preset's) --config JSON,
// every key with a one-line doc.
#include <iostream>

#include <CLI/CLI.hpp>

#include "cli/cli_util.h"
#include "cli/command.h"
#include "sparseloop/pipeline/config.h"

namespace sparseloop::cli {

int RunConfig(int argc, char** argv) {
  CLI::App app{
      "Print the default --config JSON of a command; \"doc\" holds one line per key "
      "(--config reads the output back unchanged; docs/FORMATS.md, Configuration)"};
  bool dump = false;
  std::string command = "run";
  app.add_flag("--dump", dump, "print the defaults and the doc of every key")->required();
  app.add_option("command", command, "detect (the detector keys) | run (every key)")
      ->check(CLI::IsMember({"detect", "run"}))
      ->default_str("run");
  std::string preset;
  app.add_option("--preset", preset, "the values of a shipped preset instead of the defaults")
      ->check(CLI::IsMember(PresetNames()));
  Parse(app, argc, argv);
  PipelineOptions options;
  if (!preset.empty()) ApplyPreset(preset, &options);
  // `detect` reads the "detector" object of --config, `run` every key.
  std::cout << JsonText(DumpConfig(options, command == "detect" ? "detector" : ""));
  return 0;
}

SPARSELOOP_REGISTER_COMMAND("config", "print the default configuration (--config JSON)", RunConfig);

}  // namespace sparseloop::cli
