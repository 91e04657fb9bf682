#pragma once
// The library's one logger. It writes to stderr (never stdout); applications may replace its sinks
// or level through the returned spdlog logger.
#include <spdlog/spdlog.h>

namespace sparseloop {

spdlog::logger& Logger();

}  // namespace sparseloop
