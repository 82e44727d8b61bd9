#pragma once
/// \file
/// The calibration as ROS reads it: a ROS 2 launch file of tf2_ros static transform
/// publishers and a URDF with one fixed joint per camera. Both hold T_lidar_camera (parent =
/// the LIDAR frame, child = the camera frame), the inverse of the T_camera_lidar of
/// extrinsics_<camera>.yaml, as ROS's tf tree expects it.
#include <Eigen/Geometry>
#include <map>
#include <string>
#include <vector>

namespace rgbdt::calibrate {

/// The frame names of the ROS outputs: the LIDAR's and each camera's (default: "lidar" and
/// the camera's session name, the frames of extrinsics_<camera>.yaml).
struct RosFrames {
  std::string lidar = "lidar";
  std::map<std::string, std::string> cameras;  ///< camera name -> frame; absent: the name

  std::string camera(const std::string& name) const;
};

/// Parses --frames: "lidar=NAME,CAMERA=NAME,..." (any subset, any order) over `base`. Keys are
/// "lidar" or a name of `cameras`; a frame is non-empty, without spaces, quotes or control
/// characters. Throws rgbdt::core::Error naming the option and the bad entry.
RosFrames parse_ros_frames(const std::string& text, const std::vector<std::string>& cameras,
                           RosFrames base = {});

/// The file of a session that rgbdt_import writes beside session.yaml: each sensor's ROS
/// frame_id from the header of its first message in the bag, a mapping of "lidar" and camera
/// names to frames. The default frames of the ROS outputs; --frames overrides them.
inline constexpr const char* kSessionFramesFile = "frames.yaml";

/// Reads a session's frames.yaml (the keys and frames as for --frames); throws
/// rgbdt::core::Error naming the file, the key and what was expected.
RosFrames read_session_frames(const std::string& path, const std::vector<std::string>& cameras);

/// One calibrated camera: its session name and T_camera_lidar.
struct RosCamera {
  std::string name;
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();
};

/// static_transforms.launch.py: one tf2_ros static_transform_publisher Node per camera with
/// --x --y --z --qx --qy --qz --qw --frame-id LIDAR --child-frame-id CAMERA (ROS 2 Humble and
/// later).
std::string format_static_transforms_launch(const std::vector<RosCamera>& cameras,
                                            const RosFrames& frames);
/// urdf_joints.xml: a <robot> with a <link> per frame and one fixed <joint> per camera
/// (<origin xyz rpy> = T_lidar_camera, parent = the LIDAR frame); the joints go into the
/// robot's URDF, the links are there so that the file loads on its own.
std::string format_urdf_joints(const std::vector<RosCamera>& cameras, const RosFrames& frames);

}  // namespace rgbdt::calibrate
