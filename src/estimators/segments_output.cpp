#include "traverse/estimators/segments_output.h"

#include <charconv>
#include "traverse/io/atomic_file.h"

namespace traverse::est {

void writeSegments(const std::filesystem::path& file, const std::vector<SegmentRow>& rows) {
  std::string text =
      "segment,t_start,t_end,kind,bias_x,bias_y,bias_z,sigma_bias_x,sigma_bias_y,sigma_bias_z,"
      "status,iterations,"
      "final_cost,solve_seconds";
  const bool accel = !rows.empty() && rows.front().accel_bias.has_value();
  if (accel)
    text +=
        ",accel_bias_x,accel_bias_y,accel_bias_z,sigma_accel_bias_x,sigma_accel_bias_y,"
        "sigma_accel_bias_z";
  const bool icr = !rows.empty() && rows.front().icr.has_value();
  if (icr) text += ",icr_half_track_error_m,sigma_icr_half_track_error_m";
  text += "\n";
  char buf[32];
  auto num = [&](double v) { text.append(buf, std::to_chars(buf, buf + sizeof buf, v).ptr); };
  for (const SegmentRow& r : rows) {
    text += std::to_string(r.segment) + ",";
    num(r.t_start), text += ",";
    num(r.t_end), text += ",";
    text += r.kind == Segment::Kind::kRest ? "rest," : "motion,";
    for (int i = 0; i < 3; ++i) num(r.bias[i]), text += ",";
    for (int i = 0; i < 3; ++i) num(r.sigma_bias[i]), text += ",";
    text += r.status + ",";
    if (r.iterations) text += std::to_string(*r.iterations);
    text += ",";
    if (r.final_cost) num(*r.final_cost);
    text += ",";
    if (r.solve_seconds) num(*r.solve_seconds);
    if (accel) {
      const Vec3d b = r.accel_bias.value_or(Vec3d::Zero());
      for (int i = 0; i < 3; ++i) text += ",", num(b[i]);
      for (int i = 0; i < 3; ++i) text += ",", num(r.sigma_accel_bias[i]);
    }
    if (icr) text += ",", num(r.icr.value_or(0.0)), text += ",", num(r.sigma_icr);
    text += "\n";
  }
  io::writeFileAtomically(file, text);
}

}  // namespace traverse::est
