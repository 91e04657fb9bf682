#include <algorithm>
#include <cstdio>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "cli/command.h"
#include "sparseloop/core/error.h"

namespace sparseloop::cli {

std::vector<Command>& Registry() {
  static std::vector<Command> commands;
  return commands;
}

Registrar::Registrar(std::string name, std::string help, CommandFn run) {
  Registry().push_back({std::move(name), std::move(help), std::move(run)});
}

namespace {
void PrintUsage() {
  auto commands = Registry();
  std::sort(commands.begin(), commands.end(),
            [](const Command& a, const Command& b) { return a.name < b.name; });
  std::cout << "sparseloop: loop closure for monocular visual SLAM\n\n"
               "Usage: sparseloop <command> [options]   (sparseloop <command> --help)\n"
               "       sparseloop --version\n\n"
               "Commands:\n";
  for (const auto& c : commands) std::printf("  %-10s %s\n", c.name.c_str(), c.help.c_str());
}

// "sparseloop 0.1.0 (git commit 0123456789ab)": CMake's project VERSION and the commit the build
// was configured from (src/cli/CMakeLists.txt; "unknown" outside a git checkout).
void PrintVersion() {
  std::cout << "sparseloop " << SPARSELOOP_VERSION << " (git commit " << SPARSELOOP_GIT_COMMIT
            << ")\n";
}
}  // namespace

}  // namespace sparseloop::cli

int main(int argc, char** argv) {
  using sparseloop::cli::Registry;
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    sparseloop::cli::PrintUsage();
    return argc < 2 ? 2 : 0;
  }
  if (std::string(argv[1]) == "--version") {
    sparseloop::cli::PrintVersion();
    return 0;
  }
  const std::string name = argv[1];
  for (const auto& command : Registry()) {
    if (command.name != name) continue;
    try {
      return command.run(argc - 1, argv + 1);
    } catch (const CLI::CallForHelp&) {
      return 0;  // the help text was printed by cli::Parse
    } catch (const CLI::CallForAllHelp&) {
      return 0;
    } catch (const CLI::ParseError& e) {
      std::cerr << "sparseloop " << name << ": " << e.what() << " (see: sparseloop " << name
                << " --help)\n";
      return e.get_exit_code() == 0 ? 0 : 2;
    } catch (const sparseloop::Error& e) {
      std::cerr << "sparseloop " << name << ": error: " << e.what() << "\n";
      return 2;
    } catch (const std::invalid_argument& e) {
      std::cerr << "sparseloop " << name << ": invalid argument: " << e.what() << "\n";
      return 2;
    } catch (const std::exception& e) {
      std::cerr << "sparseloop " << name << ": failed: " << e.what() << "\n";
      return 1;
    }
  }
  std::cerr << "sparseloop: unknown command '" << name << "'\n";
  sparseloop::cli::PrintUsage();
  return 2;
}
