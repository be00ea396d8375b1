#include "traverse/pipeline/pipeline.h"

#include <algorithm>

namespace traverse::pipeline {

using est::RestWindow;
using est::Segment;
using est::TrajectoryNode;

std::vector<SegmentRow> segmentRows(const Segmentation& seg, const Trajectory& tr) {
  std::vector<SegmentRow> rows;
  for (size_t s = 0; s < seg.segments.size(); ++s) {
    const Segment& sg = seg.segments[s];
    SegmentRow r;
    r.segment = static_cast<int>(s);
    r.t_start = sg.t_start, r.t_end = sg.t_end, r.kind = sg.kind;
    // The trajectory node nearest the segment's end.
    const auto it = std::lower_bound(tr.nodes.begin(), tr.nodes.end(), sg.t_end,
                                     [](const TrajectoryNode& n, double t) { return n.t < t; });
    if (!tr.nodes.empty()) {
      const TrajectoryNode& n = it == tr.nodes.end() ? tr.nodes.back() : *it;
      r.bias = n.bias, r.sigma_bias = n.bias_sigma;
    }
    if (sg.kind == Segment::Kind::kRest) {
      const RestWindow& w = seg.rests[static_cast<size_t>(sg.rest_index)];
      for (int a = 0; a < 3; ++a) {
        if (w.bias_axes[static_cast<size_t>(a)] && w.gyro_samples > 1)
          r.bias[a] = w.bias[a], r.sigma_bias[a] = w.bias_sigma[a];
      }
    }
    rows.push_back(r);
  }
  return rows;
}

Estimates estimate(const io::TraverseLog& log, const PipelineConfig& config) {
  Estimates e;
  e.segmentation = est::segment(log, config.segmentation);
  e.init = est::initialState(log, e.segmentation, config.init);
  e.dr = est::deadReckoning(log, e.segmentation, e.init, config.dead_reckoning);
  e.ekf = est::runEkf(log, e.segmentation, e.init, config.ekf);
  e.segments = segmentRows(e.segmentation, e.ekf.trajectory);
  if (config.smooth) {
    smoother::SmootherOptions so = config.smoother;
    // kAuto follows the EKF's choice: when the EKF gave up the accelerometer-driven velocity
    // (runEkf's rule), so does the smoother it seeds.
    if (so.velocity == smoother::SmootherOptions::VelocityModel::kAuto &&
        e.ekf.velocity == est::EkfOptions::VelocityModel::kPerturbation)
      so.velocity = smoother::SmootherOptions::VelocityModel::kPerturbation;
    e.smoothed = smoother::smooth(log, e.segmentation, e.ekf.trajectory, so);
    e.segments = smoother::smootherSegmentRows(e.segments, *e.smoothed);
  }
  return e;
}

}  // namespace traverse::pipeline
