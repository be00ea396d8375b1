// libFuzzer target: rover.yaml parsed from memory (io::parseRoverConfig, which loadRoverConfig
// calls after reading the file). Bad input must be an InputError; anything else (another
// exception — yaml-cpp's own included —, a sanitizer report) is a crash. A configuration that
// loads must answer SunConfig::directionAt with a unit vector.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "traverse/core/error.h"
#include "traverse/io/rover_config.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace traverse;
  const std::string text(reinterpret_cast<const char*>(data), size);
  io::RoverConfig c;
  try {
    c = io::parseRoverConfig(text, "rover.yaml");
  } catch (const InputError&) {
    return 0;  // the documented answer to bad input
  }
  const auto& tab = c.sun.azimuth_elevation;
  const double t = tab.empty() ? 0.0 : 0.5 * tab.front().x() + 0.5 * tab.back().x();
  for (const double at : {t - 1.0, t, t + 1.0}) {
    if (!(std::abs(c.sun.directionAt(at).norm() - 1.0) < 1e-9)) std::abort();
  }
  return 0;
}
