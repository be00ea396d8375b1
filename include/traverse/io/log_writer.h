// Writing a traverse log directory (docs/log-format.md) and single stream files.
//
// Every CSV is written to "<file>.tmp" and renamed into place (io/csv.h), with shortest
// round-trip numbers, so readLog(writeLog(log)) gives back every sample bit for bit and a
// failure never destroys a file already written.
#pragma once

#include <filesystem>

#include "traverse/io/log.h"

namespace traverse::io {

/// Creates `dir` (and parents) and writes every present stream under the contract's file name
/// (gyro.csv, joints.csv, sun.csv, accel.csv, cmd.csv, truth.csv), rover.yaml
/// (saveRoverConfig) and the URDF named by log.config.urdf_file: copied from log.dir when
/// log.dir is set and is another directory, otherwise an existing one in `dir` is kept.
/// Optional streams that are absent or empty are not written, and a file of that name left in
/// `dir` by an earlier log is removed (it would otherwise be read back as part of this log).
/// Throws std::invalid_argument before writing anything if gyro or joints is empty or no URDF
/// is available; std::invalid_argument from a stream that cannot be written (see formatCsv);
/// std::runtime_error on I/O failure.
void writeLog(const std::filesystem::path& dir, const TraverseLog& log);

/// Writes one stream file with header "t," + columns joined by commas (any columns: estimator
/// outputs). Same as io::writeCsv.
void writeStream(const std::filesystem::path& file, const Stream& stream);

}  // namespace traverse::io
