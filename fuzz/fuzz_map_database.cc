// Fuzzes the map database loader: arbitrary bytes as a map file must either load or raise
// MapDatabaseError / std::invalid_argument, never crash.
#include <filesystem>

#include "fuzz_util.h"
#include "sparseloop/map/map_database.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sparseloop::fuzz::WriteInput(data, size, "map.db");
  std::filesystem::remove(path.string() + "-wal");
  std::filesystem::remove(path.string() + "-shm");
  try {
    auto map = sparseloop::MapDatabase::Open(path);
    map->LoadAllKeyframes();
    map->LoadLoops();
  } catch (const sparseloop::Error&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
