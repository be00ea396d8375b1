// Writing a log directory (include/traverse/io/log_writer.h).
#include "traverse/io/log_writer.h"

#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include "traverse/io/csv.h"
#include "traverse/io/rover_config.h"

namespace traverse::io {
namespace {

namespace fs = std::filesystem;

/// Where the URDF comes from: a file to copy, or nothing (the one already in place is kept).
std::optional<fs::path> urdfSource(const fs::path& dir, const TraverseLog& log) {
  const fs::path target = dir / log.config.urdf_file;
  std::error_code ec;
  if (!log.dir.empty()) {
    const fs::path source = log.dir / log.config.urdf_file;
    if (fs::equivalent(source, target, ec)) return std::nullopt;
    if (fs::is_regular_file(source, ec)) return source;
  }
  if (fs::exists(target, ec)) return std::nullopt;
  throw std::invalid_argument("writeLog: no URDF for " + dir.string() + ": neither " +
                              (log.dir.empty() ? std::string("log.dir (unset)")
                                               : (log.dir / log.config.urdf_file).string()) +
                              " nor " + target.string() + " exists");
}

void copyAtomically(const fs::path& from, const fs::path& to) {
  const fs::path tmp = to.string() + ".tmp";
  std::error_code ec;
  fs::copy_file(from, tmp, fs::copy_options::overwrite_existing, ec);
  if (!ec) fs::rename(tmp, to, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw std::runtime_error("cannot copy " + from.string() + " to " + to.string() + ": " +
                             ec.message());
  }
}

}  // namespace

void writeStream(const fs::path& file, const Stream& stream) {
  writeCsv(file, stream);
}

void writeLog(const fs::path& dir, const TraverseLog& log) {
  if (log.gyro.empty() || log.joints.empty()) {
    throw std::invalid_argument("writeLog: gyro and joints are required and must hold samples");
  }
  const std::optional<fs::path> urdf = urdfSource(dir, log);  // before anything is written
  fs::create_directories(dir);
  for (const auto& [name, stream] : logStreams(log)) {
    if (stream != nullptr && !stream->empty()) writeCsv(dir / name, *stream);
  }
  saveRoverConfig(dir / "rover.yaml", log.config);
  if (urdf) {
    fs::create_directories((dir / log.config.urdf_file).parent_path());
    copyAtomically(*urdf, dir / log.config.urdf_file);
  }
  // A stream file left from an earlier log in `dir` would be read back as part of this one.
  for (const auto& [name, stream] : logStreams(log)) {
    if (stream == nullptr || stream->empty()) fs::remove(dir / name);
  }
}

}  // namespace traverse::io
