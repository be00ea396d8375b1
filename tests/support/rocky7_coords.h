// The bundled Rocky-7's joint coordinates (datasets/rovers/rocky7/rover.yaml `joints:`, in that
// file's order, which is the joints.csv column order): named indices for tests that set or read
// one joint of that rover. The library knows no rover's joints; RoverGeometryTest checks these
// against the loaded geometry.
#pragma once

namespace traverse::r7 {

inline constexpr int kNumWheels = 6;
inline constexpr int kNumCoords = 11;
enum Coord : int {
  kGamma0 = 0,  // rocker differential γ0
  kGamma1,      // left bogie γ1
  kGamma2,      // right bogie γ2
  kLambda1,     // left steering λ1
  kLambda2,     // right steering λ2
  kPsi1,        // wheel drive angles ψ1..ψ6 (1 left front, 2-3 left bogie, 4 right front, 5-6)
  kPsi2,
  kPsi3,
  kPsi4,
  kPsi5,
  kPsi6,
};

}  // namespace traverse::r7
