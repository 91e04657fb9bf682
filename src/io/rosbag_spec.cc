#include "sparseloop/io/rosbag_spec.h"

#include <algorithm>

#include "sparseloop/core/check.h"

namespace sparseloop {

bool IsRosbagSpec(const std::string& spec) { return spec.rfind("rosbag:", 0) == 0; }

RosbagSpec ParseRosbagSpec(const std::string& spec) {
  SL_CHECK_MSG(IsRosbagSpec(spec), "a rosbag spec starts with 'rosbag:', got '{}'", spec);
  const std::string rest = spec.substr(std::string("rosbag:").size());
  const size_t q = rest.find('?');
  RosbagSpec out;
  out.file = rest.substr(0, q);
  SL_CHECK_MSG(!out.file.empty(), "'{}': expected rosbag:FILE.bag?image=TOPIC[&pose=TOPIC...]",
               spec);
  if (q != std::string::npos) {
    const std::string query = rest.substr(q + 1);
    size_t start = 0;
    while (start <= query.size()) {
      const size_t amp = std::min(query.find('&', start), query.size());
      const std::string item = query.substr(start, amp - start);
      start = amp + 1;
      if (item.empty()) continue;
      const size_t eq = item.find('=');
      const std::string key = item.substr(0, eq);
      const std::string value = eq == std::string::npos ? "" : item.substr(eq + 1);
      std::string* field = key == "image"         ? &out.image
                           : key == "camera_info" ? &out.camera_info
                           : key == "pose"        ? &out.pose
                           : key == "gt"          ? &out.gt
                                                  : nullptr;
      SL_CHECK_MSG(field != nullptr, "'{}': unknown key '{}' (valid: image, camera_info, pose, gt)",
                   spec, key);
      SL_CHECK_MSG(!value.empty() && value.front() == '/',
                   "'{}': {}= needs a topic name starting with '/', got '{}'", spec, key, value);
      SL_CHECK_MSG(field->empty(), "'{}': {}= given twice ('{}' and '{}'); give each key once",
                   spec, key, *field, value);
      *field = value;
    }
  }
  SL_CHECK_MSG(!out.image.empty(), "'{}': no image topic (rosbag:FILE.bag?image=/cam0/image_raw)",
               spec);
  return out;
}

}  // namespace sparseloop
