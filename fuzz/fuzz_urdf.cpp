// libFuzzer target: the URDF loading path of the log reader — the binary-content check, then
// io::parseRoverGeometry on the text — with one of three rover.yaml set-ups (by the input's
// size, so that the input is plain URDF text): the defaults (every movable joint a column),
// rocky7's (a column -> joint map, a turn centre) and pathfinder's (skid steering).
// Bad input must be an InputError; anything else (another exception, a sanitizer report) is a
// crash.
#include <cstdint>
#include <string>

#include "traverse/core/error.h"
#include "traverse/io/input_file.h"
#include "traverse/io/rover_config.h"
#include "traverse/io/rover_description.h"

namespace {

traverse::io::RoverConfig bundled(const char* rover) {
  return traverse::io::loadRoverConfig(std::string(TRAVERSE_SOURCE_DIR) + "/datasets/rovers/" +
                                       rover + "/rover.yaml");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace traverse;
  static const io::RoverConfig kConfigs[] = {io::RoverConfig{}, bundled("rocky7"),
                                             bundled("pathfinder")};
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    io::rejectBinary(text, "rover.urdf");
    (void)io::parseRoverGeometry(text, kConfigs[size % 3], "rover.urdf");
  } catch (const InputError&) {
    return 0;  // the documented answer to bad input
  }
  return 0;
}
