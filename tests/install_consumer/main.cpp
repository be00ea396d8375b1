// Uses the installed traverse: loads the installed Rocky-7 description and evaluates the slip
// constraint of a rolling wheel (zero).
#include <iostream>

#include <traverse/io/rover_description.h>
#include <traverse/rover/slip_constraint.h>

int main() {
  using namespace traverse;
  const std::string dir = std::string(TRAVERSE_DATA_DIR) + "/rovers/rocky7/";
  const io::RoverConfig config = io::loadRoverConfig(dir + "rover.yaml");
  const rover::RoverGeometry geo = io::loadRoverGeometry(dir + "rover.urdf", config);
  const auto kin = rover::forwardKinematics<double>(geo, geo.zeroJoints());
  rover::JointVectord rates = geo.zeroJoints();
  for (const rover::Wheel& w : geo.wheels) rates[w.coord] = 0.1 / w.radius;
  const Vec4d t = rover::slipConstraint<double>(kin[0].T_body_wheel, 0.065,
                                                rover::wheelJointTwist(kin[0], rates),
                                                Vec3d(0.1, 0, 0), Vec3d::Zero(), 0.0);
  std::cout << "slip of a rolling wheel: " << t.norm() << "\n";
  return t.norm() < 1e-12 ? 0 : 1;
}
