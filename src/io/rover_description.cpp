#include "traverse/io/rover_description.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <deque>
#include <fstream>
#include <map>
#include <sstream>
#include <string_view>

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>

#include "traverse/core/error.h"
#include "traverse/rover/kinematics.h"

namespace traverse::io {
namespace {

Posed toPose(const urdf::Pose& p) {
  Posed g;
  g.p = Vec3d(p.position.x, p.position.y, p.position.z);
  g.R =
      Quatd(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z).normalized().toRotationMatrix();
  return g;
}

/// Radius of a wheel link: its collision cylinder, else its visual cylinder (0: none).
double wheelRadius(const urdf::LinkConstSharedPtr& link) {
  auto cyl = [](const urdf::GeometrySharedPtr& g) -> double {
    if (g && g->type == urdf::Geometry::CYLINDER)
      return std::static_pointer_cast<urdf::Cylinder>(g)->radius;
    return 0.0;
  };
  if (link->collision && cyl(link->collision->geometry) != 0) return cyl(link->collision->geometry);
  if (link->visual && cyl(link->visual->geometry) != 0) return cyl(link->visual->geometry);
  return 0.0;
}

bool hasCylinder(const urdf::LinkConstSharedPtr& link) {
  auto is_cyl = [](const auto& part) {
    return part && part->geometry && part->geometry->type == urdf::Geometry::CYLINDER;
  };
  return is_cyl(link->collision) || is_cyl(link->visual);
}

/// Joint names in the order the URDF text declares them (urdfdom keeps its joints in a map
/// sorted by name): the `name` attribute of every <joint> element outside comments — what the
/// regex <joint\b[^>]*?\bname\s*=\s*["']([^"']*)["'] finds, scanned by hand in linear time
/// (libstdc++'s std::regex recurses once per character of a match: a joint tag of 100 kB
/// overflowed the stack).
std::vector<std::string> jointsInDocumentOrder(const std::string& xml) {
  std::string text = xml;
  for (size_t a = text.find("<!--"); a != std::string::npos; a = text.find("<!--", a)) {
    const size_t b = text.find("-->", a);
    text.erase(a, b == std::string::npos ? std::string::npos : b + 3 - a);
  }
  const auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
  const auto space = [](char c) { return c == ' ' || (c >= '\t' && c <= '\r'); };
  const size_t n = text.size();
  std::vector<std::string> out;
  size_t pos = 0;
  size_t gt = 0;  // the first '>' at or after pos (n: none)
  while ((pos = text.find("<joint", pos)) != std::string::npos) {
    pos += 6;
    if (pos < n && word(text[pos])) continue;  // <jointX…: another element
    if (gt < pos) gt = std::min(text.find('>', pos), n);
    const std::string_view tag(text.data(), gt);  // `name` must start before the tag's '>'
    for (size_t q = tag.find("name", pos); q != tag.npos; q = tag.find("name", q + 1)) {
      if (word(text[q - 1])) continue;  // …name inside another attribute's name
      size_t p = q + 4;
      while (p < n && space(text[p])) ++p;
      if (p == n || text[p] != '=') continue;
      ++p;
      while (p < n && space(text[p])) ++p;
      if (p == n || (text[p] != '"' && text[p] != '\'')) continue;
      const size_t value = p + 1;
      const size_t close = text.find_first_of("\"'", value);
      if (close == std::string::npos) continue;
      out.push_back(text.substr(value, close - value));
      pos = close + 1;
      break;
    }
  }
  return out;
}

bool movable(const urdf::JointConstSharedPtr& j) {
  return j->type == urdf::Joint::REVOLUTE || j->type == urdf::Joint::CONTINUOUS;
}

}  // namespace

rover::RoverGeometry parseRoverGeometry(const std::string& xml, const RoverConfig& config,
                                        const std::string& source) {
  // urdfdom reports parse problems through console_bridge; we report them as one InputError.
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  // urdfdom parses the text's c_str() with TinyXML 2.6.2, which steps over a UTF-8 lead byte's
  // whole sequence: a text ending in a truncated sequence (a lone 0xC8 in the last tag) made it
  // read up to 3 bytes past the terminating NUL, out of the string (a heap over-read found by
  // fuzz_urdf). Zero bytes after the terminator stop it there.
  std::string padded = xml;
  padded.append(4, '\0');
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(padded);
  if (!model) throw InputError(source, 0, "unreadable URDF (urdfdom could not parse it)");
  const auto fail = [&](const std::string& what) { throw InputError(source, 0, what); };
  for (const auto& [name, j] : model->joints_) {
    if (j->type != urdf::Joint::FIXED && !movable(j)) {
      fail("joint '" + name + "': only revolute, continuous and fixed joints are supported");
    }
  }
  rover::RoverGeometry geo;
  geo.name = model->getName();

  // The joint coordinates (joints.csv columns): every movable joint that does not mimic another.
  std::map<std::string, int> coord_of;  // URDF joint name → coordinate index
  auto add = [&](const std::string& column, const std::string& joint) {
    coord_of[joint] = geo.numCoords();
    geo.coords.push_back({column, joint, rover::CoordKind::kSuspension, -1});
  };
  if (!config.joint_names.empty()) {  // rover.yaml `joints`: column → joint, in column order
    for (const auto& [column, joint] : config.joint_names) {
      const urdf::JointConstSharedPtr j = model->getJoint(joint);
      if (!j) fail("joint '" + joint + "' (joints.csv column '" + column + "') is not in the URDF");
      if (!movable(j)) {
        fail("joint '" + joint + "' (joints.csv column '" + column +
             "') is fixed: only movable joints have a column");
      }
      if (j->mimic) {
        fail("joint '" + joint + "' (joints.csv column '" + column + "') mimics '" +
             j->mimic->joint_name + "' and so has no column of its own");
      }
      if (coord_of.count(joint)) fail("joint '" + joint + "' is mapped to two joints.csv columns");
      add(column, joint);
    }
  } else {
    for (const std::string& name : jointsInDocumentOrder(xml)) {
      const urdf::JointConstSharedPtr j = model->getJoint(name);
      if (j && movable(j) && !j->mimic && !coord_of.count(name)) add(name, name);
    }
  }
  for (const auto& [name, j] : model->joints_) {
    if (movable(j) && !j->mimic && !coord_of.count(name)) {
      fail("joint '" + name + "' is not mapped to a joints.csv column (rover.yaml 'joints')");
    }
  }
  if (geo.numCoords() > rover::kMaxCoords) {
    fail("the URDF has " + std::to_string(geo.numCoords()) + " movable joints (at most " +
         std::to_string(rover::kMaxCoords) + " are supported)");
  }

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
      } else if (kj.axis.norm() < 1e-9) {
        fail("joint '" + j->name + "': zero axis");
      } else {
        kj.axis.normalize();
        if (const auto it = coord_of.find(j->name); it != coord_of.end()) {
          kj.coord = it->second;
        } else {  // a mimic joint (every other movable joint is a coordinate)
          const auto m = coord_of.find(j->mimic->joint_name);
          if (m == coord_of.end()) {
            fail("joint '" + j->name + "' mimics '" + j->mimic->joint_name +
                 "', which is not mapped to a joints.csv column");
          }
          kj.coord = m->second;
          kj.multiplier = j->mimic->multiplier;
          kj.offset = j->mimic->offset;
        }
      }
      joint_index[j->name] = static_cast<int>(geo.joints.size());
      geo.joints.push_back(kj);
      const urdf::LinkConstSharedPtr child = model->getLink(j->child_link_name);
      if (!child) fail("joint '" + j->name + "': child link '" + j->child_link_name + "' missing");
      link_parent[child->name] = joint_index[j->name];
      queue.push_back(child);
    }
  }

  // Wheels: continuous joints, and leaf revolute joints whose link is a cylinder. Steering: the
  // other coordinates whose axis is near the body's vertical at zero angles. Suspension: the rest.
  const std::vector<Posed> at_zero = rover::jointPoses<double>(geo, geo.zeroJoints());
  for (rover::Coordinate& c : geo.coords) {
    const urdf::JointConstSharedPtr j = model->getJoint(c.joint);
    const urdf::LinkConstSharedPtr link = model->getLink(j->child_link_name);
    const bool wheel =
        j->type == urdf::Joint::CONTINUOUS || (link->child_joints.empty() && hasCylinder(link));
    // A joint that the walk from the root never reached (urdfdom builds its tree from the
    // links' parents, so a second chain, or a joint whose parent link is carried twice, can
    // stay outside it): bad input, not a crash (found by fuzz_urdf).
    const auto reached = joint_index.find(c.joint);
    if (reached == joint_index.end()) {
      fail("joint '" + c.joint + "' is not connected to the root link '" + model->getRoot()->name +
           "'");
    }
    const int d = reached->second;
    if (wheel) {
      if ((geo.joints[d].axis - Vec3d::UnitY()).norm() > 1e-9) {
        fail("wheel drive joint '" + c.joint + "' must rotate about +y of its frame (axis 0 1 0)");
      }
      rover::Wheel w;
      w.drive_joint = d;
      w.coord = static_cast<int>(&c - geo.coords.data());
      w.radius = wheelRadius(link);
      if (!(w.radius > 0.0)) {
        fail("wheel link of joint '" + c.joint +
             "' has no cylinder geometry giving a positive radius");
      }
      c.kind = rover::CoordKind::kDrive;
      c.wheel = geo.numWheels();
      geo.wheels.push_back(w);
    } else {
      const Vec3d axis_body = at_zero[static_cast<size_t>(d)].R * geo.joints[d].axis;
      c.kind = std::abs(axis_body.z()) > std::cos(30.0 * M_PI / 180.0)
                   ? rover::CoordKind::kSteering
                   : rover::CoordKind::kSuspension;
    }
  }
  if (geo.wheels.empty()) {
    fail(
        "the URDF has no wheel (a continuous joint, or a revolute joint ending in a cylinder "
        "link)");
  }
  if (geo.numWheels() > rover::kMaxWheels) {
    fail("the URDF has " + std::to_string(geo.numWheels()) + " wheels (at most " +
         std::to_string(rover::kMaxWheels) + " are supported)");
  }
  for (rover::Wheel& w : geo.wheels) {
    for (int j = w.drive_joint; j >= 0; j = geo.joints[j].parent) {
      const int c = geo.joints[j].coord;
      w.steered |= c >= 0 && geo.coords[static_cast<size_t>(c)].kind == rover::CoordKind::kSteering;
    }
  }
  {  // each wheel's side, and the calibrated rolling radii (io::OdometryConfig)
    const auto kin = rover::forwardKinematics<double>(geo, geo.zeroJoints());
    const double left = config.odometry.wheel_radius_scale_left;
    const double right = config.odometry.wheel_radius_scale_right;
    for (int w = 0; w < geo.numWheels(); ++w) {
      const double y = kin[w].T_body_wheel.p.y();
      const double share = y > 1e-6 ? 1.0 : y < -1e-6 ? 0.0 : 0.5;
      geo.wheels[w].left_share = share;
      if (left != 1.0 || right != 1.0) geo.wheels[w].radius *= share * left + (1 - share) * right;
    }
  }
  if (config.skid_steer) {
    const auto kin = rover::forwardKinematics<double>(geo, geo.zeroJoints());
    for (int w = 0; w < geo.numWheels(); ++w) {
      const double y = kin[w].T_body_wheel.p.y();
      if (geo.wheels[w].steered)
        fail("skid_steer: wheel joint '" + geo.coords[geo.wheels[w].coord].joint + "' is steered");
      if (std::abs(y) < 1e-6)
        fail("skid_steer: wheel joint '" + geo.coords[geo.wheels[w].coord].joint +
             "' is on the body's centre line (no side)");
      geo.wheels[w].icr_offset_y =
          (y > 0 ? config.skid_steer->icr_y_left_m : config.skid_steer->icr_y_right_m) - y;
      geo.wheels[w].icr_side = y > 0 ? 1.0 : -1.0;
    }
  }
  if (config.turn_centre_x_m) {
    geo.turn_centre_x = *config.turn_centre_x_m;
  } else {  // mean x of the wheels without a steering joint on their chain
    const auto kin = rover::forwardKinematics<double>(geo, geo.zeroJoints());
    double sum = 0.0;
    int n = 0;
    for (int w = 0; w < geo.numWheels(); ++w) {
      if (!geo.wheels[w].steered) sum += kin[w].T_body_wheel.p.x(), ++n;
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
