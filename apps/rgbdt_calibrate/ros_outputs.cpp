#include "ros_outputs.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <set>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace rgbdt::calibrate {
namespace {

/// Twelve significant digits: the launch file and the URDF agree with the YAML to 1e-11.
std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.12g", v == 0.0 ? 0.0 : v);  // no "-0"
  return buf;
}

/// A Python string literal ('...').
std::string python_string(const std::string& s) {
  std::string out = "'";
  for (const char c : s) {
    if (c == '\\' || c == '\'') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", static_cast<unsigned char>(c));
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "'";
}

/// Text for an XML attribute value in double quotes.
std::string xml_attribute(const std::string& s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

/// A ROS node name from a camera's: letters, digits and '_' only.
std::string node_name(const std::string& camera) {
  std::string out = "rgbdt_static_tf_";
  for (const char c : camera) out += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return out;
}

}  // namespace

std::string RosFrames::camera(const std::string& name) const {
  const auto it = cameras.find(name);
  return it == cameras.end() ? name : it->second;
}

namespace {

/// Why `key` is neither "lidar" nor one of `cameras`; empty when it is one.
std::string unknown_key(const std::string& key, const std::vector<std::string>& cameras) {
  if (key == "lidar" || std::find(cameras.begin(), cameras.end(), key) != cameras.end()) return {};
  std::string names;
  for (const auto& c : cameras) names += " " + c;
  return "'" + key + "' is neither lidar nor a camera of the session (it has:" + names + ")";
}

/// Why `frame` cannot be a ROS frame id; empty when it can.
std::string bad_frame(const std::string& frame, const std::string& key) {
  if (frame.empty()) return "the frame of " + key + " is empty";
  for (const char c : frame)
    if (std::isspace(static_cast<unsigned char>(c)) || std::iscntrl(static_cast<unsigned char>(c)) ||
        c == '"' || c == '\'' || c == '\\' || c == '<' || c == '>' || c == '&')
      return "frame '" + frame + "' of " + key + " holds a space, quote or markup character; a ROS frame id does not";
  return {};
}

void set_frame(RosFrames& frames, const std::string& key, const std::string& frame) {
  if (key == "lidar")
    frames.lidar = frame;
  else
    frames.cameras[key] = frame;
}

}  // namespace

RosFrames read_session_frames(const std::string& path, const std::vector<std::string>& cameras) {
  const core::YamlField root(core::load_yaml_file(path), path);
  RosFrames frames;
  for (const auto& [key, value] : root.entries("a mapping of lidar and camera names to ROS frame ids")) {
    if (std::string why = unknown_key(key, cameras); !why.empty()) throw core::Error(path, why);
    const std::string frame = value.as_string("a ROS frame id");
    if (std::string why = bad_frame(frame, key); !why.empty()) throw core::Error(path, why);
    set_frame(frames, key, frame);
  }
  return frames;
}

RosFrames parse_ros_frames(const std::string& text, const std::vector<std::string>& cameras,
                           RosFrames base) {
  RosFrames frames = std::move(base);
  if (text.empty()) return frames;
  std::set<std::string> seen;
  std::stringstream ss(text);
  std::string entry;
  while (std::getline(ss, entry, ',')) {
    const size_t eq = entry.find('=');
    const std::string key = entry.substr(0, eq);
    const std::string frame = eq == std::string::npos ? std::string() : entry.substr(eq + 1);
    if (eq == std::string::npos || key.empty() || frame.empty())
      throw core::Error("--frames", "entry '" + entry +
                                        "' is not KEY=FRAME (e.g. lidar=velodyne,rgb=camera_link)");
    if (std::string why = unknown_key(key, cameras); !why.empty()) throw core::Error("--frames", why);
    if (std::string why = bad_frame(frame, key); !why.empty()) throw core::Error("--frames", why);
    if (!seen.insert(key).second) throw core::Error("--frames", "'" + key + "' is given twice");
    set_frame(frames, key, frame);
  }
  return frames;
}

std::string format_static_transforms_launch(const std::vector<RosCamera>& cameras,
                                            const RosFrames& frames) {
  std::ostringstream os;
  os << "# Written by rgbdt_calibrate: the camera-LIDAR extrinsics as static transforms\n"
        "# (T_lidar_camera, the inverse of extrinsics_<camera>.yaml's T_camera_lidar).\n"
        "#   ros2 launch ./static_transforms.launch.py\n"
        "from launch import LaunchDescription\n"
        "from launch_ros.actions import Node\n\n\n"
        "def generate_launch_description():\n"
        "    return LaunchDescription([\n";
  for (const RosCamera& c : cameras) {
    const Eigen::Isometry3d T = c.T_camera_lidar.inverse();
    const Eigen::Quaterniond q(T.linear());
    const Eigen::Vector4d xyzw = core::quaternion_to_xyzw(q.normalized());
    const Eigen::Vector3d& t = T.translation();
    os << "        Node(\n"
       << "            package='tf2_ros',\n"
       << "            executable='static_transform_publisher',\n"
       << "            name=" << python_string(node_name(c.name)) << ",\n"
       << "            arguments=[\n"
       << "                '--x', '" << number(t.x()) << "', '--y', '" << number(t.y())
       << "', '--z', '" << number(t.z()) << "',\n"
       << "                '--qx', '" << number(xyzw[0]) << "', '--qy', '" << number(xyzw[1])
       << "', '--qz', '" << number(xyzw[2]) << "', '--qw', '" << number(xyzw[3]) << "',\n"
       << "                '--frame-id', " << python_string(frames.lidar)
       << ", '--child-frame-id', " << python_string(frames.camera(c.name)) << ",\n"
       << "            ],\n"
       << "        ),\n";
  }
  os << "    ])\n";
  return os.str();
}

std::string format_urdf_joints(const std::vector<RosCamera>& cameras, const RosFrames& frames) {
  std::ostringstream os;
  os << "<?xml version=\"1.0\"?>\n"
        "<!-- Written by rgbdt_calibrate: one fixed joint per calibrated camera, origin =\n"
        "     T_lidar_camera (the inverse of extrinsics_<camera>.yaml's T_camera_lidar; rpy in\n"
        "     radians, R = Rz(yaw) Ry(pitch) Rx(roll)). Copy the joints into the robot's URDF;\n"
        "     the links are here so that this file loads on its own. -->\n"
        "<robot name=\"rgbdt_calibration\">\n"
     << "  <link name=\"" << xml_attribute(frames.lidar) << "\"/>\n";
  for (const RosCamera& c : cameras)
    os << "  <link name=\"" << xml_attribute(frames.camera(c.name)) << "\"/>\n";
  for (const RosCamera& c : cameras) {
    const Eigen::Isometry3d T = c.T_camera_lidar.inverse();
    const Eigen::Vector3d rpy = core::rotation_to_rpy(T.linear());
    const Eigen::Vector3d& t = T.translation();
    const std::string child = frames.camera(c.name);
    os << "  <joint name=\"" << xml_attribute(child + "_joint") << "\" type=\"fixed\">\n"
       << "    <parent link=\"" << xml_attribute(frames.lidar) << "\"/>\n"
       << "    <child link=\"" << xml_attribute(child) << "\"/>\n"
       << "    <origin xyz=\"" << number(t.x()) << " " << number(t.y()) << " " << number(t.z())
       << "\" rpy=\"" << number(rpy.x()) << " " << number(rpy.y()) << " " << number(rpy.z())
       << "\"/>\n"
       << "  </joint>\n";
  }
  os << "</robot>\n";
  return os.str();
}

}  // namespace rgbdt::calibrate
