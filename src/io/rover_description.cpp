#include "traverse/io/rover_description.h"

#include <cmath>
#include <deque>
#include <fstream>
#include <map>
#include <sstream>

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>

#include "traverse/core/error.h"
#include "traverse/rover/kinematics.h"

namespace traverse::io {
namespace {

using rover::kNumCoords;
using rover::kNumWheels;

Posed toPose(const urdf::Pose& p) {
  Posed g;
  g.p = Vec3d(p.position.x, p.position.y, p.position.z);
  g.R =
      Quatd(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z).normalized().toRotationMatrix();
  return g;
}

/// Radius of a wheel link: its collision cylinder, else its visual cylinder.
double wheelRadius(const urdf::LinkConstSharedPtr& link) {
  auto cyl = [](const urdf::GeometrySharedPtr& g) -> double {
    if (g && g->type == urdf::Geometry::CYLINDER)
      return std::static_pointer_cast<urdf::Cylinder>(g)->radius;
    return 0.0;
  };
  if (link->collision && cyl(link->collision->geometry) > 0) return cyl(link->collision->geometry);
  if (link->visual && cyl(link->visual->geometry) > 0) return cyl(link->visual->geometry);
  return 0.0;
}

/// Coordinate index for each URDF joint name (via the yaml column map).
std::map<std::string, int> coordinateMap(const RoverConfig& config) {
  std::map<std::string, int> by_joint;
  for (int c = 0; c < kNumCoords; ++c) {
    const std::string column(rover::kCoordNames[c]);
    const auto it = config.joint_names.find(column);
    by_joint[it == config.joint_names.end() ? column : it->second] = c;
  }
  return by_joint;
}

}  // namespace

rover::RoverGeometry parseRoverGeometry(const std::string& xml, const RoverConfig& config,
                                        const std::string& source) {
  // urdfdom reports parse problems through console_bridge; we report them as one InputError.
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(xml);
  if (!model) throw InputError(source, 0, "unreadable URDF (urdfdom could not parse it)");
  const auto coords = coordinateMap(config);
  for (const auto& [joint, c] : coords) {
    if (!model->getJoint(joint)) {
      throw InputError(source, 0,
                       "joint '" + joint + "' (joints.csv column '" +
                           std::string(rover::kCoordNames[c]) + "') is not in the URDF");
    }
  }
  rover::RoverGeometry geo;
  geo.name = model->getName();
  std::map<std::string, int> joint_index;  // URDF joint name → index in geo.joints
  std::map<std::string, int> link_parent;  // link name → index of the joint that carries it
  std::deque<urdf::LinkConstSharedPtr> queue{model->getRoot()};
  link_parent[model->getRoot()->name] = -1;
  while (!queue.empty()) {  // breadth-first: parents before children
    const urdf::LinkConstSharedPtr link = queue.front();
    queue.pop_front();
    for (const urdf::JointSharedPtr& j : link->child_joints) {
      rover::KinematicJoint kj;
      kj.name = j->name;
      kj.parent = link_parent.at(link->name);
      kj.origin = toPose(j->parent_to_joint_origin_transform);
      kj.axis = Vec3d(j->axis.x, j->axis.y, j->axis.z);
      if (j->type == urdf::Joint::FIXED) {
        kj.axis.setZero();
      } else if (j->type != urdf::Joint::REVOLUTE && j->type != urdf::Joint::CONTINUOUS) {
        throw InputError(
            source, 0,
            "joint '" + j->name + "': only revolute, continuous and fixed joints are supported");
      } else if (kj.axis.norm() < 1e-9) {
        throw InputError(source, 0, "joint '" + j->name + "': zero axis");
      } else {
        kj.axis.normalize();
        if (const auto it = coords.find(j->name); it != coords.end()) {
          kj.coord = it->second;
        } else if (j->mimic) {
          const auto m = coords.find(j->mimic->joint_name);
          if (m == coords.end()) {
            throw InputError(source, 0,
                             "joint '" + j->name + "' mimics '" + j->mimic->joint_name +
                                 "', which is not mapped to a joints.csv column");
          }
          kj.coord = m->second;
          kj.multiplier = j->mimic->multiplier;
          kj.offset = j->mimic->offset;
        } else {
          throw InputError(
              source, 0,
              "joint '" + j->name + "' is not mapped to a joints.csv column (rover.yaml 'joints')");
        }
      }
      joint_index[j->name] = static_cast<int>(geo.joints.size());
      geo.joints.push_back(kj);
      const urdf::LinkConstSharedPtr child = model->getLink(j->child_link_name);
      link_parent[child->name] = joint_index[j->name];
      queue.push_back(child);
    }
  }
  for (const auto& [name, c] : coords) {
    if (c < rover::kPsi1) continue;
    const int w = c - rover::kPsi1;
    const int d = joint_index.at(name);
    if (geo.joints[d].coord != c || (geo.joints[d].axis - Vec3d::UnitY()).norm() > 1e-9) {
      throw InputError(
          source, 0,
          "wheel drive joint '" + name + "' must rotate about +y of its frame (axis 0 1 0)");
    }
    geo.wheels[w].drive_joint = d;
    geo.wheels[w].radius = wheelRadius(model->getLink(model->getJoint(name)->child_link_name));
    if (!(geo.wheels[w].radius > 0.0)) {
      throw InputError(
          source, 0,
          "wheel link of joint '" + name + "' has no cylinder geometry giving a positive radius");
    }
  }
  if (config.turn_centre_x_m) {
    geo.turn_centre_x = *config.turn_centre_x_m;
  } else {  // mean x of the wheels without a steering joint on their chain
    const auto kin = rover::forwardKinematics<double>(geo, rover::JointVectord::Zero());
    double sum = 0.0;
    int n = 0;
    for (int w = 0; w < kNumWheels; ++w) {
      bool steered = false;
      for (int j = geo.wheels[w].drive_joint; j >= 0; j = geo.joints[j].parent) {
        steered |= geo.joints[j].coord == rover::kLambda1 || geo.joints[j].coord == rover::kLambda2;
      }
      if (!steered) sum += kin[w].T_body_wheel.p.x(), ++n;
    }
    geo.turn_centre_x = n > 0 ? sum / n : 0.0;
  }
  return geo;
}

rover::RoverGeometry loadRoverGeometry(const std::filesystem::path& urdf_file,
                                       const RoverConfig& config) {
  std::ifstream f(urdf_file);
  if (!f) throw InputError(urdf_file.string(), 0, "required file is missing or unreadable");
  std::stringstream ss;
  ss << f.rdbuf();
  return parseRoverGeometry(ss.str(), config, urdf_file.string());
}

}  // namespace traverse::io
