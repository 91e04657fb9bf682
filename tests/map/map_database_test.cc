#include "sparseloop/map/map_database.h"

#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>

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
