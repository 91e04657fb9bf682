#include "sparseloop/io/rosbag_spec.h"

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace sparseloop {
namespace {

TEST(RosbagSpec, ParsesEveryKeyInAnyOrder) {
  const RosbagSpec s = ParseRosbagSpec(
      "rosbag:/d/run "
      "1.bag?gt=/vicon/pose&image=/cam0/image_raw&pose=/orb/pose&camera_info=/c/info");
  EXPECT_EQ(s.file, "/d/run 1.bag");
  EXPECT_EQ(s.image, "/cam0/image_raw");
  EXPECT_EQ(s.pose, "/orb/pose");
  EXPECT_EQ(s.gt, "/vicon/pose");
  EXPECT_EQ(s.camera_info, "/c/info");
  const RosbagSpec minimal = ParseRosbagSpec("rosbag:a.bag?image=/i&");
  EXPECT_EQ(minimal.image, "/i");
  EXPECT_TRUE(minimal.pose.empty());
  EXPECT_TRUE(minimal.gt.empty());
  EXPECT_TRUE(minimal.camera_info.empty());
}

TEST(RosbagSpec, IsRosbagSpecLooksAtThePrefixOnly) {
  EXPECT_TRUE(IsRosbagSpec("rosbag:x"));
  EXPECT_FALSE(IsRosbagSpec("kitti:rosbag:x"));
  EXPECT_FALSE(IsRosbagSpec("images:dir"));
}

TEST(RosbagSpec, BadSpecsNameTheProblem) {
  const auto message = [](const std::string& spec) {
    try {
      ParseRosbagSpec(spec);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("kitti:dir").find("starts with 'rosbag:'"), std::string::npos);
  EXPECT_NE(message("rosbag:?image=/i").find("expected rosbag:FILE.bag"), std::string::npos);
  EXPECT_NE(message("rosbag:a.bag?imgae=/i").find("unknown key 'imgae'"), std::string::npos);
  EXPECT_NE(message("rosbag:a.bag?image=cam0").find("starting with '/'"), std::string::npos);
  EXPECT_NE(message("rosbag:a.bag?image=").find("image= needs a topic"), std::string::npos);
  EXPECT_NE(message("rosbag:a.bag?pose=/p").find("no image topic"), std::string::npos);
  EXPECT_NE(message("rosbag:a.bag").find("no image topic"), std::string::npos);
  // A key given twice silently used the last.
  EXPECT_NE(message("rosbag:a.bag?image=/a&image=/b").find("image= given twice ('/a' and '/b')"),
            std::string::npos)
      << message("rosbag:a.bag?image=/a&image=/b");
}

}  // namespace
}  // namespace sparseloop
