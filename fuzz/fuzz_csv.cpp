// libFuzzer target: one CSV stream file parsed from memory (io::parseCsv), as the log reader
// does. The first byte chooses the stream's spec and the options, the rest is the file's text:
//   bits 0-2: gyro, joints, sun, accel, cmd, truth, gps (7: the generic estimator-output spec)
//   bit 3:    joints.csv / truth.csv for the bundled rocky7 rover (its columns, its 6 wheels)
//   bit 4:    --skip-bad-rows
// Bad input must be an InputError whose message is one printable line; anything else (another
// exception, a sanitizer report) is a crash. A file that parses must write back (formatCsv) and
// read back to the same bits.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>

#include "traverse/core/error.h"
#include "traverse/io/csv.h"
#include "traverse/io/rover_config.h"
#include "traverse/io/rover_description.h"

namespace {

using namespace traverse;

const rover::RoverGeometry& rocky7() {
  static const rover::RoverGeometry geo = [] {
    const std::string dir = std::string(TRAVERSE_SOURCE_DIR) + "/datasets/rovers/rocky7/";
    return io::loadRoverGeometry(dir + "rover.urdf", io::loadRoverConfig(dir + "rover.yaml"));
  }();
  return geo;
}

bool sameBits(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         (a.size() == 0 || std::memcmp(a.data(), b.data(),
                                       sizeof(double) * static_cast<std::size_t>(a.size())) == 0);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const char* const kFiles[] = {"gyro.csv", "joints.csv", "sun.csv", "accel.csv",
                                       "cmd.csv",  "truth.csv",  "gps.csv"};
  const unsigned selector = data[0];
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  const unsigned which = selector & 7U;
  io::StreamSpec spec;  // 7: any header starting with t
  std::string file = "out.csv";
  if (which < 7) {
    file = kFiles[which];
    spec = (selector & 8U) != 0 ? io::logStreamSpec(file, rocky7()) : io::logStreamSpec(file);
  }
  io::ReadOptions options;
  options.skip_bad_rows = (selector & 16U) != 0;
  io::ReadReport report;
  io::Stream s;
  try {
    s = io::parseCsv(text, file, spec, options, &report);
  } catch (const InputError& e) {
    // The documented answer to bad input: one printable line (bytes quoted as \xNN).
    for (const char c : std::string_view(e.what())) {
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) std::abort();
    }
    return 0;
  }
  // What the reader accepts, the writer writes and the reader reads back bit for bit.
  const io::Stream back = io::parseCsv(io::formatCsv(s), file, io::StreamSpec{});
  if (back.columns != s.columns || !sameBits(back.t, s.t) || !sameBits(back.values, s.values)) {
    std::abort();
  }
  return 0;
}
