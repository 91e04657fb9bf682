#include "sparseloop/posegraph/g2o.h"

#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <sstream>

#include <fmt/format.h>
#include <Eigen/Dense>

#include "sparseloop/core/error.h"
#include "sparseloop/core/quaternion.h"
#include "sparseloop/core/text_lines.h"

namespace sparseloop {
namespace {

enum class Dim { kUnknown, k2, k3 };

Eigen::Quaterniond FromRollPitchYaw(double roll, double pitch, double yaw) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                            Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()));
}

Eigen::Quaterniond FromYaw(double yaw) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
}

double YawOf(const Eigen::Quaterniond& q) {
  return std::atan2(2.0 * (q.w() * q.z() + q.x() * q.y()),
                    1.0 - 2.0 * (q.y() * q.y() + q.z() * q.z()));
}

// Upper-triangular 6x6 -> symmetric, in [translation, rotation] order.
Eigen::Matrix<double, 6, 6> UpperToSymmetric(const std::vector<double>& v) {
  Eigen::Matrix<double, 6, 6> m;
  size_t k = 0;
  for (int r = 0; r < 6; ++r)
    for (int c = r; c < 6; ++c) m(r, c) = m(c, r) = v[k++];
  return m;
}

Matrix7d Embed6(const Eigen::Matrix<double, 6, 6>& info6, double rotation_factor) {
  Matrix7d info = Matrix7d::Zero();
  info.topLeftCorner<6, 6>() = info6;
  info.block<3, 3>(0, 3) *= rotation_factor;
  info.block<3, 3>(3, 0) *= rotation_factor;
  info.block<3, 3>(3, 3) *= rotation_factor * rotation_factor;
  info(6, 6) = 1.0;  // scale residual is identically zero in SE(3) graphs
  return info;
}

struct Parser {
  std::string name;
  int line_no = 0;
  std::istringstream fields;

  [[noreturn]] void Fail(const std::string& expected, const std::string& got) const {
    throw FileError(name, line_no, expected, got);
  }
  double Number(const char* what) {
    std::string token;
    if (!(fields >> token)) Fail(fmt::format("a number ({})", what), "end of line");
    try {
      size_t used = 0;
      const double v = std::stod(token, &used);
      if (used != token.size() || !std::isfinite(v)) throw std::invalid_argument(token);
      return v;
    } catch (const std::exception&) {
      Fail(fmt::format("a number ({})", what), "'" + token + "'");
    }
  }
  // A position coordinate: also within 1e12 (a vertex at 1e300 made every cost inf and the solve
  // "converge" on nan).
  double Coordinate(const char* what) {
    const double v = Number(what);
    if (std::abs(v) > 1e12)
      Fail(fmt::format("a coordinate ({}) within +-1e12", what), fmt::format("{}", v));
    return v;
  }
  int64_t Id(const char* what) {
    std::string token;
    if (!(fields >> token)) Fail(fmt::format("an integer id ({})", what), "end of line");
    try {
      size_t used = 0;
      const long long v = std::stoll(token, &used);
      if (used != token.size()) throw std::invalid_argument(token);
      return v;
    } catch (const std::exception&) {
      Fail(fmt::format("an integer id ({})", what), "'" + token + "'");
    }
  }
  void End() {
    std::string extra;
    if (fields >> extra) Fail("end of line", "'" + extra + "'");
  }
  // Separate statements: the evaluation order of constructor arguments is unspecified.
  Eigen::Vector3d Translation() {
    const double x = Coordinate("x");
    const double y = Coordinate("y");
    const double z = Coordinate("z");
    return {x, y, z};
  }
  Eigen::Quaterniond Quaternion() {
    const double qx = Number("qx"), qy = Number("qy"), qz = Number("qz"), qw = Number("qw");
    const double norm = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
    if (std::abs(norm - 1.0) > 1e-2) Fail("a unit quaternion", fmt::format("norm {}", norm));
    return QuaternionFromXyzw(qx, qy, qz, qw).normalized();
  }
  Eigen::Quaterniond RollPitchYaw() {
    const double roll = Number("roll"), pitch = Number("pitch"), yaw = Number("yaw");
    return FromRollPitchYaw(roll, pitch, yaw);
  }
  std::vector<double> Numbers(int count, const char* what) {
    std::vector<double> v(count);
    for (int i = 0; i < count; ++i) v[i] = Number(what);
    return v;
  }
  // An edge's information matrix as written in the file must be positive definite: an all-zero
  // or singular one would give the edge no (or a degenerate) weight instead of an error.
  template <typename Matrix>
  void RequirePositiveDefinite(const Matrix& information) const {
    if (information.isZero(0.0)) Fail("a positive-definite information matrix", "all zeros");
    const Eigen::LLT<Matrix> llt(information);
    if (llt.info() != Eigen::Success) {
      const Eigen::SelfAdjointEigenSolver<Matrix> eig(information, Eigen::EigenvaluesOnly);
      Fail("a positive-definite information matrix",
           fmt::format("smallest eigenvalue {:.6g}", eig.eigenvalues().minCoeff()));
    }
  }
};

// What a g2o file holds, record by record (ReadG2o): one method per record kind, then the
// vertices completed (edges-only files) and the graph built, each error with its line.
struct G2oRecords {
  explicit G2oRecords(Parser& parser) : p(parser) {}
  Parser& p;
  Dim dim = Dim::kUnknown;
  std::map<int64_t, Sim3d> vertices;
  std::vector<int64_t> vertex_order;
  std::vector<PoseGraphEdge> edges;
  std::vector<int> edge_lines;
  std::optional<int64_t> fixed;
  int fixed_line = 0;

  void SetDim(Dim d) {
    if (dim != Dim::kUnknown && dim != d) p.Fail("records of one dimension (2D or 3D)", "a mix");
    dim = d;
  }
  void AddVertex(int64_t id, const Sim3d& pose) {
    if (vertices.count(id)) p.Fail("a new vertex id", fmt::format("duplicate id {}", id));
    vertices[id] = pose;
    vertex_order.push_back(id);
  }
  void AddEdge(const PoseGraphEdge& e) {
    edges.push_back(e);
    edge_lines.push_back(p.line_no);
  }

  // One line's record after its tag; false for an unknown tag.
  bool Read(const std::string& tag) {
    if (tag == "VERTEX_SE3:QUAT" || tag == "VERTEX3") {
      ReadVertex3(tag == "VERTEX3");
    } else if (tag == "VERTEX_SE2") {
      SetDim(Dim::k2);
      const int64_t id = p.Id("vertex id");
      const double x = p.Coordinate("x"), y = p.Coordinate("y"), theta = p.Number("theta");
      p.End();
      AddVertex(id, Sim3d(1.0, FromYaw(theta), Eigen::Vector3d(x, y, 0.0)));
    } else if (tag == "EDGE_SE3:QUAT" || tag == "EDGE3") {
      ReadEdge3(tag == "EDGE3");
    } else if (tag == "EDGE_SE2") {
      ReadEdgeSe2();
    } else if (tag == "FIX") {
      fixed = p.Id("fixed vertex id");
      fixed_line = p.line_no;
      p.End();
    } else {
      return false;
    }
    return true;
  }

  // VERTEX_SE3:QUAT (quaternion) or VERTEX3 (roll, pitch, yaw).
  void ReadVertex3(bool euler) {
    SetDim(Dim::k3);
    const int64_t id = p.Id("vertex id");
    const Eigen::Vector3d t = p.Translation();
    const Eigen::Quaterniond q = euler ? p.RollPitchYaw() : p.Quaternion();
    p.End();
    AddVertex(id, Sim3d(1.0, q, t));
  }

  // EDGE_SE3:QUAT (quaternion; information on the quaternion's vector part, hence the factor
  // 0.5 for our rotation vector) or EDGE3 (roll, pitch, yaw).
  void ReadEdge3(bool euler) {
    SetDim(Dim::k3);
    PoseGraphEdge e;
    e.from = p.Id("from id");
    e.to = p.Id("to id");
    const Eigen::Vector3d t = p.Translation();
    const Eigen::Quaterniond q = euler ? p.RollPitchYaw() : p.Quaternion();
    const std::vector<double> upper = p.Numbers(21, "information");
    p.End();
    p.RequirePositiveDefinite(UpperToSymmetric(upper));
    e.from_from_to = Sim3d(1.0, q, t);
    e.information = Embed6(UpperToSymmetric(upper), euler ? 1.0 : 0.5);
    AddEdge(e);
  }

  void ReadEdgeSe2() {
    SetDim(Dim::k2);
    PoseGraphEdge e;
    e.from = p.Id("from id");
    e.to = p.Id("to id");
    const double x = p.Coordinate("x"), y = p.Coordinate("y"), theta = p.Number("theta");
    const std::vector<double> u = p.Numbers(6, "information");
    p.End();
    e.from_from_to = Sim3d(1.0, FromYaw(theta), Eigen::Vector3d(x, y, 0.0));
    const int idx[3] = {0, 1, 5};
    const double m[3][3] = {{u[0], u[1], u[2]}, {u[1], u[3], u[4]}, {u[2], u[4], u[5]}};
    p.RequirePositiveDefinite(Eigen::Matrix3d{
        {m[0][0], m[0][1], m[0][2]}, {m[1][0], m[1][1], m[1][2]}, {m[2][0], m[2][1], m[2][2]}});
    e.information.setZero();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) e.information(idx[r], idx[c]) = m[r][c];
    AddEdge(e);
  }

  // Every vertex the edges need: a file with VERTEX lines defines every vertex (an edge to an id
  // it never defined is a typo or a truncated file, not a vertex to invent); an edges-only file
  // is chained from its lowest id.
  void CompleteVertices() {
    if (!vertices.empty()) {
      for (size_t k = 0; k < edges.size(); ++k) {
        for (const int64_t id : {edges[k].from, edges[k].to}) {
          if (!vertices.count(id)) {
            throw FileError(p.name, edge_lines[k],
                            "an edge between vertices defined by VERTEX lines",
                            fmt::format("edge {} -> {}: vertex {} is not defined", edges[k].from,
                                        edges[k].to, id));
          }
        }
      }
    }
    if (vertices.empty()) {
      int64_t root = edges.front().from;
      for (const auto& e : edges) root = std::min({root, e.from, e.to});
      AddVertex(root, Sim3d());
    }
    bool changed = true;
    while (changed) {
      changed = false;
      for (const auto& e : edges) {
        const bool has_from = vertices.count(e.from) > 0;
        const bool has_to = vertices.count(e.to) > 0;
        if (has_from && !has_to) {
          AddVertex(e.to, vertices[e.from] * e.from_from_to);
          changed = true;
        } else if (!has_from && has_to) {
          AddVertex(e.from, vertices[e.to] * e.from_from_to.Inverse());
          changed = true;
        }
      }
    }
  }

  PoseGraph Build() const {
    PoseGraph graph(dim == Dim::k2 ? VertexType::kSe2 : VertexType::kSe3);
    // Insertion order by id (time order in every benchmark file).
    for (const auto& [id, pose] : vertices) graph.AddVertex(id, pose);
    for (size_t k = 0; k < edges.size(); ++k) {
      if (!vertices.count(edges[k].from) || !vertices.count(edges[k].to)) {
        throw FileError(p.name, edge_lines[k], "an edge connected to the graph",
                        fmt::format("edge {} -> {} unreachable", edges[k].from, edges[k].to));
      }
      if (edges[k].from == edges[k].to) {
        throw FileError(p.name, edge_lines[k], "an edge between two vertices",
                        fmt::format("self-edge on {}", edges[k].from));
      }
      try {
        graph.AddEdge(edges[k]);
      } catch (const std::invalid_argument& ex) {
        throw FileError(p.name, edge_lines[k], "a valid edge", ex.what());
      }
    }
    if (fixed) {
      if (!graph.HasVertex(*fixed)) {
        throw FileError(p.name, fixed_line, "FIX of a known vertex", fmt::format("id {}", *fixed));
      }
      graph.SetFixedVertex(*fixed);
    }
    return graph;
  }
};

}  // namespace

PoseGraph ReadG2o(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw FileError(path.string(), 0, "a readable g2o file", "cannot open");
  return ReadG2o(in, path.string());
}

PoseGraph ReadG2o(std::istream& in, const std::string& name) {
  Parser p;
  p.name = name;
  G2oRecords records(p);
  // The whole text, split as every reader splits lines (a BOM, "\r\n" and lone "\r" ends).
  const std::string text(std::istreambuf_iterator<char>(in), {});
  for (const std::string_view view : SplitLines(text)) {
    const std::string line(view);
    ++p.line_no;
    p.fields.clear();
    p.fields.str(line);
    std::string tag;
    if (!(p.fields >> tag) || tag[0] == '#') continue;
    if (!records.Read(tag)) {
      p.Fail("VERTEX_SE3:QUAT, EDGE_SE3:QUAT, VERTEX_SE2, EDGE_SE2, VERTEX3, EDGE3 or FIX",
             "'" + tag + "'");
    }
  }
  if (records.dim == Dim::kUnknown) throw FileError(name, 0, "at least one vertex or edge", "none");
  records.CompleteVertices();
  return records.Build();
}

void WriteG2o(std::ostream& out, const PoseGraph& graph) {
  const bool planar = graph.vertex_type() == VertexType::kSe2;
  out.precision(17);
  for (int64_t id : graph.VertexIds()) {
    const Sim3d& pose = graph.Pose(id);
    if (planar) {
      out << "VERTEX_SE2 " << id << ' ' << pose.translation.x() << ' ' << pose.translation.y()
          << ' ' << YawOf(pose.rotation) << '\n';
    } else {
      const auto q = QuaternionToXyzw(pose.rotation);
      out << "VERTEX_SE3:QUAT " << id << ' ' << pose.translation.x() << ' ' << pose.translation.y()
          << ' ' << pose.translation.z() << ' ' << q[0] << ' ' << q[1] << ' ' << q[2] << ' ' << q[3]
          << '\n';
    }
  }
  auto write_edge = [&](int64_t from, int64_t to, const Sim3d& z, const Matrix7d& info) {
    if (planar) {
      const int idx[3] = {0, 1, 5};
      out << "EDGE_SE2 " << from << ' ' << to << ' ' << z.translation.x() << ' '
          << z.translation.y() << ' ' << YawOf(z.rotation);
      for (int r = 0; r < 3; ++r)
        for (int c = r; c < 3; ++c) out << ' ' << info(idx[r], idx[c]);
      out << '\n';
      return;
    }
    Eigen::Matrix<double, 6, 6> i6 = info.topLeftCorner<6, 6>();
    i6.block<3, 3>(0, 3) *= 2.0;
    i6.block<3, 3>(3, 0) *= 2.0;
    i6.block<3, 3>(3, 3) *= 4.0;
    const auto q = QuaternionToXyzw(z.rotation);
    out << "EDGE_SE3:QUAT " << from << ' ' << to << ' ' << z.translation.x() << ' '
        << z.translation.y() << ' ' << z.translation.z() << ' ' << q[0] << ' ' << q[1] << ' '
        << q[2] << ' ' << q[3];
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) out << ' ' << i6(r, c);
    out << '\n';
  };
  for (const PoseGraphEdge& e : graph.edges())
    write_edge(e.from, e.to, e.from_from_to, e.information);
  for (const LoopConstraint& l : graph.loops()) {
    write_edge(l.match_id, l.query_id, l.match_from_query, l.weight * l.information);
  }
  if (graph.num_vertices() > 0 && graph.fixed_vertex() != graph.VertexIds().front()) {
    out << "FIX " << graph.fixed_vertex() << '\n';
  }
}

}  // namespace sparseloop
