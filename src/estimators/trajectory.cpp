#include "traverse/estimators/trajectory.h"

#include <charconv>

#include "traverse/core/so3.h"
#include "traverse/io/atomic_file.h"
#include "traverse/io/csv.h"
#include "traverse/io/log_writer.h"

namespace traverse::est {
namespace {

std::vector<std::string> columns(bool with_cov, int wheels) {
  std::vector<std::string> c = {"x",  "y",  "z",  "qw", "qx", "qy", "qz",
                                "vx", "vy", "vz", "wx", "wy", "wz"};
  for (int i = 1; i <= wheels; ++i) c.push_back("xi" + std::to_string(i));
  for (const char* s : {"bx", "by", "bz"}) c.emplace_back(s);
  if (with_cov) {
    for (const char* s :
         {"sx", "sy", "sz", "sroll", "spitch", "syaw", "cxy", "cxz", "cyz", "crp", "cry", "cpy"}) {
      c.emplace_back(s);
    }
  }
  return c;
}

}  // namespace

io::Stream toStream(const Trajectory& tr) {
  io::Stream s;
  const int nw = tr.nodes.empty() ? 0 : static_cast<int>(tr.nodes.front().xi.size());
  s.columns = columns(tr.has_covariance, nw);
  const auto n = static_cast<Eigen::Index>(tr.nodes.size());
  s.t.resize(n);
  s.values.resize(n, static_cast<Eigen::Index>(s.columns.size()));
  for (Eigen::Index k = 0; k < n; ++k) {
    const TrajectoryNode& nd = tr.nodes[static_cast<size_t>(k)];
    s.t[k] = nd.t;
    auto row = s.values.row(k);
    row.head<3>() = nd.p_site.transpose();
    row.segment<4>(3) << nd.q_site_body.w(), nd.q_site_body.x(), nd.q_site_body.y(),
        nd.q_site_body.z();
    row.segment<3>(7) = nd.v_body.transpose();
    row.segment<3>(10) = nd.w_body.transpose();
    if (nd.xi.size() != static_cast<Eigen::Index>(nw))
      throw std::logic_error(tr.name + ": nodes with different wheel counts");
    row.segment(13, nw) = nd.xi.transpose();
    row.segment<3>(13 + nw) = nd.bias.transpose();
    if (tr.has_covariance) {
      const Mat6d& C = nd.covariance;
      for (int i = 0; i < 6; ++i) row[16 + nw + i] = std::sqrt(std::max(0.0, C(i, i)));
      row.segment<6>(22 + nw) << C(0, 1), C(0, 2), C(1, 2), C(3, 4), C(3, 5), C(4, 5);
    }
  }
  return s;
}

Trajectory fromStream(const io::Stream& s, const std::string& name) {
  Trajectory tr;
  tr.name = name;
  tr.has_covariance = s.has("sx");
  int nw = 0;
  while (s.has("xi" + std::to_string(nw + 1))) ++nw;
  if (nw > rover::kMaxWheels) throw std::invalid_argument(name + ": too many xi columns");
  const auto expected = columns(tr.has_covariance, nw);
  for (size_t c = 0; c < expected.size() && c < s.columns.size(); ++c) {
    if (s.columns[c] != expected[c])
      throw std::invalid_argument(name + ": unexpected column " + s.columns[c]);
  }
  tr.nodes.resize(static_cast<size_t>(s.size()));
  for (Eigen::Index k = 0; k < s.size(); ++k) {
    TrajectoryNode& nd = tr.nodes[static_cast<size_t>(k)];
    const auto row = s.values.row(k);
    nd.t = s.t[k];
    nd.p_site = row.head<3>().transpose();
    nd.q_site_body = Quatd(row[3], row[4], row[5], row[6]).normalized();
    nd.v_body = row.segment<3>(7).transpose();
    nd.w_body = row.segment<3>(10).transpose();
    nd.xi = row.segment(13, nw).transpose();
    nd.bias = row.segment<3>(13 + nw).transpose();
    if (tr.has_covariance) {
      Mat6d& C = nd.covariance;
      C.setZero();
      for (int i = 0; i < 6; ++i) C(i, i) = row[16 + nw + i] * row[16 + nw + i];
      if (s.has("cxy")) {
        const int o = 22 + nw;
        C(0, 1) = C(1, 0) = row[o], C(0, 2) = C(2, 0) = row[o + 1], C(1, 2) = C(2, 1) = row[o + 2];
        C(3, 4) = C(4, 3) = row[o + 3], C(3, 5) = C(5, 3) = row[o + 4];
        C(4, 5) = C(5, 4) = row[o + 5];
      }
    }
  }
  return tr;
}

Trajectory asWritten(const Trajectory& tr) {
  const Trajectory back = fromStream(toStream(tr), tr.name);
  Trajectory out = tr;
  for (size_t k = 0; k < out.nodes.size(); ++k) {
    out.nodes[k].q_site_body = back.nodes[k].q_site_body;
    out.nodes[k].covariance = back.nodes[k].covariance;
  }
  return out;
}

void writeTrajectory(const std::filesystem::path& dir, const Trajectory& tr) {
  std::filesystem::create_directories(dir);
  io::writeStream(dir / (tr.name + ".csv"), toStream(tr));
  // TUM: t tx ty tz qx qy qz qw, space separated, shortest round-trip numbers.
  std::string text = "# t tx ty tz qx qy qz qw\n";
  char buf[32];
  auto put = [&](double v, char sep) {
    text.append(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
    text.push_back(sep);
  };
  for (const TrajectoryNode& nd : tr.nodes) {
    const Quatd& q = nd.q_site_body;
    for (double v : {nd.t, nd.p_site.x(), nd.p_site.y(), nd.p_site.z(), q.x(), q.y(), q.z()})
      put(v, ' ');
    put(q.w(), '\n');
  }
  io::writeFileAtomically(dir / (tr.name + ".tum"), text);
}

Trajectory readTrajectory(const std::filesystem::path& dir, const std::string& name) {
  return fromStream(io::readCsv(dir / (name + ".csv"), io::StreamSpec{}), name);
}

void addOdometryScaleCovariance(Trajectory* trajectory, double variance) {
  if (variance <= 0.0 || !trajectory->has_covariance || trajectory->nodes.empty()) return;
  const Vec3d x0 = trajectory->nodes.front().p_site;
  for (TrajectoryNode& n : trajectory->nodes) {
    const Vec3d d = n.p_site - x0;
    n.covariance.topLeftCorner<3, 3>() += variance * d * d.transpose();
  }
}

void addMountingCovariance(Trajectory* trajectory, double sigma_rad) {
  if (sigma_rad <= 0.0 || !trajectory->has_covariance || trajectory->nodes.empty()) return;
  Mat3d J = Mat3d::Zero();
  const double var = sigma_rad * sigma_rad;
  for (size_t k = 0; k < trajectory->nodes.size(); ++k) {
    TrajectoryNode& n = trajectory->nodes[k];
    if (k > 0) {
      const TrajectoryNode& prev = trajectory->nodes[k - 1];
      J -= prev.q_site_body.toRotationMatrix() * so3::skew(prev.v_body) * (n.t - prev.t);
    }
    n.covariance.topLeftCorner<3, 3>() += var * J * J.transpose();
  }
}

}  // namespace traverse::est
