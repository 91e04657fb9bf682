#include "sparseloop/map/map_database.h"

#include <sqlite3.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>

#include "sparseloop/core/check.h"
#include "sparseloop/core/logging.h"
#include "sparseloop/core/packed_keyframe.h"

namespace sparseloop {
namespace {

// RAII prepared statement.
class Statement {
 public:
  Statement(sqlite3* db, const char* sql, const std::filesystem::path& path) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) {
      throw MapDatabaseError(fmt::format("{}: SQLite error preparing '{}': {}", path.string(), sql,
                                         sqlite3_errmsg(db)));
    }
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  sqlite3_stmt* get() const { return stmt_; }
  void BindBlob(int index, const void* data, size_t bytes) {
    sqlite3_bind_blob(stmt_, index, bytes ? data : "", static_cast<int>(bytes), SQLITE_TRANSIENT);
  }
  int Step() { return sqlite3_step(stmt_); }

 private:
  sqlite3_stmt* stmt_ = nullptr;
};

std::vector<double> SimToBlob(const Sim3d& s) {
  const Vector8d v = s.ToVector();
  return {v.data(), v.data() + 8};
}

Sim3d SimFromBlob(const void* data, int bytes, const std::filesystem::path& path) {
  if (bytes != 8 * static_cast<int>(sizeof(double))) {
    throw MapDatabaseError(
        fmt::format("{}: corrupt pose blob of {} bytes (expected 64)", path.string(), bytes));
  }
  Vector8d v;
  std::memcpy(v.data(), data, 64);
  if (!v.allFinite() || !(v[7] > 0.0) || std::abs(v.head<4>().norm() - 1.0) > 1e-6) {
    throw MapDatabaseError(
        fmt::format("{}: corrupt pose (non-finite, zero scale or non-unit "
                    "quaternion)",
                    path.string()));
  }
  return Sim3d::FromVector(v);
}

template <typename T>
std::vector<T> ColumnArray(sqlite3_stmt* stmt, int col) {
  const int bytes = sqlite3_column_bytes(stmt, col);
  std::vector<T> out(static_cast<size_t>(bytes) / sizeof(T));
  if (bytes > 0) std::memcpy(out.data(), sqlite3_column_blob(stmt, col), out.size() * sizeof(T));
  return out;
}

int QueryInt(sqlite3* db, const char* sql, const std::filesystem::path& path) {
  Statement st(db, sql, path);
  const int rc = st.Step();
  if (rc != SQLITE_ROW) {
    throw MapDatabaseError(
        fmt::format("{}: cannot read '{}': {}", path.string(), sql, sqlite3_errmsg(db)));
  }
  return sqlite3_column_int(st.get(), 0);
}

constexpr const char* kCreateKeyframesV3 =
    " (session INTEGER NOT NULL REFERENCES sessions(id), id INTEGER NOT NULL,"
    " timestamp REAL NOT NULL, record BLOB NOT NULL, PRIMARY KEY(session, id))";

// StoredKeyframe (plain arrays) -> the fields of a packed record. Sizes are checked by the caller.
PackedKeyframe::Fields ToFields(const StoredKeyframe& kf) {
  PackedKeyframe::Fields f;
  f.id = kf.id;
  f.timestamp = kf.timestamp;
  f.has_pose = kf.has_pose;
  if (kf.has_pose) f.world_from_cam = kf.raw_world_from_cam;
  f.focal_px = kf.focal_px;
  f.descriptors.resize(static_cast<size_t>(kf.num_features));
  if (kf.num_features > 0) {
    std::memcpy(f.descriptors.data(), kf.descriptors.data(), f.descriptors.size() * 32);
  }
  f.keypoints = kf.keypoints;
  f.depths = kf.depths;
  return f;
}

// A packed record read back -> StoredKeyframe (the quantised values).
StoredKeyframe FromPacked(const PackedKeyframe& packed, int64_t session) {
  PackedKeyframe::Fields f = packed.Unpack();
  StoredKeyframe kf;
  kf.session = session;
  kf.id = f.id;
  kf.timestamp = f.timestamp;
  kf.has_pose = f.has_pose;
  kf.raw_world_from_cam = f.has_pose ? f.world_from_cam : Sim3d::Identity();
  kf.focal_px = f.focal_px;
  kf.num_features = static_cast<int>(f.descriptors.size());
  kf.descriptors.resize(f.descriptors.size() * 32);
  if (!f.descriptors.empty()) {
    std::memcpy(kf.descriptors.data(), f.descriptors.data(), kf.descriptors.size());
  }
  kf.keypoints = std::move(f.keypoints);
  kf.depths = std::move(f.depths);
  return kf;
}

// The record column of the current row as a validated packed keyframe; a bad blob is a
// MapDatabaseError naming the file, the row and the reason.
PackedKeyframe RecordFromColumn(sqlite3_stmt* stmt, int col, int64_t session, int64_t id,
                                const std::filesystem::path& path) {
  const auto* data = static_cast<const uint8_t*>(sqlite3_column_blob(stmt, col));
  const int bytes = sqlite3_column_bytes(stmt, col);
  PackedKeyframe packed;
  try {
    packed = PackedKeyframe::FromBytes({data, static_cast<size_t>(std::max(bytes, 0))});
  } catch (const std::invalid_argument& e) {
    throw MapDatabaseError(fmt::format("{}: corrupt keyframe record (session {}, id {}): {}",
                                       path.string(), session, id, e.what()));
  }
  if (packed.id() != id) {
    throw MapDatabaseError(
        fmt::format("{}: corrupt keyframe record (session {}, id {}): the record holds id {}",
                    path.string(), session, id, packed.id()));
  }
  return packed;
}

void CopyPackedRows(sqlite3* db, const std::filesystem::path& path);

// Schema 2 -> 3 inside the caller's transaction: every row's columns are packed into one
// record blob (create keyframes_v3, copy, drop the old table, rename).
void MigrateKeyframesTwoToThree(sqlite3* db, const std::filesystem::path& path) {
  const auto exec = [&](const std::string& sql) {
    char* err = nullptr;
    if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
      std::string msg = err ? err : sqlite3_errmsg(db);
      sqlite3_free(err);
      throw MapDatabaseError(
          fmt::format("{}: SQLite error migrating to schema 3: {}", path.string(), msg));
    }
  };
  exec(std::string("CREATE TABLE keyframes_v3") + kCreateKeyframesV3);
  CopyPackedRows(db, path);  // its statements are finalized before the old table is dropped
  exec("DROP TABLE keyframes; ALTER TABLE keyframes_v3 RENAME TO keyframes;");
}

void CopyPackedRows(sqlite3* db, const std::filesystem::path& path) {
  Statement read(db,
                 "SELECT session, id, timestamp, pose, num_features, descriptors, keypoints,"
                 " depths, focal_px, has_pose FROM keyframes ORDER BY session, id",
                 path);
  Statement write(db, "INSERT INTO keyframes_v3(session, id, timestamp, record) VALUES(?,?,?,?)",
                  path);
  int rc;
  while ((rc = read.Step()) == SQLITE_ROW) {
    sqlite3_stmt* s = read.get();
    StoredKeyframe kf;
    kf.session = sqlite3_column_int64(s, 0);
    kf.id = sqlite3_column_int64(s, 1);
    kf.timestamp = sqlite3_column_double(s, 2);
    kf.has_pose = sqlite3_column_int(s, 9) != 0;
    kf.num_features = sqlite3_column_int(s, 4);
    kf.descriptors = ColumnArray<uint8_t>(s, 5);
    kf.keypoints = ColumnArray<float>(s, 6);
    kf.depths = ColumnArray<float>(s, 7);
    kf.focal_px = static_cast<float>(sqlite3_column_double(s, 8));
    const size_t n = static_cast<size_t>(std::max(kf.num_features, 0));
    std::string reason;
    if (kf.num_features < 0 || kf.descriptors.size() != n * 32 || kf.keypoints.size() != n * 2 ||
        (!kf.depths.empty() && kf.depths.size() != n)) {
      reason = "array sizes do not match num_features";
    }
    PackedKeyframe packed;
    if (reason.empty()) {
      try {
        if (kf.has_pose) {
          kf.raw_world_from_cam =
              SimFromBlob(sqlite3_column_blob(s, 3), sqlite3_column_bytes(s, 3), path);
        }
        packed = PackedKeyframe::Pack(ToFields(kf));
      } catch (const std::exception& e) {
        reason = e.what();
      }
    }
    if (!reason.empty()) {
      throw MapDatabaseError(
          fmt::format("{}: cannot migrate keyframe (session {}, id {}) to schema 3: {}",
                      path.string(), kf.session, kf.id, reason));
    }
    sqlite3_reset(write.get());
    sqlite3_bind_int64(write.get(), 1, kf.session);
    sqlite3_bind_int64(write.get(), 2, kf.id);
    sqlite3_bind_double(write.get(), 3, kf.timestamp);
    const auto bytes = packed.bytes();
    write.BindBlob(4, bytes.data(), bytes.size());
    if (write.Step() != SQLITE_DONE) {
      throw MapDatabaseError(fmt::format("{}: cannot migrate keyframe (session {}, id {}): {}",
                                         path.string(), kf.session, kf.id, sqlite3_errmsg(db)));
    }
  }
  if (rc != SQLITE_DONE) {
    throw MapDatabaseError(path.string() +
                           ": cannot read keyframes to migrate: " + sqlite3_errmsg(db));
  }
}

}  // namespace

void MapDatabaseOptions::Check() const {
  SL_CHECK_MSG(commit_every >= 1, "commit_every must be >= 1, got {}", commit_every);
}

namespace {

// What stops `path` from holding a map, before SQLite is asked (whose words would be "disk I/O
// error" for /dev/null, or "attempt to write a readonly database" while reading a PRAGMA): not a
// regular file, or a folder where the -wal / -shm files cannot be created. Empty when fine.
std::string MapPathProblem(const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec && status.type() != fs::file_type::not_found) {
    return fmt::format("expected a map database file, got {}", ec.message());
  }
  if (status.type() != fs::file_type::not_found && status.type() != fs::file_type::regular) {
    return fmt::format(
        "expected a map database file (a regular file or a new file name), got {}",
        status.type() == fs::file_type::directory ? "a directory" : "a device, FIFO or socket");
  }
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec)) {
    return fmt::format("expected a map in an existing folder, got {} missing", dir.string());
  }
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    return fmt::format(
        "expected a writable folder (SQLite keeps {}-wal and -shm beside the map), got {}: {}",
        path.filename().string(), dir.string(), std::strerror(errno));
  }
  if (status.type() == fs::file_type::regular && ::access(path.c_str(), R_OK | W_OK) != 0) {
    return fmt::format("expected a readable and writable map file, got {}", std::strerror(errno));
  }
  return {};
}

}  // namespace

std::unique_ptr<MapDatabase> MapDatabase::Open(const std::filesystem::path& path,
                                               const MapDatabaseOptions& options) {
  options.Check();
  if (const std::string problem = MapPathProblem(path); !problem.empty()) {
    throw MapDatabaseError(path.string() + ": " + problem);
  }
  sqlite3* db = nullptr;
  const int rc =
      sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr);
  if (rc != SQLITE_OK) {
    const std::string msg = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    throw MapDatabaseError(fmt::format("{}: cannot open map database: {}", path.string(), msg));
  }
  // The constructor takes ownership of db; from here on errors close it through the destructor.
  std::unique_ptr<MapDatabase> map(new MapDatabase(path, options, db));
  sqlite3_busy_timeout(db, 5000);
  // Reading the header fails with SQLITE_NOTADB for a file that is not SQLite at all.
  const int app_id = QueryInt(db, "PRAGMA application_id", path);
  const int version = QueryInt(db, "PRAGMA user_version", path);
  const int tables = QueryInt(db, "SELECT count(*) FROM sqlite_master", path);
  if (tables == 0 && app_id == 0) {
    map->Exec("PRAGMA journal_mode=WAL");
    map->Exec(fmt::format("PRAGMA application_id={}", kApplicationId).c_str());
    map->Exec(fmt::format("PRAGMA user_version={}", kSchemaVersion).c_str());
    const std::string tables_sql =
        "CREATE TABLE sessions(id INTEGER PRIMARY KEY, created_unix REAL NOT NULL, label TEXT);"
        "CREATE TABLE keyframes" +
        std::string(kCreateKeyframesV3) +
        ";"
        "CREATE TABLE loops(session INTEGER NOT NULL, query INTEGER NOT NULL,"
        " match_session INTEGER NOT NULL, match INTEGER NOT NULL, inliers INTEGER NOT NULL,"
        " score REAL NOT NULL, relative BLOB NOT NULL, accepted INTEGER NOT NULL);";
    map->Exec(tables_sql.c_str());
  } else if (app_id != kApplicationId) {
    throw MapDatabaseError(fmt::format(
        "{}: not a sparseloop map (SQLite application_id {:#x}, expected {:#x})", path.string(),
        static_cast<uint32_t>(app_id), static_cast<uint32_t>(kApplicationId)));
  } else if (version > kSchemaVersion) {
    throw MapDatabaseError(fmt::format(
        "{}: map schema version {} is newer than this sparseloop supports ({}); upgrade "
        "sparseloop",
        path.string(), version, kSchemaVersion));
  } else if (version < 1) {
    throw MapDatabaseError(fmt::format("{}: map schema version {} has no migration to {}",
                                       path.string(), version, kSchemaVersion));
  } else {
    if (version < 3) {
      // One transaction for the whole chain: a failure leaves the file at its old version.
      map->Exec("BEGIN IMMEDIATE");
      try {
        if (version == 1) {
          // 1 -> 2: per-keyframe focal length (verification thresholds) and pose flag
          // (relocalisation). Old keyframes: focal unknown (0), pose present.
          map->Exec(
              "ALTER TABLE keyframes ADD COLUMN focal_px REAL NOT NULL DEFAULT 0;"
              "ALTER TABLE keyframes ADD COLUMN has_pose INTEGER NOT NULL DEFAULT 1;");
        }
        // 2 -> 3: each keyframe's columns become one PackedKeyframe record (quantised).
        MigrateKeyframesTwoToThree(db, path);
        map->Exec("PRAGMA user_version=3");
        map->Exec("COMMIT");
      } catch (...) {
        sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
        throw;
      }
      Logger().info("{}: map schema migrated from version {} to 3", path.string(), version);
    }
    map->Exec("PRAGMA journal_mode=WAL");
    const int ok =
        QueryInt(db, "SELECT count(*) FROM pragma_quick_check WHERE quick_check='ok'", path);
    if (ok != 1) throw MapDatabaseError(path.string() + ": map database failed quick_check");
  }
  map->Exec(options.full_sync ? "PRAGMA synchronous=FULL" : "PRAGMA synchronous=NORMAL");
  return map;
}

MapDatabase::MapDatabase(std::filesystem::path path, MapDatabaseOptions options, sqlite3* db)
    : path_(std::move(path)), options_(options), db_(db) {}

MapDatabase::~MapDatabase() {
  if (db_ == nullptr) return;
  if (in_transaction_) {
    if (sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr) != SQLITE_OK) {
      Logger().error("{}: final commit failed: {}", path_.string(), sqlite3_errmsg(db_));
    }
  }
  sqlite3_close(db_);
}

void MapDatabase::Exec(const char* sql) const {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : sqlite3_errmsg(db_);
    sqlite3_free(err);
    throw MapDatabaseError(fmt::format("{}: SQLite error: {}", path_.string(), msg));
  }
}

void MapDatabase::BeginIfNeeded() {
  if (!in_transaction_) {
    Exec("BEGIN IMMEDIATE");
    in_transaction_ = true;
  }
}

void MapDatabase::MaybeCommit() {
  if (++pending_ >= options_.commit_every) Flush();
}

void MapDatabase::Flush() {
  if (in_transaction_) {
    Exec("COMMIT");
    in_transaction_ = false;
  }
  pending_ = 0;
}

int64_t MapDatabase::BeginSession(const std::string& label) {
  BeginIfNeeded();
  Statement st(db_, "INSERT INTO sessions(created_unix, label) VALUES(?, ?)", path_);
  const double now =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  sqlite3_bind_double(st.get(), 1, now);
  sqlite3_bind_text(st.get(), 2, label.c_str(), -1, SQLITE_TRANSIENT);
  if (st.Step() != SQLITE_DONE) {
    throw MapDatabaseError(path_.string() + ": cannot add session: " + sqlite3_errmsg(db_));
  }
  const int64_t id = sqlite3_last_insert_rowid(db_);
  Flush();
  return id;
}

std::vector<int64_t> MapDatabase::Sessions() const {
  Statement st(db_, "SELECT id FROM sessions ORDER BY id", path_);
  std::vector<int64_t> out;
  while (st.Step() == SQLITE_ROW) out.push_back(sqlite3_column_int64(st.get(), 0));
  return out;
}

void MapDatabase::PutKeyframe(const StoredKeyframe& kf) {
  SL_CHECK_MSG(kf.num_features >= 0, "keyframe {}: negative feature count", kf.id);
  SL_CHECK_MSG(kf.descriptors.size() == static_cast<size_t>(kf.num_features) * 32,
               "keyframe {}: {} descriptor bytes for {} features (expected 32 each)", kf.id,
               kf.descriptors.size(), kf.num_features);
  SL_CHECK_MSG(kf.keypoints.size() == static_cast<size_t>(kf.num_features) * 2,
               "keyframe {}: {} keypoint floats for {} features (expected 2 each)", kf.id,
               kf.keypoints.size(), kf.num_features);
  SL_CHECK_MSG(kf.depths.empty() || kf.depths.size() == static_cast<size_t>(kf.num_features),
               "keyframe {}: {} depths for {} features", kf.id, kf.depths.size(), kf.num_features);
  SL_CHECK_MSG(std::isfinite(kf.timestamp), "keyframe {}: non-finite timestamp", kf.id);
  SL_CHECK_MSG(std::isfinite(kf.focal_px) && kf.focal_px >= 0,
               "keyframe {}: focal_px must be finite and >= 0, got {}", kf.id, kf.focal_px);
  PutRecord(kf.session, PackedKeyframe::Pack(ToFields(kf)));  // packed before any write
}

int MapDatabase::StepRecord(const char* sql, int64_t session, const PackedKeyframe& record) {
  BeginIfNeeded();
  Statement st(db_, sql, path_);
  sqlite3_bind_int64(st.get(), 1, session);
  sqlite3_bind_int64(st.get(), 2, record.id());
  sqlite3_bind_double(st.get(), 3, record.timestamp());
  const auto bytes = record.bytes();
  st.BindBlob(4, bytes.data(), bytes.size());
  return st.Step();
}

void MapDatabase::PutRecord(int64_t session, const PackedKeyframe& record) {
  const int rc = StepRecord(
      "INSERT INTO keyframes(session, id, timestamp, record) VALUES(?1,?2,?3,?4)", session, record);
  if (rc == SQLITE_CONSTRAINT) {
    // Statement-level rollback: earlier keyframes in this transaction are kept.
    SL_CHECK_MSG(false, "keyframe id {} already stored in session {}", record.id(), session);
  }
  if (rc != SQLITE_DONE) {
    throw MapDatabaseError(path_.string() + ": cannot store keyframe: " + sqlite3_errmsg(db_));
  }
  MaybeCommit();
}

void MapDatabase::PutLoop(const StoredLoop& loop) {
  BeginIfNeeded();
  Statement st(db_,
               "INSERT INTO loops(session, query, match_session, match, inliers, score, relative,"
               " accepted) VALUES(?,?,?,?,?,?,?,?)",
               path_);
  const auto rel = SimToBlob(loop.match_from_query);
  sqlite3_bind_int64(st.get(), 1, loop.session);
  sqlite3_bind_int64(st.get(), 2, loop.query);
  sqlite3_bind_int64(st.get(), 3, loop.match_session);
  sqlite3_bind_int64(st.get(), 4, loop.match);
  sqlite3_bind_int(st.get(), 5, loop.inliers);
  sqlite3_bind_double(st.get(), 6, loop.score);
  st.BindBlob(7, rel.data(), rel.size() * sizeof(double));
  sqlite3_bind_int(st.get(), 8, loop.accepted ? 1 : 0);
  if (st.Step() != SQLITE_DONE) {
    throw MapDatabaseError(path_.string() + ": cannot store loop: " + sqlite3_errmsg(db_));
  }
  MaybeCommit();
}

namespace {
std::vector<StoredKeyframe> ReadKeyframes(sqlite3* db, Statement& st,
                                          const std::filesystem::path& path) {
  std::vector<StoredKeyframe> out;
  int rc;
  while ((rc = st.Step()) == SQLITE_ROW) {
    sqlite3_stmt* s = st.get();
    const int64_t session = sqlite3_column_int64(s, 0);
    const int64_t id = sqlite3_column_int64(s, 1);
    out.push_back(FromPacked(RecordFromColumn(s, 2, session, id, path), session));
  }
  if (rc != SQLITE_DONE) {
    throw MapDatabaseError(path.string() + ": cannot read keyframes: " + sqlite3_errmsg(db));
  }
  return out;
}
constexpr const char* kSelectKeyframes = "SELECT session, id, record FROM keyframes";
}  // namespace

std::vector<StoredKeyframe> MapDatabase::LoadKeyframes(int64_t session) const {
  const std::string sql = std::string(kSelectKeyframes) + " WHERE session=? ORDER BY id";
  Statement st(db_, sql.c_str(), path_);
  sqlite3_bind_int64(st.get(), 1, session);
  return ReadKeyframes(db_, st, path_);
}

std::vector<StoredKeyframe> MapDatabase::LoadAllKeyframes() const {
  const std::string sql = std::string(kSelectKeyframes) + " ORDER BY session, id";
  Statement st(db_, sql.c_str(), path_);
  return ReadKeyframes(db_, st, path_);
}

std::vector<uint8_t> MapDatabase::LoadRecordBytes(int64_t session, int64_t id) const {
  Statement st(db_, "SELECT record FROM keyframes WHERE session=? AND id=?", path_);
  sqlite3_bind_int64(st.get(), 1, session);
  sqlite3_bind_int64(st.get(), 2, id);
  const int rc = st.Step();
  if (rc != SQLITE_ROW) {
    throw MapDatabaseError(
        rc == SQLITE_DONE
            ? fmt::format("{}: no keyframe (session {}, id {})", path_.string(), session, id)
            : fmt::format("{}: cannot read keyframe (session {}, id {}): {}", path_.string(),
                          session, id, sqlite3_errmsg(db_)));
  }
  return ColumnArray<uint8_t>(st.get(), 0);
}

std::vector<StoredLoop> MapDatabase::LoadLoops() const {
  Statement st(db_,
               "SELECT session, query, match_session, match, inliers, score, relative, accepted"
               " FROM loops ORDER BY rowid",
               path_);
  std::vector<StoredLoop> out;
  while (st.Step() == SQLITE_ROW) {
    sqlite3_stmt* s = st.get();
    StoredLoop l;
    l.session = sqlite3_column_int64(s, 0);
    l.query = sqlite3_column_int64(s, 1);
    l.match_session = sqlite3_column_int64(s, 2);
    l.match = sqlite3_column_int64(s, 3);
    l.inliers = sqlite3_column_int(s, 4);
    l.score = sqlite3_column_double(s, 5);
    l.match_from_query = SimFromBlob(sqlite3_column_blob(s, 6), sqlite3_column_bytes(s, 6), path_);
    l.accepted = sqlite3_column_int(s, 7) != 0;
    out.push_back(l);
  }
  return out;
}

int64_t MapDatabase::CountKeyframes() const {
  return QueryInt(db_, "SELECT count(*) FROM keyframes", path_);
}

}  // namespace sparseloop
