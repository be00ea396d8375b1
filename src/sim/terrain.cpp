#include "traverse/sim/terrain.h"

#include <cmath>
#include <random>

namespace traverse::sim {

PlaneTerrain::PlaneTerrain(double slope_rad, double direction_rad)
    : g_(std::tan(slope_rad) * Vec2d(std::cos(direction_rad), std::sin(direction_rad))) {}

namespace {
// One Gaussian term a·exp(−k((x−cx)² + (y−cy)²)) and its gradient.
double gauss(double a, double k, double cx, double cy, double x, double y, Vec2d* grad) {
  const double dx = x - cx, dy = y - cy;
  const double v = a * std::exp(-k * (dx * dx + dy * dy));
  if (grad) *grad += -2.0 * k * v * Vec2d(dx, dy);
  return v;
}
}  // namespace

double UndulatingTerrain::height(double x, double y) const {
  return 0.2 * (gauss(0.25, 5 * 6.25, 0.5, 0.2, x, y, nullptr) -
                gauss(0.25, 4 * 6.25, 0.5, -0.2, x, y, nullptr) + 0.5 * std::sin(0.75 * x * y));
}

Vec2d UndulatingTerrain::gradient(double x, double y) const {
  Vec2d g = Vec2d::Zero(), d = Vec2d::Zero();
  gauss(0.25, 5 * 6.25, 0.5, 0.2, x, y, &g);
  gauss(0.25, 4 * 6.25, 0.5, -0.2, x, y, &d);
  const double c = 0.5 * 0.75 * std::cos(0.75 * x * y);
  return 0.2 * (g - d + c * Vec2d(y, x));
}

StepTerrain::StepTerrain(double height_m, double x_edge, double y_min, double y_max, double ramp_m)
    : h_(height_m), x0_(x_edge), y0_(y_min), y1_(y_max), w_(ramp_m) {}

namespace {
// Smooth 0→1 ramp over [0, w] (half cosine) and its derivative.
double ramp(double s, double w, double* ds) {
  if (s <= 0.0 || s >= w) {
    *ds = 0.0;
    return s <= 0.0 ? 0.0 : 1.0;
  }
  *ds = 0.5 * M_PI / w * std::sin(M_PI * s / w);
  return 0.5 * (1.0 - std::cos(M_PI * s / w));
}
}  // namespace

double StepTerrain::height(double x, double y) const {
  double d;
  return h_ * ramp(x - x0_, w_, &d) * ramp(y - y0_, w_, &d) * ramp(y1_ - y, w_, &d);
}

Vec2d StepTerrain::gradient(double x, double y) const {
  double dx, dy0, dy1;
  const double rx = ramp(x - x0_, w_, &dx), ry0 = ramp(y - y0_, w_, &dy0),
               ry1 = ramp(y1_ - y, w_, &dy1);
  return h_ * Vec2d(dx * ry0 * ry1, rx * (dy0 * ry1 - ry0 * dy1));
}

namespace {
// a (1 − d²/R²)³ for d < R, and its gradient.
double polyBump(double a, double inv_r2, double cx, double cy, double x, double y, Vec2d* grad) {
  const double dx = x - cx, dy = y - cy;
  const double s = (dx * dx + dy * dy) * inv_r2;
  if (s >= 1.0) return 0.0;
  const double u = 1.0 - s;
  if (grad) *grad += -6.0 * a * u * u * inv_r2 * Vec2d(dx, dy);
  return a * u * u * u;
}
}  // namespace

RoughTerrain::RoughTerrain(const Options& o) : o_(o), cell_(3.0 * o.correlation_length_m) {
  nx_ = std::max(1, static_cast<int>(std::ceil((o.x_max - o.x_min) / cell_)));
  ny_ = std::max(1, static_cast<int>(std::ceil((o.y_max - o.y_min) / cell_)));
  grid_.assign(static_cast<size_t>(nx_ * ny_), {});
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> ux(o.x_min, o.x_max), uy(o.y_min, o.y_max), u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  const long count = std::lround(o.bumps_per_m2 * (o.x_max - o.x_min) * (o.y_max - o.y_min));
  std::vector<Bump> bumps;
  for (long k = 0; k < count; ++k) {
    const double radius = o.correlation_length_m * (1.0 + 2.0 * u01(rng));
    const double x = ux(rng), y = uy(rng), a = n01(rng);
    bumps.push_back({x, y, a, 1.0 / (radius * radius)});
  }
  for (const Bump& b : bumps) {
    const int i = std::clamp(static_cast<int>((b.x - o.x_min) / cell_), 0, nx_ - 1);
    const int j = std::clamp(static_cast<int>((b.y - o.y_min) / cell_), 0, ny_ - 1);
    grid_[static_cast<size_t>(i * ny_ + j)].push_back(b);
  }
  // Scale amplitudes to the requested RMS height over a sample grid of the area.
  double sum_sq = 0.0;
  int n = 0;
  for (double x = o.x_min + cell_; x < o.x_max - cell_; x += 0.25 * o.correlation_length_m) {
    for (double y = o.y_min + cell_; y < o.y_max - cell_; y += 0.25 * o.correlation_length_m) {
      const double h = height(x, y);
      sum_sq += h * h;
      ++n;
    }
  }
  const double scale = n > 0 && sum_sq > 0 ? o.rms_height_m / std::sqrt(sum_sq / n) : 0.0;
  for (auto& cell : grid_) {
    for (Bump& b : cell) b.amplitude *= scale;
  }
  // Per quarter of a cell (kSub × kSub sub-cells), the bumps of the cell's 3 × 3 neighbourhood in
  // forNearby's order, less those whose disk is clearly clear of the sub-cell (widened by 1 µm
  // for the rounding of the sub-cell index): they add exactly 0 anywhere in it, so the sum is
  // the same, term for term, over about a third of the bumps.
  const double sub = cell_ / kSub;
  near_.assign(grid_.size() * kSub * kSub, {});
  for (int i0 = 0; i0 < nx_; ++i0) {
    for (int j0 = 0; j0 < ny_; ++j0) {
      for (int a = 0; a < kSub; ++a) {
        for (int c = 0; c < kSub; ++c) {
          const double x0 = o.x_min + i0 * cell_ + a * sub - 1e-6, x1 = x0 + sub + 2e-6;
          const double y0 = o.y_min + j0 * cell_ + c * sub - 1e-6, y1 = y0 + sub + 2e-6;
          auto& list = near_[(static_cast<size_t>(i0 * ny_ + j0) * kSub + a) * kSub + c];
          forCells(i0, j0, [&](const Bump& b) {
            const double dx = std::max({x0 - b.x, 0.0, b.x - x1});
            const double dy = std::max({y0 - b.y, 0.0, b.y - y1});
            // Kept unless d² ≥ R² (1 + 1e-6): rounding can never make such a bump's s < 1.
            if ((dx * dx + dy * dy) * b.inv_radius_sq < 1.0 + 1e-6) list.push_back(b);
          });
        }
      }
    }
  }
}

template <typename F>
void RoughTerrain::forCells(int i0, int j0, F&& f) const {
  for (int i = std::max(0, i0 - 1); i <= std::min(nx_ - 1, i0 + 1); ++i) {
    for (int j = std::max(0, j0 - 1); j <= std::min(ny_ - 1, j0 + 1); ++j) {
      for (const Bump& b : grid_[static_cast<size_t>(i * ny_ + j)]) f(b);
    }
  }
}

template <typename F>
void RoughTerrain::forNearby(double x, double y, F&& f) const {
  const int i0 = static_cast<int>(std::floor((x - o_.x_min) / cell_));
  const int j0 = static_cast<int>(std::floor((y - o_.y_min) / cell_));
  if (i0 >= 0 && i0 < nx_ && j0 >= 0 && j0 < ny_ && !near_.empty()) {
    const double sub = cell_ / kSub;
    const int a = std::clamp(static_cast<int>((x - o_.x_min - i0 * cell_) / sub), 0, kSub - 1);
    const int c = std::clamp(static_cast<int>((y - o_.y_min - j0 * cell_) / sub), 0, kSub - 1);
    for (const Bump& b : near_[(static_cast<size_t>(i0 * ny_ + j0) * kSub + a) * kSub + c]) f(b);
    return;
  }
  forCells(i0, j0, f);  // outside the grid (and while the constructor scales the amplitudes)
}

double RoughTerrain::height(double x, double y) const {
  double h = 0.0;
  forNearby(x, y, [&](const Bump& b) {
    h += polyBump(b.amplitude, b.inv_radius_sq, b.x, b.y, x, y, nullptr);
  });
  return h;
}

Vec2d RoughTerrain::gradient(double x, double y) const {
  Vec2d g = Vec2d::Zero();
  forNearby(x, y,
            [&](const Bump& b) { polyBump(b.amplitude, b.inv_radius_sq, b.x, b.y, x, y, &g); });
  return g;
}

double SumTerrain::height(double x, double y) const {
  double h = 0.0;
  for (const auto& p : parts_) h += p->height(x, y);
  return h;
}

Vec2d SumTerrain::gradient(double x, double y) const {
  Vec2d g = Vec2d::Zero();
  for (const auto& p : parts_) g += p->gradient(x, y);
  return g;
}

}  // namespace traverse::sim
