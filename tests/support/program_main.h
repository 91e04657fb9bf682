#pragma once
// main() of the accuracy programs in bench/ (own main, one JSON object on stdout): an exception
// becomes "NAME: message" on stderr and the exit code `error_exit`.
#include <cstdio>
#include <exception>

namespace sparseloop::test {

template <typename Run>
int RunProgram(const char* name, int error_exit, Run&& run) {
  try {
    return run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", name, e.what());
    return error_exit;
  }
}

}  // namespace sparseloop::test
