#include "sparseloop/core/logging.h"

#include <spdlog/sinks/stdout_color_sinks.h>

namespace sparseloop {

spdlog::logger& Logger() {
  // Function-local static: thread-safe initialisation, one logger, stderr only.
  static std::shared_ptr<spdlog::logger> logger = [] {
    auto l = spdlog::stderr_color_mt("sparseloop");
    l->set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
    l->set_level(spdlog::level::info);
    return l;
  }();
  return *logger;
}

}  // namespace sparseloop
