#pragma once
/// \file
/// A time-stamped sequence of poses T_world_lidar with interpolation, as estimated by the
/// registration and as stored in simulated ground truth (CSV time_s,x,y,z,qx,qy,qz,qw).
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace rgbdt::rgbdt_map {

struct TimedPose {
  double time_s = 0.0;                                            ///< session clock [s]
  Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();  ///< LIDAR pose in the world
};

class Trajectory {
 public:
  Trajectory() = default;
  /// Poses must be sorted by strictly increasing time; throws std::invalid_argument otherwise.
  explicit Trajectory(std::vector<TimedPose> poses);

  /// Appends a pose later than the last one; throws std::invalid_argument otherwise.
  void push_back(const TimedPose& pose);

  bool empty() const { return poses_.empty(); }
  std::size_t size() const { return poses_.size(); }
  const std::vector<TimedPose>& poses() const { return poses_; }

  /// T_world_lidar at time t: slerp/linear between the surrounding poses; before the first
  /// or after the last pose, extrapolated with the velocity of the first/last interval
  /// (constant-velocity model), or the single pose if there is only one.
  /// Throws std::logic_error on an empty trajectory.
  Eigen::Isometry3d pose_at(double time_s) const;

 private:
  std::vector<TimedPose> poses_;
};

/// Extrapolates or interpolates the motion a->b with parameter s (s = 1 gives b, s = 2
/// continues at the same velocity), applied on the right: a * (a^-1 b)^s.
Eigen::Isometry3d scale_motion(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double s);

/// Reads CSV "time_s,x,y,z,qx,qy,qz,qw" (header line optional). Throws rgbdt::core::Error
/// naming the file and line.
Trajectory read_trajectory_csv(const std::string& path);
/// Writes the same CSV atomically (a temporary sibling renamed into place); throws
/// rgbdt::core::Error naming the file when any write, the close or the rename fails.
void write_trajectory_csv(const std::string& path, const Trajectory& trajectory);

/// Root mean square of the translation error between `estimate` and `truth`, evaluated at
/// the estimate's time stamps, after expressing the estimate in the truth's world frame
/// through their first poses (the estimate starts wherever the mapper put its origin). [m]
double trajectory_rmse_m(const Trajectory& estimate, const Trajectory& truth);

/// The same error after the rigid motion that best aligns the estimate's positions with
/// the truth's (Umeyama, no scale): the absolute trajectory error of the TUM RGB-D
/// benchmark. trajectory_rmse_m also counts an early heading error carried along the whole
/// path; this one does not, which separates it from drift along the way. Needs 3 poses. [m]
double trajectory_ate_m(const Trajectory& estimate, const Trajectory& truth);

}  // namespace rgbdt::rgbdt_map
