#pragma once
// The "rosbag:FILE.bag?image=TOPIC[&camera_info=TOPIC][&pose=TOPIC][&gt=TOPIC]" dataset spec
// (docs/FORMATS.md, "rosbag:"), parsed once for the bag reader (bag module) and for the CLI, which
// must know before opening the bag whether raw poses come from a topic. Needs no ROS.
#include <string>

namespace sparseloop {

struct RosbagSpec {
  std::string file;         // FILE.bag
  std::string image;        // required
  std::string camera_info;  // empty: the image topic's sibling .../camera_info, if in the bag
  std::string pose;         // raw vSLAM poses; empty: none
  std::string gt;           // ground truth; empty: none
};

// True when `spec` starts with "rosbag:".
bool IsRosbagSpec(const std::string& spec);

// Throws std::invalid_argument naming the spec and the key: not "rosbag:", no file, unknown key,
// a topic that does not start with '/', no image topic.
RosbagSpec ParseRosbagSpec(const std::string& spec);

}  // namespace sparseloop
