// Terrains for the simulator: height fields z = f(x, y) with their gradient (site frame, m).
#pragma once

#include <memory>
#include <vector>

#include "traverse/core/types.h"

namespace traverse::sim {

class Terrain {
 public:
  virtual ~Terrain() = default;
  virtual double height(double x, double y) const = 0;
  /// (∂f/∂x, ∂f/∂y)
  virtual Vec2d gradient(double x, double y) const = 0;
  /// Upward unit normal (−f_x, −f_y, 1)/‖·‖.
  Vec3d normal(double x, double y) const {
    const Vec2d g = gradient(x, y);
    return Vec3d(-g.x(), -g.y(), 1.0).normalized();
  }
};

class FlatTerrain final : public Terrain {
 public:
  explicit FlatTerrain(double z0 = 0.0) : z0_(z0) {}
  double height(double, double) const override { return z0_; }
  Vec2d gradient(double, double) const override { return Vec2d::Zero(); }

 private:
  double z0_;
};

/// A plane rising at `slope_rad` towards the azimuth `direction_rad` (from +x towards +y).
class PlaneTerrain final : public Terrain {
 public:
  PlaneTerrain(double slope_rad, double direction_rad);
  double height(double x, double y) const override { return g_.dot(Vec2d(x, y)); }
  Vec2d gradient(double, double) const override { return g_; }

 private:
  Vec2d g_;
};

/// The undulating surface of K-22, read as (see docs/simulator.md for the reading):
///   z = 0.2 [ 0.25 e^{−5·6.25((x−0.5)² + (y−0.2)²)} − 0.25 e^{−4·6.25((x−0.5)² + (y+0.2)²)}
///             + 0.5 sin(0.75 x y) ]
/// a bump under the left wheels, a dip under the right ones, and a gentle saddle.
class UndulatingTerrain final : public Terrain {
 public:
  double height(double x, double y) const override;
  Vec2d gradient(double x, double y) const override;
};

/// A brick-sized step (K §4.2): height `height_m` for x ≥ x_edge and y inside [y_min, y_max]
/// (under one side's wheels), with edges smoothed by a half-cosine ramp of width `ramp_m` so
/// the contact stays defined: the ramp's concave curvature hπ²/(2w²) must stay below the
/// wheel's 1/r, i.e. w > π√(h r / 2) (0.14 m for a 6 cm brick and r = 6.5 cm), or a thin wheel
/// would touch in two points, which the one-parameter contact model (K §2.2.4) cannot express.
class StepTerrain final : public Terrain {
 public:
  StepTerrain(double height_m, double x_edge, double y_min, double y_max, double ramp_m);
  double height(double x, double y) const override;
  Vec2d gradient(double x, double y) const override;

 private:
  double h_, x0_, y0_, y1_, w_;
};

/// Seeded random rough terrain: a sum of smooth, compactly supported bumps
/// a·(1 − d²/R²)³ (C², zero beyond R; random centres, normal amplitudes, radii R in
/// [L, 3L] for the correlation length L) over a rectangle, scaled so that the RMS height over
/// it is `rms_height_m`. Bumps are binned on a grid of cell 3L, so evaluation looks at the 3×3
/// cells around the point only and the surface has no seams.
class RoughTerrain final : public Terrain {
 public:
  struct Options {
    double rms_height_m = 0.02;
    double correlation_length_m = 0.5;
    double x_min = -5, x_max = 60, y_min = -20, y_max = 20;
    double bumps_per_m2 = 2.0;
    unsigned seed = 1;
  };
  explicit RoughTerrain(const Options& options);
  double height(double x, double y) const override;
  Vec2d gradient(double x, double y) const override;

 private:
  struct Bump {
    double x, y, amplitude, inv_radius_sq;
  };
  template <typename F>
  void forNearby(double x, double y, F&& f) const;
  template <typename F>
  void forCells(int i0, int j0, F&& f) const;  ///< the bumps of the 3 × 3 cells around (i0, j0)
  Options o_;
  double cell_;
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<Bump>> grid_;
  static constexpr int kSub = 4;  ///< sub-cells per cell side in near_
  /// Per sub-cell (cell index × kSub², row-major): the bumps that can reach it, in forNearby's
  /// order.
  std::vector<std::vector<Bump>> near_;
};

/// Sum of terrains (e.g. rough terrain on a slope).
class SumTerrain final : public Terrain {
 public:
  explicit SumTerrain(std::vector<std::shared_ptr<const Terrain>> parts)
      : parts_(std::move(parts)) {}
  double height(double x, double y) const override;
  Vec2d gradient(double x, double y) const override;

 private:
  std::vector<std::shared_ptr<const Terrain>> parts_;
};

}  // namespace traverse::sim
