#pragma once
// Each subcommand lives in its own cmd_<name>.cc and registers itself with
// SPARSELOOP_REGISTER_COMMAND. A command parses arguments into the library's options structs,
// calls the library, prints, and returns an exit code:
//   0 success, 1 runtime failure, 2 bad input (bad file, bad argument).
// Exceptions of type sparseloop::Error / std::invalid_argument are mapped to exit code 2 by main.
#include <functional>
#include <string>
#include <vector>

namespace sparseloop::cli {

using CommandFn = std::function<int(int argc, char** argv)>;

struct Command {
  std::string name;
  std::string help;
  CommandFn run;
};

std::vector<Command>& Registry();

struct Registrar {
  Registrar(std::string name, std::string help, CommandFn run);
};

}  // namespace sparseloop::cli

#define SPARSELOOP_REGISTER_COMMAND(name, help, fn) \
  static const ::sparseloop::cli::Registrar kRegistrar_##fn(name, help, fn)
