// Reading an input file whole, with a size limit checked before a byte is read: a multi-GB file
// dropped into a log directory by mistake is refused by its size (docs/log-format.md, "Bad
// input") instead of filling memory.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace traverse::io {

/// The largest input file accepted, in bytes: $TRAVERSE_MAX_INPUT_BYTES when set (a positive
/// integer), else kDefaultMaxInputBytes.
inline constexpr std::uintmax_t kDefaultMaxInputBytes = std::uintmax_t{1} << 30;  // 1 GiB
std::uintmax_t maxInputBytes();

/// Throws InputError(file, 0, …) naming the file's size and the limit when it is larger than
/// maxInputBytes(); looks only at the directory entry (a sparse file is never read).
void checkInputSize(const std::filesystem::path& file);

/// Throws InputError(file, line, "binary content …") when the text holds a NUL byte, which no
/// text file does (a binary or corrupt file, whatever its name says).
void rejectBinary(std::string_view text, const std::string& file);

/// The file's bytes, after checkInputSize. InputError when missing, a directory or unreadable.
std::string readInputFile(const std::filesystem::path& file);

}  // namespace traverse::io
