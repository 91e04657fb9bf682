#pragma once
// Persistent keyframe map in SQLite (WAL mode). Survives power cuts: every committed keyframe is
// readable after a kill -9 at any moment. Holds several sessions so that a later run can close
// loops against, and relocalise in, an earlier one.
//
// Schema (version kSchemaVersion, checked on open; application_id identifies our files):
//   sessions(id INTEGER PRIMARY KEY, created_unix REAL, label TEXT)
//   keyframes(session INTEGER, id INTEGER, timestamp REAL, record BLOB,
//             PRIMARY KEY(session, id))
//     record: the exact bytes of a PackedKeyframe (include/sparseloop/core/packed_keyframe.h:
//     id, timestamp, pose, has_pose, focal_px, descriptors, quantised keypoints and depths), the
//     same bytes the detector keeps in memory; timestamp is repeated as a column for queries.
//     Schema 3. Older files are migrated on open in one transaction: schema 1 (no focal_px /
//     has_pose columns: focal 0, pose present) and schema 2 (one column per field) are packed
//     row by row, so their floats become the quantised ones.
//   loops(session INTEGER, query INTEGER, match_session INTEGER, match INTEGER, inliers INTEGER,
//         score REAL, relative BLOB(8 doubles), accepted INTEGER)
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "sparseloop/core/error.h"
#include "sparseloop/core/packed_keyframe.h"
#include "sparseloop/core/sim3.h"

struct sqlite3;

namespace sparseloop {

// Raised for a file that is not a sparseloop map, is corrupt, or has an unsupported schema.
class MapDatabaseError : public Error {
 public:
  using Error::Error;
};

// What the map stores per keyframe: exactly what matching needs (see features/keyframe_record.h),
// as plain arrays so that this layer depends on core only.
struct StoredKeyframe {
  int64_t session = 0;
  int64_t id = 0;
  double timestamp = 0.0;
  Sim3d raw_world_from_cam;  // meaningful only when has_pose (identity otherwise)
  bool has_pose = true;      // false for a keyframe given without a raw pose (tracking lost)
  float focal_px = 0.0f;     // mean focal length of the camera, pixels (0 = unknown: v1 maps)
  int num_features = 0;
  std::vector<uint8_t> descriptors;  // num_features x 32 bytes (ORB)
  // num_features x 2: undistorted NORMALISED image coordinates x, y (as KeyframeRecord stores
  // them: x = (u - cx) / fx), not pixels.
  std::vector<float> keypoints;
  std::vector<float> depths;  // empty or num_features (raw vSLAM scale; <= 0 = unknown)
};

struct StoredLoop {
  int64_t session = 0;
  int64_t query = 0;
  int64_t match_session = 0;  // session of `match` (== session for a loop inside the session)
  int64_t match = 0;
  int inliers = 0;
  double score = 0.0;
  Sim3d match_from_query;
  bool accepted = true;
};

struct MapDatabaseOptions {
  // Commit every N keyframes (1 = every keyframe is durable once Put returns). Larger batches are
  // faster; at most N-1 keyframes are lost on a power cut.
  int commit_every = 1;
  // synchronous=NORMAL in WAL mode is durable against process crashes (kill -9) and keeps the file
  // consistent across power loss; FULL additionally guarantees the last commit survives power loss.
  bool full_sync = false;
  void Check() const;
};

class MapDatabase {
 public:
  // 2: keyframes.focal_px, keyframes.has_pose; 3: keyframes.record (one PackedKeyframe blob)
  static constexpr int kSchemaVersion = 3;
  static constexpr int32_t kApplicationId = 0x534C4D50;  // "SLMP"

  // Opens or creates. Throws MapDatabaseError naming the file for a foreign, corrupt or
  // newer-schema file. A schema-1 or schema-2 file is migrated to schema 3 in place (one
  // transaction; a keyframe that cannot be packed is a MapDatabaseError and the file is kept).
  static std::unique_ptr<MapDatabase> Open(const std::filesystem::path& path,
                                           const MapDatabaseOptions& options = {});
  ~MapDatabase();
  MapDatabase(const MapDatabase&) = delete;
  MapDatabase& operator=(const MapDatabase&) = delete;

  // Starts a new session and returns its id (1, 2, ...).
  int64_t BeginSession(const std::string& label);
  std::vector<int64_t> Sessions() const;

  // Stores a keyframe as one PackedKeyframe record (quantised: see packed_keyframe.h); throws
  // std::invalid_argument on a duplicate (session, id), an inconsistent record (sizes that do not
  // match num_features) or one that cannot be packed, leaving the map unchanged.
  void PutKeyframe(const StoredKeyframe& keyframe);
  // Stores `record`'s bytes as they are (the detector's stored record, LoopDetector::
  // packed_record): no unpack / re-pack. Same errors as PutKeyframe.
  void PutRecord(int64_t session, const PackedKeyframe& record);
  void PutLoop(const StoredLoop& loop);
  // Commits pending writes now (also done by the destructor).
  void Flush();

  // Loaded keyframes hold the record's (quantised) values; a record that does not decode is a
  // MapDatabaseError naming the file, session, id and reason.
  std::vector<StoredKeyframe> LoadKeyframes(int64_t session) const;  // ordered by id
  std::vector<StoredKeyframe> LoadAllKeyframes() const;              // by session, id
  // The stored record bytes (PackedKeyframe::bytes()); MapDatabaseError if there is no such row.
  std::vector<uint8_t> LoadRecordBytes(int64_t session, int64_t id) const;
  std::vector<StoredLoop> LoadLoops() const;
  int64_t CountKeyframes() const;
  const std::filesystem::path& path() const { return path_; }

 private:
  MapDatabase(std::filesystem::path path, MapDatabaseOptions options, sqlite3* db);
  void Exec(const char* sql) const;
  void MaybeCommit();
  void BeginIfNeeded();
  // Binds (session, record id, timestamp, record bytes) as ?1-?4 of `sql` and steps it.
  int StepRecord(const char* sql, int64_t session, const PackedKeyframe& record);

  std::filesystem::path path_;
  MapDatabaseOptions options_;
  sqlite3* db_ = nullptr;
  bool in_transaction_ = false;
  int pending_ = 0;
};

}  // namespace sparseloop
