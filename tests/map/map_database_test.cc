#include "sparseloop/map/map_database.h"

#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>

#include <fmt/format.h>

#include <gtest/gtest.h>

#include "test_util.h"

namespace sparseloop {
namespace {

StoredKeyframe MakeKeyframe(int64_t session, int64_t id, int k, bool depths) {
  StoredKeyframe kf;
  kf.session = session;
  kf.id = id;
  kf.timestamp = 0.1 * static_cast<double>(id);
  Vector7d t;
  t << 0.1 * id, 0.2, -0.3, 0.01 * id, 0.02, 0.03, 0.001 * id;
  kf.raw_world_from_cam = Sim3d::Exp(t);
  kf.num_features = k;
  for (int i = 0; i < k * 32; ++i)
    kf.descriptors.push_back(static_cast<uint8_t>((id * 31 + i) & 0xff));
  for (int i = 0; i < k * 2; ++i) kf.keypoints.push_back(static_cast<float>(id + 0.5 * i));
  if (depths) {
    for (int i = 0; i < k; ++i) kf.depths.push_back(static_cast<float>(1.0 + i));
  }
  return kf;
}

void ExpectSame(const StoredKeyframe& a, const StoredKeyframe& b) {
  EXPECT_EQ(a.session, b.session);
  EXPECT_EQ(a.id, b.id);
  EXPECT_DOUBLE_EQ(a.timestamp, b.timestamp);
  EXPECT_LT((a.raw_world_from_cam.ToVector() - b.raw_world_from_cam.ToVector()).norm(), 1e-15);
  EXPECT_EQ(a.descriptors, b.descriptors);
  EXPECT_EQ(a.keypoints, b.keypoints);
  EXPECT_EQ(a.depths, b.depths);
}

TEST(MapDatabase, RoundTripAcrossSessions) {
  const auto path = test::TempDir() / "map.db";
  std::vector<StoredKeyframe> written;
  {
    auto map = MapDatabase::Open(path);
    const int64_t s1 = map->BeginSession("first flight");
    for (int i = 0; i < 20; ++i) {
      written.push_back(MakeKeyframe(s1, i, 15, i % 2 == 0));
      map->PutKeyframe(written.back());
    }
    StoredLoop loop;
    loop.session = s1;
    loop.query = 19;
    loop.match_session = s1;
    loop.match = 2;
    loop.inliers = 12;
    loop.score = 0.8;
    map->PutLoop(loop);
  }
  auto map = MapDatabase::Open(path);
  const int64_t s2 = map->BeginSession("second flight");
  map->PutKeyframe(MakeKeyframe(s2, 0, 15, false));
  map->Flush();
  EXPECT_EQ(map->Sessions(), (std::vector<int64_t>{1, 2}));
  const auto loaded = map->LoadKeyframes(1);
  ASSERT_EQ(loaded.size(), written.size());
  for (size_t i = 0; i < loaded.size(); ++i) ExpectSame(loaded[i], written[i]);
  EXPECT_EQ(map->LoadAllKeyframes().size(), 21u);
  ASSERT_EQ(map->LoadLoops().size(), 1u);
  EXPECT_EQ(map->LoadLoops()[0].match, 2);
}

TEST(MapDatabase, DuplicateIdIsRejectedAndNothingIsLost) {
  const auto path = test::TempDir() / "map.db";
  auto map = MapDatabase::Open(path, MapDatabaseOptions{.commit_every = 4});
  const int64_t s = map->BeginSession("s");
  map->PutKeyframe(MakeKeyframe(s, 0, 15, false));
  map->PutKeyframe(MakeKeyframe(s, 1, 15, false));
  EXPECT_THROW(map->PutKeyframe(MakeKeyframe(s, 1, 15, false)), std::invalid_argument);
  map->PutKeyframe(MakeKeyframe(s, 2, 15, false));
  map->Flush();
  EXPECT_EQ(map->CountKeyframes(), 3);
}

TEST(MapDatabase, InconsistentRecordIsRejected) {
  auto map = MapDatabase::Open(test::TempDir() / "map.db");
  const int64_t s = map->BeginSession("s");
  StoredKeyframe kf = MakeKeyframe(s, 0, 15, false);
  kf.descriptors.pop_back();
  EXPECT_THROW(map->PutKeyframe(kf), std::invalid_argument);
  EXPECT_EQ(map->CountKeyframes(), 0);
}

TEST(MapDatabase, ForeignSqliteFileGivesClearError) {
  const auto path = test::TempDir() / "foreign.db";
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(
      sqlite3_exec(db, "CREATE TABLE t(x); INSERT INTO t VALUES(1);", nullptr, nullptr, nullptr),
      SQLITE_OK);
  sqlite3_close(db);
  try {
    MapDatabase::Open(path);
    FAIL() << "no throw";
  } catch (const MapDatabaseError& e) {
    EXPECT_NE(std::string(e.what()).find("not a sparseloop map"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos);
  }
}

TEST(MapDatabase, GarbageFileGivesClearError) {
  const auto path = test::TempDir() / "garbage.db";
  {
    std::ofstream out(path, std::ios::binary);
    for (int i = 0; i < 8192; ++i) out.put(static_cast<char>((i * 7919) & 0xff));
  }
  EXPECT_THROW(MapDatabase::Open(path), MapDatabaseError);
}

TEST(MapDatabase, CorruptedPagesAreDetected) {
  const auto path = test::TempDir() / "map.db";
  {
    auto map = MapDatabase::Open(path);
    const int64_t s = map->BeginSession("s");
    for (int i = 0; i < 200; ++i) map->PutKeyframe(MakeKeyframe(s, i, 15, true));
  }
  {
    // Overwrite the middle of the file (b-tree pages) with garbage, keeping the header.
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(0, std::ios::end);
    const auto size = static_cast<long>(f.tellp());
    ASSERT_GT(size, 16384);
    f.seekp(size / 2);
    for (int i = 0; i < 8192; ++i) f.put(static_cast<char>(0xA5 ^ i));
  }
  EXPECT_THROW(
      {
        auto map = MapDatabase::Open(path);
        map->LoadAllKeyframes();
      },
      MapDatabaseError);
}

TEST(MapDatabase, NewerSchemaIsRefused) {
  const auto path = test::TempDir() / "map.db";
  { MapDatabase::Open(path)->BeginSession("s"); }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "PRAGMA user_version=99", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  try {
    MapDatabase::Open(path);
    FAIL() << "no throw";
  } catch (const MapDatabaseError& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 99"), std::string::npos) << e.what();
  }
}

TEST(MapDatabase, FocalAndPoseFlagRoundTrip) {
  const auto path = test::TempDir() / "map.db";
  StoredKeyframe a = MakeKeyframe(1, 1, 3, false);
  a.focal_px = 512.5f;
  StoredKeyframe b = MakeKeyframe(1, 2, 3, true);
  b.has_pose = false;
  b.raw_world_from_cam = Sim3d();
  {
    auto map = MapDatabase::Open(path);
    map->BeginSession("s");
    map->PutKeyframe(a);
    map->PutKeyframe(b);
    StoredKeyframe bad = MakeKeyframe(1, 3, 3, false);
    bad.focal_px = -1.0f;
    EXPECT_THROW(map->PutKeyframe(bad), std::invalid_argument);
  }
  const auto back = MapDatabase::Open(path)->LoadKeyframes(1);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].focal_px, 512.5f);
  EXPECT_TRUE(back[0].has_pose);
  EXPECT_EQ(back[1].focal_px, 0.0f);
  EXPECT_FALSE(back[1].has_pose);
}

// A schema-1 file (no focal_px / has_pose columns) is migrated in place on open; its keyframes
// read back with focal 0 (unknown) and a pose, and the file reports schema 2 afterwards.
TEST(MapDatabase, SchemaOneIsMigratedToTwo) {
  const auto path = test::TempDir() / "v1.db";
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  const std::string v1 = fmt::format(
      "PRAGMA application_id={};PRAGMA user_version=1;"
      "CREATE TABLE sessions(id INTEGER PRIMARY KEY, created_unix REAL NOT NULL, label TEXT);"
      "CREATE TABLE keyframes(session INTEGER NOT NULL REFERENCES sessions(id),"
      " id INTEGER NOT NULL, timestamp REAL NOT NULL, pose BLOB NOT NULL,"
      " num_features INTEGER NOT NULL, descriptors BLOB NOT NULL, keypoints BLOB NOT NULL,"
      " depths BLOB NOT NULL, PRIMARY KEY(session, id));"
      "CREATE TABLE loops(session INTEGER NOT NULL, query INTEGER NOT NULL,"
      " match_session INTEGER NOT NULL, match INTEGER NOT NULL, inliers INTEGER NOT NULL,"
      " score REAL NOT NULL, relative BLOB NOT NULL, accepted INTEGER NOT NULL);"
      "INSERT INTO sessions VALUES(1, 0, 'old');",
      MapDatabase::kApplicationId);
  ASSERT_EQ(sqlite3_exec(db, v1.c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
  const StoredKeyframe kf = MakeKeyframe(1, 7, 2, false);
  sqlite3_stmt* st = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "INSERT INTO keyframes VALUES(1, 7, 0.7, ?, 2, ?, ?, ?)", -1,
                               &st, nullptr),
            SQLITE_OK);
  const Vector8d pose = kf.raw_world_from_cam.ToVector();
  sqlite3_bind_blob(st, 1, pose.data(), 64, SQLITE_TRANSIENT);
  sqlite3_bind_blob(st, 2, kf.descriptors.data(), 64, SQLITE_TRANSIENT);
  sqlite3_bind_blob(st, 3, kf.keypoints.data(), 16, SQLITE_TRANSIENT);
  sqlite3_bind_blob(st, 4, "", 0, SQLITE_TRANSIENT);
  ASSERT_EQ(sqlite3_step(st), SQLITE_DONE);
  sqlite3_finalize(st);
  sqlite3_close(db);

  {
    auto map = MapDatabase::Open(path);
    const auto back = map->LoadKeyframes(1);
    ASSERT_EQ(back.size(), 1u);
    EXPECT_EQ(back[0].descriptors, kf.descriptors);
    EXPECT_EQ(back[0].focal_px, 0.0f);
    EXPECT_TRUE(back[0].has_pose);
    StoredKeyframe fresh = MakeKeyframe(map->BeginSession("new"), 1, 2, false);
    fresh.focal_px = 300.0f;
    map->PutKeyframe(fresh);
  }
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_prepare_v2(db, "PRAGMA user_version", -1, &st, nullptr);
  ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(st, 0), 2);
  sqlite3_finalize(st);
  sqlite3_close(db);
  EXPECT_EQ(MapDatabase::Open(path)->LoadKeyframes(2).at(0).focal_px, 300.0f);
}

// A writer process is killed with SIGKILL while it stores keyframes. The database must open
// and hold every keyframe whose Put had returned (the child reports them through a pipe).
TEST(MapDatabase, SurvivesKillDashNineMidRun) {
  const auto path = test::TempDir() / "map.db";
  { MapDatabase::Open(path)->BeginSession("victim"); }
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    close(fds[0]);
    auto map = MapDatabase::Open(path);  // commit_every = 1: durable once Put returns
    for (int64_t i = 0;; ++i) {
      map->PutKeyframe(MakeKeyframe(1, i, 15, true));
      if (write(fds[1], &i, sizeof(i)) != sizeof(i)) _exit(3);
    }
  }
  close(fds[1]);
  int64_t last_committed = -1;
  int64_t value = 0;
  // Let the writer run for a while, then kill it mid-write.
  while (last_committed < 300 && read(fds[0], &value, sizeof(value)) == sizeof(value)) {
    last_committed = value;
  }
  kill(pid, SIGKILL);
  while (read(fds[0], &value, sizeof(value)) == sizeof(value)) last_committed = value;
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status));
  ASSERT_GE(last_committed, 300);

  auto map = MapDatabase::Open(path);
  const auto loaded = map->LoadKeyframes(1);
  ASSERT_GE(static_cast<int64_t>(loaded.size()), last_committed + 1);
  for (int64_t i = 0; i <= last_committed; ++i) ExpectSame(loaded[i], MakeKeyframe(1, i, 15, true));
  // And the map stays writable.
  map->PutKeyframe(MakeKeyframe(1, static_cast<int64_t>(loaded.size()), 15, true));
}

}  // namespace
}  // namespace sparseloop
