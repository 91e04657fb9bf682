#pragma once
// g2o / TORO pose-graph text files.
//
// Read: VERTEX_SE3:QUAT id x y z qx qy qz qw
//       EDGE_SE3:QUAT a b x y z qx qy qz qw I11 I12 .. I16 I22 .. I66   (upper triangle, 21)
//       VERTEX_SE2 id x y theta
//       EDGE_SE2 a b x y theta I11 I12 I13 I22 I23 I33
//       VERTEX3 id x y z roll pitch yaw       (TORO 3D)
//       EDGE3 a b x y z roll pitch yaw + 21 upper-triangle info   (TORO 3D, e.g. sphere2500.txt)
//       FIX id
// '#' comments and blank lines are skipped; anything else is a FileError naming the line.
// 2D and 3D records must not be mixed. Vertices that no VERTEX line gives (edges-only files such
// as kitti_00.g2o or sphere2500.txt) are initialised by chaining edge measurements from the
// lowest id (set to identity), in file order.
//
// Information mapping: g2o's SE3 error uses the quaternion vector part (about omega / 2), our
// residual the rotation vector omega, so rotation rows / columns of the information are scaled by
// 1/2 each on reading (and back on writing). TORO roll/pitch/yaw errors are taken as omega.
// All edges of a file become PoseGraph::edges() (g2o does not mark loops); loops of a PoseGraph
// are written as ordinary edges.
#include <filesystem>
#include <iosfwd>

#include "sparseloop/posegraph/pose_graph.h"

namespace sparseloop {

// Throws FileError for a missing, unreadable or malformed file.
PoseGraph ReadG2o(const std::filesystem::path& path);
// Parses from a stream; `name` is used in error messages.
PoseGraph ReadG2o(std::istream& in, const std::string& name);

// Writes SE2 graphs as VERTEX_SE2 / EDGE_SE2 and every other type as VERTEX_SE3:QUAT /
// EDGE_SE3:QUAT (the scale of Sim(3) vertices is dropped: g2o has no Sim3 text record).
void WriteG2o(std::ostream& out, const PoseGraph& graph);

}  // namespace sparseloop
