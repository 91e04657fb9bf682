#include "sparseloop/map/map_database.h"

#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>

#include <fmt/format.h>

#include <gtest/gtest.h>

#include "sparseloop/core/packed_keyframe.h"
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

// The fields of the packed record the map stores for `kf`.
PackedKeyframe::Fields ToFields(const StoredKeyframe& kf) {
  PackedKeyframe::Fields f;
  f.id = kf.id;
  f.timestamp = kf.timestamp;
  f.has_pose = kf.has_pose;
  if (kf.has_pose) f.world_from_cam = kf.raw_world_from_cam;
  f.focal_px = kf.focal_px;
  f.descriptors.resize(static_cast<size_t>(kf.num_features));
  if (!kf.descriptors.empty()) {
    std::memcpy(f.descriptors.data(), kf.descriptors.data(), kf.descriptors.size());
  }
  f.keypoints = kf.keypoints;
  f.depths = kf.depths;
  return f;
}

// What the map gives back for `kf`: PackedKeyframe::Pack(...).Unpack() of the same input.
StoredKeyframe Quantised(const StoredKeyframe& kf) {
  const PackedKeyframe::Fields f = PackedKeyframe::Pack(ToFields(kf)).Unpack();
  StoredKeyframe q;
  q.session = kf.session;
  q.id = f.id;
  q.timestamp = f.timestamp;
  q.has_pose = f.has_pose;
  q.raw_world_from_cam = f.has_pose ? f.world_from_cam : Sim3d::Identity();
  q.focal_px = f.focal_px;
  q.num_features = static_cast<int>(f.descriptors.size());
  q.descriptors.resize(f.descriptors.size() * 32);
  if (!q.descriptors.empty()) {
    std::memcpy(q.descriptors.data(), f.descriptors.data(), q.descriptors.size());
  }
  q.keypoints = f.keypoints;
  q.depths = f.depths;
  return q;
}

// Exact equality (loaded values against the quantised expectation).
void ExpectSame(const StoredKeyframe& a, const StoredKeyframe& b) {
  EXPECT_EQ(a.session, b.session);
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.timestamp, b.timestamp);
  EXPECT_EQ(a.has_pose, b.has_pose);
  EXPECT_EQ(a.raw_world_from_cam.ToVector(), b.raw_world_from_cam.ToVector());
  EXPECT_EQ(a.focal_px, b.focal_px);
  EXPECT_EQ(a.num_features, b.num_features);
  EXPECT_EQ(a.descriptors, b.descriptors);
  EXPECT_EQ(a.keypoints, b.keypoints);
  EXPECT_EQ(a.depths, b.depths);
}

// Loaded values against the original floats, within the tolerances packed_keyframe.h documents.
void ExpectWithinQuantisation(const StoredKeyframe& loaded, const StoredKeyframe& put) {
  EXPECT_EQ(loaded.id, put.id);
  EXPECT_EQ(loaded.timestamp, put.timestamp);
  EXPECT_EQ(loaded.descriptors, put.descriptors);
  ASSERT_EQ(loaded.has_pose, put.has_pose);
  if (put.has_pose) {
    const Sim3d& a = loaded.raw_world_from_cam;
    const Sim3d& b = put.raw_world_from_cam;
    EXPECT_LT((a.translation - b.translation).norm(), 1e-6 * (1.0 + b.translation.norm()));
    EXPECT_NEAR(a.scale, b.scale, 1e-6 * b.scale);
    EXPECT_LT(a.rotation.angularDistance(b.rotation), 1e-4);
  }
  ASSERT_EQ(loaded.keypoints.size(), put.keypoints.size());
  float max_kp = 0.0f;
  for (float v : put.keypoints) max_kp = std::max(max_kp, std::abs(v));
  for (size_t i = 0; i < put.keypoints.size(); ++i) {
    // Step 2^e_k with the codes in int16: at most max |x| / 32767 / 2 (+ float rounding).
    EXPECT_NEAR(loaded.keypoints[i], put.keypoints[i], max_kp / 32767.0f + 1e-7f);
  }
  ASSERT_EQ(loaded.depths.size(), put.depths.size());
  for (size_t i = 0; i < put.depths.size(); ++i) {
    if (put.depths[i] > 0) {
      EXPECT_NEAR(loaded.depths[i], put.depths[i], 5e-4f * put.depths[i]);
    } else {
      EXPECT_EQ(loaded.depths[i], 0.0f);
    }
  }
}

// A keyframe with arbitrary (not exactly representable) floats.
StoredKeyframe MakeRandomKeyframe(int64_t session, int64_t id, int k, bool depths, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> kp(-0.9f, 0.9f);
  std::uniform_real_distribution<float> depth(0.3f, 80.0f);
  std::uniform_int_distribution<int> byte(0, 255);
  StoredKeyframe kf = MakeKeyframe(session, id, k, depths);
  kf.timestamp = 1234.56789 + 0.0333 * static_cast<double>(id);
  kf.focal_px = 718.856f;
  for (auto& b : kf.descriptors) b = static_cast<uint8_t>(byte(rng));
  for (auto& v : kf.keypoints) v = kp(rng);
  for (auto& d : kf.depths) d = depth(rng);
  if (depths && k > 2) kf.depths[1] = 0.0f;  // unknown
  Vector7d t;
  t << 3.7, -12.25, 0.4, 0.3, -1.1, 2.0, 0.17;
  kf.raw_world_from_cam = Sim3d::Exp(t * (1.0 + 0.01 * static_cast<double>(id)));
  return kf;
}

std::string ReadCommittedUserVersion(const std::filesystem::path& path) {
  sqlite3* db = nullptr;
  if (sqlite3_open(path.c_str(), &db) != SQLITE_OK) return "cannot open";
  sqlite3_stmt* st = nullptr;
  std::string out = "no row";
  sqlite3_prepare_v2(db, "PRAGMA user_version", -1, &st, nullptr);
  if (sqlite3_step(st) == SQLITE_ROW) out = std::to_string(sqlite3_column_int(st, 0));
  sqlite3_finalize(st);
  sqlite3_close(db);
  return out;
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
  for (size_t i = 0; i < loaded.size(); ++i) {
    ExpectSame(loaded[i], Quantised(written[i]));
    ExpectWithinQuantisation(loaded[i], written[i]);
  }
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

// Paths that cannot hold a map are refused before SQLite is asked, whose words were "disk I/O
// error" (/dev/null) or "attempt to write a readonly database" while reading a PRAGMA.
TEST(MapDatabase, DevicesFoldersAndMissingFoldersAreRefusedBeforeSqlite) {
  const auto dir = test::TempDir();
  const auto message = [](const std::filesystem::path& path) {
    try {
      MapDatabase::Open(path);
    } catch (const MapDatabaseError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message("/dev/null"),
            "/dev/null: expected a map database file (a regular file or a new file name), got a "
            "device, FIFO or socket");
  EXPECT_NE(message(dir).find("got a directory"), std::string::npos) << message(dir);
  EXPECT_NE(message(dir / "missing" / "map.db").find("missing"), std::string::npos);
  if (::geteuid() != 0) {  // root writes anywhere
    std::filesystem::create_directories(dir / "ro");
    std::filesystem::permissions(
        dir / "ro", std::filesystem::perms::owner_read | std::filesystem::perms::owner_exec);
    const std::string ro = message(dir / "ro" / "map.db");
    std::filesystem::permissions(dir / "ro", std::filesystem::perms::owner_all);
    EXPECT_NE(ro.find("expected a writable folder"), std::string::npos) << ro;
  }
  EXPECT_EQ(message(dir / "map.db"), "no error");
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

// A schema-1 file (no focal_px / has_pose columns) is migrated in place on open (through schema 2
// to 3); its keyframes read back with focal 0 (unknown) and a pose, and the file reports schema 3
// afterwards.
TEST(MapDatabase, SchemaOneIsMigratedToThree) {
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
    StoredKeyframe expected = kf;
    expected.timestamp = 0.7;
    expected.focal_px = 0.0f;
    ExpectSame(back[0], Quantised(expected));
    StoredKeyframe fresh = MakeKeyframe(map->BeginSession("new"), 1, 2, false);
    fresh.focal_px = 300.0f;
    map->PutKeyframe(fresh);
  }
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_prepare_v2(db, "PRAGMA user_version", -1, &st, nullptr);
  ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(st, 0), 3);
  sqlite3_finalize(st);
  sqlite3_close(db);
  EXPECT_EQ(MapDatabase::Open(path)->LoadKeyframes(2).at(0).focal_px, 300.0f);
}

// Put -> Load -> Put into a second map stores the same bytes: the loaded (quantised) values pack
// to the record they came from, so memory -> map -> memory -> map is exact.
TEST(MapDatabase, RecordRoundTripIsByteExact) {
  const auto dir = test::TempDir();
  auto first = MapDatabase::Open(dir / "first.db");
  auto second = MapDatabase::Open(dir / "second.db");
  const int64_t s1 = first->BeginSession("a");
  const int64_t s2 = second->BeginSession("b");
  ASSERT_EQ(s1, s2);
  std::vector<StoredKeyframe> put;
  for (int i = 0; i < 12; ++i) {
    put.push_back(MakeRandomKeyframe(s1, i, i == 0 ? 0 : 15 + 7 * i, i % 3 != 0, 100u + i));
    if (i == 4) {
      put.back().has_pose = false;
      put.back().raw_world_from_cam = Sim3d::Identity();
    }
    first->PutKeyframe(put.back());
  }
  const auto loaded = first->LoadKeyframes(s1);
  ASSERT_EQ(loaded.size(), put.size());
  for (const auto& kf : loaded) second->PutKeyframe(kf);
  const auto reloaded = second->LoadKeyframes(s2);
  ASSERT_EQ(reloaded.size(), put.size());
  for (size_t i = 0; i < put.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(second->LoadRecordBytes(s2, put[i].id), first->LoadRecordBytes(s1, put[i].id));
    ExpectSame(reloaded[i], loaded[i]);
    ExpectSame(loaded[i], Quantised(put[i]));
    ExpectWithinQuantisation(loaded[i], put[i]);
  }
  EXPECT_TRUE(loaded[0].keypoints.empty());
  EXPECT_TRUE(loaded[3].depths.empty());
  EXPECT_FALSE(loaded[4].has_pose);
  EXPECT_EQ(loaded[4].raw_world_from_cam.ToVector(), Sim3d::Identity().ToVector());
}

// The blob is exactly PackedKeyframe::Pack(fields).bytes(), the detector's in-memory bytes; at
// K = 15 with depths that is 618 bytes (588 without depths).
TEST(MapDatabase, StoredBytesArePackedKeyframeBytes) {
  auto map = MapDatabase::Open(test::TempDir() / "map.db");
  const int64_t s = map->BeginSession("s");
  const StoredKeyframe with = MakeRandomKeyframe(s, 1, 15, true, 7u);
  const StoredKeyframe without = MakeRandomKeyframe(s, 2, 15, false, 8u);
  StoredKeyframe big = MakeRandomKeyframe(s, 3, 500, true, 9u);
  big.focal_px = 0.0f;
  const std::vector<const StoredKeyframe*> all = {&with, &without, &big};
  for (const auto* kf : all) map->PutKeyframe(*kf);
  for (const auto* kf : all) {
    const PackedKeyframe packed = PackedKeyframe::Pack(ToFields(*kf));
    const std::vector<uint8_t> expected(packed.bytes().begin(), packed.bytes().end());
    EXPECT_EQ(map->LoadRecordBytes(s, kf->id), expected) << kf->id;
  }
  EXPECT_EQ(map->LoadRecordBytes(s, 1).size(), 618u);
  EXPECT_EQ(map->LoadRecordBytes(s, 2).size(), 588u);
  EXPECT_EQ(map->LoadRecordBytes(s, 3).size(), 48u + 500u * 38u);
  EXPECT_THROW(map->LoadRecordBytes(s, 99), MapDatabaseError);
  EXPECT_THROW(map->LoadRecordBytes(s + 1, 1), MapDatabaseError);
  // PutRecord stores a packed record's bytes as they are (what the detector keeps), and refuses
  // a duplicate id like PutKeyframe.
  StoredKeyframe other = MakeRandomKeyframe(s, 4, 15, true, 10u);
  const PackedKeyframe packed = PackedKeyframe::Pack(ToFields(other));
  map->PutRecord(s, packed);
  EXPECT_EQ(map->LoadRecordBytes(s, 4),
            std::vector<uint8_t>(packed.bytes().begin(), packed.bytes().end()));
  EXPECT_THROW(map->PutRecord(s, packed), std::invalid_argument);
  const int64_t s2 = map->BeginSession("t");
  map->PutRecord(s2, packed);  // the same id in another session is a different keyframe
  EXPECT_EQ(map->LoadRecordBytes(s2, 4), map->LoadRecordBytes(s, 4));
  map->Flush();
  EXPECT_EQ(map->LoadKeyframes(s).size(), 4u);
}

// A keyframe that cannot be packed (non-finite keypoint) is refused before anything is written.
TEST(MapDatabase, UnpackableKeyframeIsRejected) {
  auto map = MapDatabase::Open(test::TempDir() / "map.db", MapDatabaseOptions{.commit_every = 3});
  const int64_t s = map->BeginSession("s");
  map->PutKeyframe(MakeKeyframe(s, 0, 15, true));
  StoredKeyframe bad = MakeKeyframe(s, 1, 15, true);
  bad.keypoints[3] = std::nanf("");
  EXPECT_THROW(map->PutKeyframe(bad), std::invalid_argument);
  map->Flush();
  EXPECT_EQ(map->CountKeyframes(), 1);
}

namespace {
// A schema-2 file made by raw SQL (one column per field), as sparseloop wrote it before schema 3.
void WriteSchemaTwoFile(const std::filesystem::path& path, const std::vector<StoredKeyframe>& kfs) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  const std::string v2 = fmt::format(
      "PRAGMA application_id={};PRAGMA user_version=2;"
      "CREATE TABLE sessions(id INTEGER PRIMARY KEY, created_unix REAL NOT NULL, label TEXT);"
      "CREATE TABLE keyframes(session INTEGER NOT NULL REFERENCES sessions(id),"
      " id INTEGER NOT NULL, timestamp REAL NOT NULL, pose BLOB NOT NULL,"
      " num_features INTEGER NOT NULL, descriptors BLOB NOT NULL, keypoints BLOB NOT NULL,"
      " depths BLOB NOT NULL, focal_px REAL NOT NULL DEFAULT 0,"
      " has_pose INTEGER NOT NULL DEFAULT 1, PRIMARY KEY(session, id));"
      "CREATE TABLE loops(session INTEGER NOT NULL, query INTEGER NOT NULL,"
      " match_session INTEGER NOT NULL, match INTEGER NOT NULL, inliers INTEGER NOT NULL,"
      " score REAL NOT NULL, relative BLOB NOT NULL, accepted INTEGER NOT NULL);"
      "INSERT INTO sessions VALUES(1, 0, 'old');",
      MapDatabase::kApplicationId);
  ASSERT_EQ(sqlite3_exec(db, v2.c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
  for (const auto& kf : kfs) {
    sqlite3_stmt* st = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(db, "INSERT INTO keyframes VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                                 -1, &st, nullptr),
              SQLITE_OK);
    const Vector8d pose = kf.raw_world_from_cam.ToVector();
    sqlite3_bind_int64(st, 1, kf.session);
    sqlite3_bind_int64(st, 2, kf.id);
    sqlite3_bind_double(st, 3, kf.timestamp);
    sqlite3_bind_blob(st, 4, pose.data(), 64, SQLITE_TRANSIENT);
    sqlite3_bind_int(st, 5, kf.num_features);
    sqlite3_bind_blob(st, 6, kf.descriptors.empty() ? "" : (const void*)kf.descriptors.data(),
                      static_cast<int>(kf.descriptors.size()), SQLITE_TRANSIENT);
    sqlite3_bind_blob(st, 7, kf.keypoints.empty() ? "" : (const void*)kf.keypoints.data(),
                      static_cast<int>(kf.keypoints.size() * 4), SQLITE_TRANSIENT);
    sqlite3_bind_blob(st, 8, kf.depths.empty() ? "" : (const void*)kf.depths.data(),
                      static_cast<int>(kf.depths.size() * 4), SQLITE_TRANSIENT);
    sqlite3_bind_double(st, 9, kf.focal_px);
    sqlite3_bind_int(st, 10, kf.has_pose ? 1 : 0);
    ASSERT_EQ(sqlite3_step(st), SQLITE_DONE);
    sqlite3_finalize(st);
  }
  sqlite3_close(db);
}

std::vector<std::string> TableNamesAndKeyframeColumns(const std::filesystem::path& path) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  std::vector<std::string> out;
  for (const char* sql : {"SELECT name FROM sqlite_master WHERE type='table' ORDER BY name",
                          "SELECT name FROM pragma_table_info('keyframes') ORDER BY cid"}) {
    sqlite3_stmt* st = nullptr;
    EXPECT_EQ(sqlite3_prepare_v2(db, sql, -1, &st, nullptr), SQLITE_OK);
    while (sqlite3_step(st) == SQLITE_ROW) {
      out.emplace_back(reinterpret_cast<const char*>(sqlite3_column_text(st, 0)));
    }
    sqlite3_finalize(st);
    out.emplace_back("|");
  }
  sqlite3_close(db);
  return out;
}
}  // namespace

// A schema-2 file is migrated to 3 on open (one transaction): the loaded values are the
// packed-quantised originals, the file reports schema 3 with the new table layout, and opening it
// again changes nothing.
TEST(MapDatabase, SchemaTwoIsMigratedToThree) {
  const auto path = test::TempDir() / "v2.db";
  std::vector<StoredKeyframe> old = {MakeRandomKeyframe(1, 3, 15, true, 21u),
                                     MakeRandomKeyframe(1, 8, 40, false, 22u)};
  old[1].has_pose = false;  // schema 2 stored a pose blob anyway
  old[1].focal_px = 0.0f;
  WriteSchemaTwoFile(path, old);
  ASSERT_EQ(ReadCommittedUserVersion(path), "2");

  std::vector<std::vector<uint8_t>> bytes;
  {
    auto map = MapDatabase::Open(path);
    const auto back = map->LoadKeyframes(1);
    ASSERT_EQ(back.size(), 2u);
    for (size_t i = 0; i < 2; ++i) {
      SCOPED_TRACE(i);
      ExpectSame(back[i], Quantised(old[i]));
      ExpectWithinQuantisation(back[i], old[i]);
      const PackedKeyframe packed = PackedKeyframe::Pack(ToFields(old[i]));
      bytes.push_back(map->LoadRecordBytes(1, old[i].id));
      EXPECT_EQ(bytes.back(), std::vector<uint8_t>(packed.bytes().begin(), packed.bytes().end()));
    }
    EXPECT_EQ(bytes[0].size(), 618u);
    EXPECT_EQ(map->Sessions(), (std::vector<int64_t>{1}));
  }
  EXPECT_EQ(ReadCommittedUserVersion(path), "3");
  const std::vector<std::string> layout = {"keyframes", "loops",     "sessions", "|", "session",
                                           "id",        "timestamp", "record",   "|"};
  EXPECT_EQ(TableNamesAndKeyframeColumns(path), layout);

  // Reopening does nothing more: same version, same layout, same bytes; and the map is writable.
  {
    auto map = MapDatabase::Open(path);
    EXPECT_EQ(map->LoadRecordBytes(1, 3), bytes[0]);
    EXPECT_EQ(map->LoadRecordBytes(1, 8), bytes[1]);
    map->PutKeyframe(MakeKeyframe(map->BeginSession("new"), 0, 15, true));
  }
  EXPECT_EQ(ReadCommittedUserVersion(path), "3");
  EXPECT_EQ(TableNamesAndKeyframeColumns(path), layout);
  EXPECT_EQ(MapDatabase::Open(path)->LoadAllKeyframes().size(), 3u);
}

// A schema-2 row that cannot be packed fails the migration with a MapDatabaseError naming the
// row, and the file stays at schema 2, unchanged.
TEST(MapDatabase, FailedMigrationLeavesTheFileAtSchemaTwo) {
  const auto path = test::TempDir() / "v2.db";
  std::vector<StoredKeyframe> old = {MakeKeyframe(1, 1, 15, true), MakeKeyframe(1, 2, 15, true)};
  old[1].keypoints.pop_back();  // inconsistent with num_features
  WriteSchemaTwoFile(path, old);
  try {
    MapDatabase::Open(path);
    FAIL() << "no throw";
  } catch (const MapDatabaseError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path.string()), std::string::npos) << what;
    EXPECT_NE(what.find("session 1, id 2"), std::string::npos) << what;
  }
  EXPECT_EQ(ReadCommittedUserVersion(path), "2");
  const std::vector<std::string> v2_tables = {"keyframes", "loops", "sessions", "|"};
  const auto layout = TableNamesAndKeyframeColumns(path);
  EXPECT_EQ(std::vector<std::string>(layout.begin(), layout.begin() + 4), v2_tables);
  EXPECT_EQ(layout.size(), 4u + 10u + 1u);  // the ten schema-2 columns
}

// A record blob cut short (raw SQL) is a MapDatabaseError naming the file, session, id and why.
TEST(MapDatabase, CorruptRecordNamesSessionAndId) {
  const auto path = test::TempDir() / "map.db";
  {
    auto map = MapDatabase::Open(path);
    const int64_t s = map->BeginSession("s");
    for (int i = 0; i < 5; ++i) map->PutKeyframe(MakeKeyframe(s, i, 15, true));
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db,
                         "UPDATE keyframes SET record = substr(record, 1, 600)"
                         " WHERE session = 1 AND id = 3",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  EXPECT_EQ(sqlite3_changes(db), 1);
  sqlite3_close(db);
  auto map = MapDatabase::Open(path);
  EXPECT_EQ(map->LoadRecordBytes(1, 3).size(), 600u);
  for (int all = 0; all < 2; ++all) {
    try {
      if (all) {
        map->LoadAllKeyframes();
      } else {
        map->LoadKeyframes(1);
      }
      FAIL() << "no throw";
    } catch (const MapDatabaseError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path.string()), std::string::npos) << what;
      EXPECT_NE(what.find("session 1, id 3"), std::string::npos) << what;
      EXPECT_NE(what.find("need 618 bytes, got 600"), std::string::npos) << what;
    }
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
  for (int64_t i = 0; i <= last_committed; ++i) {
    ExpectSame(loaded[i], Quantised(MakeKeyframe(1, i, 15, true)));
  }
  // And the map stays writable.
  map->PutKeyframe(MakeKeyframe(1, static_cast<int64_t>(loaded.size()), 15, true));
}

}  // namespace
}  // namespace sparseloop
