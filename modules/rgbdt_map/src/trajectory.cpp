#include "rgbdt/rgbdt_map/trajectory.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/transform.hpp"

namespace rgbdt::rgbdt_map {

Trajectory::Trajectory(std::vector<TimedPose> poses) {
  for (const auto& p : poses) push_back(p);
}

void Trajectory::push_back(const TimedPose& pose) {
  if (!std::isfinite(pose.time_s)) throw std::invalid_argument("Trajectory: pose time is not finite");
  if (!poses_.empty() && !(pose.time_s > poses_.back().time_s)) {
    std::ostringstream os;
    os << "Trajectory: pose time " << pose.time_s << " s is not after the previous one ("
       << poses_.back().time_s << " s); expected strictly increasing times";
    throw std::invalid_argument(os.str());
  }
  poses_.push_back(pose);
}

Eigen::Isometry3d scale_motion(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double s) {
  const core::Vector6d delta = core::to_vector6(a.inverse() * b);
  return a * core::from_vector6(delta * s);
}

Eigen::Isometry3d Trajectory::pose_at(double t) const {
  if (poses_.empty()) throw std::logic_error("Trajectory::pose_at on an empty trajectory");
  if (poses_.size() == 1) return poses_.front().T_world_lidar;
  std::size_t hi = 1;
  if (t >= poses_.back().time_s) {
    hi = poses_.size() - 1;
  } else if (t > poses_.front().time_s) {
    const auto it = std::upper_bound(poses_.begin(), poses_.end(), t,
                                     [](double v, const TimedPose& p) { return v < p.time_s; });
    hi = static_cast<std::size_t>(it - poses_.begin());
  }
  const TimedPose& a = poses_[hi - 1];
  const TimedPose& b = poses_[hi];
  const double s = (t - a.time_s) / (b.time_s - a.time_s);
  if (s >= 0.0 && s <= 1.0) return core::interpolate(a.T_world_lidar, b.T_world_lidar, s);
  return scale_motion(a.T_world_lidar, b.T_world_lidar, s);
}

Trajectory read_trajectory_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw core::Error(path, "cannot open trajectory CSV (expected time_s,x,y,z,qx,qy,qz,qw)");
  Trajectory trajectory;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty() || line[0] == '#') continue;
    if (line_number == 1 && line.find_first_of("abcdefghijklmnopqrstuvwxyz") != std::string::npos) continue;
    std::stringstream ss(line);
    std::string cell;
    std::vector<double> values;
    while (std::getline(ss, cell, ',')) {
      try {
        values.push_back(std::stod(cell));
      } catch (const std::exception&) {
        throw core::Error(path, "line " + std::to_string(line_number) + ": '" + cell + "' is not a number");
      }
    }
    if (values.size() != 8) {
      throw core::Error(path, "line " + std::to_string(line_number) + " has " + std::to_string(values.size()) +
                                  " values, expected 8 (time_s,x,y,z,qx,qy,qz,qw)");
    }
    TimedPose pose;
    pose.time_s = values[0];
    try {
      const Eigen::Quaterniond q =
          core::quaternion_from_xyzw(Eigen::Vector4d(values[4], values[5], values[6], values[7]));
      pose.T_world_lidar = core::make_transform(q.normalized().toRotationMatrix(),
                                                Eigen::Vector3d(values[1], values[2], values[3]));
      trajectory.push_back(pose);
    } catch (const std::invalid_argument& e) {
      throw core::Error(path, "line " + std::to_string(line_number) + ": " + e.what());
    }
  }
  return trajectory;
}

void write_trajectory_csv(const std::string& path, const Trajectory& trajectory) {
  std::ostringstream out;
  out << "time_s,x,y,z,qx,qy,qz,qw\n" << std::setprecision(10);
  for (const auto& p : trajectory.poses()) {
    const Eigen::Vector3d t = p.T_world_lidar.translation();
    const Eigen::Vector4d q = core::quaternion_to_xyzw(Eigen::Quaterniond(p.T_world_lidar.rotation()));
    out << p.time_s << ',' << t.x() << ',' << t.y() << ',' << t.z() << ',' << q[0] << ',' << q[1] << ','
        << q[2] << ',' << q[3] << '\n';
  }
  // A reader sees the whole trajectory or none; write errors are thrown naming the file.
  core::write_file_atomic(path, out.str());
}

double trajectory_rmse_m(const Trajectory& estimate, const Trajectory& truth) {
  if (estimate.empty() || truth.empty()) throw std::invalid_argument("trajectory_rmse_m: empty trajectory");
  const double t0 = estimate.poses().front().time_s;
  const Eigen::Isometry3d T_truth_est = truth.pose_at(t0) * estimate.poses().front().T_world_lidar.inverse();
  double sum = 0.0;
  for (const auto& p : estimate.poses()) {
    const Eigen::Vector3d e = (T_truth_est * p.T_world_lidar).translation() - truth.pose_at(p.time_s).translation();
    sum += e.squaredNorm();
  }
  return std::sqrt(sum / static_cast<double>(estimate.size()));
}

double trajectory_ate_m(const Trajectory& estimate, const Trajectory& truth) {
  if (estimate.size() < 3 || truth.empty()) {
    throw std::invalid_argument("trajectory_ate_m: needs at least 3 estimated poses and a truth, got " +
                                std::to_string(estimate.size()) + " and " + std::to_string(truth.size()));
  }
  const auto n = static_cast<Eigen::Index>(estimate.size());
  Eigen::Matrix3Xd est(3, n), ref(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const TimedPose& p = estimate.poses()[static_cast<std::size_t>(i)];
    est.col(i) = p.T_world_lidar.translation();
    ref.col(i) = truth.pose_at(p.time_s).translation();
  }
  const Eigen::Matrix4d T = Eigen::umeyama(est, ref, false);
  const Eigen::Matrix3Xd error = ((T.topLeftCorner<3, 3>() * est).colwise() + T.topRightCorner<3, 1>()) - ref;
  return std::sqrt(error.colwise().squaredNorm().mean());
}

}  // namespace rgbdt::rgbdt_map
