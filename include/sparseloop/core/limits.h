#pragma once
// Bounds on the numbers the library takes from its users, one place for each.

namespace sparseloop {

// Largest |coordinate| of a position the library takes (trajectory files, keyframe poses): beyond
// any map in any unit (1e15 m is 7000 astronomical units), and small enough that sums of squares
// (alignment, distances) stay finite and a position fits the float of a stored keyframe.
inline constexpr double kMaxCoordinate = 1e15;

}  // namespace sparseloop
