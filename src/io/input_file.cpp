// Input files read whole under a size limit (include/traverse/io/input_file.h).
#include "traverse/io/input_file.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string_view>

#include "traverse/core/error.h"

namespace traverse::io {

std::uintmax_t maxInputBytes() {
  const char* env = std::getenv("TRAVERSE_MAX_INPUT_BYTES");
  if (env == nullptr || *env == '\0') return kDefaultMaxInputBytes;
  const std::string_view text(env);
  std::uintmax_t v = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size() || v == 0) {
    // A typo must not silently lift (or keep) the limit.
    throw InputError("TRAVERSE_MAX_INPUT_BYTES", 0,
                     "'" + std::string(text) + "' is not a positive number of bytes");
  }
  return v;
}

void checkInputSize(const std::filesystem::path& file) {
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(file, ec);
  if (ec) return;  // not a regular file or unreadable: the read says so
  const std::uintmax_t limit = maxInputBytes();
  if (size <= limit) return;
  const double s = static_cast<double>(size);
  char human[32];
  if (s >= 1e9)
    std::snprintf(human, sizeof human, "%.3g GB", s / 1e9);
  else if (s >= 1e6)
    std::snprintf(human, sizeof human, "%.3g MB", s / 1e6);
  else
    std::snprintf(human, sizeof human, "%.3g kB", s / 1e3);
  throw InputError(file.string(), 0,
                   "file of " + std::to_string(size) + " bytes (" + human +
                       ") is larger than the input limit of " + std::to_string(limit) +
                       " bytes; not read (TRAVERSE_MAX_INPUT_BYTES sets the limit)");
}

void rejectBinary(std::string_view text, const std::string& file) {
  const auto* nul = static_cast<const char*>(std::memchr(text.data(), '\0', text.size()));
  if (nul == nullptr) return;
  const std::string_view before(text.data(), static_cast<std::size_t>(nul - text.data()));
  const long line = static_cast<long>(std::count(before.begin(), before.end(), '\n')) + 1;
  const std::size_t column = before.size() - (before.rfind('\n') + 1) + 1;
  throw InputError(
      file, line,
      "binary content (NUL byte at column " + std::to_string(column) + "): not a text file");
}

std::string readInputFile(const std::filesystem::path& file) {
  const std::string name = file.string();
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) throw InputError(name, 0, "file not found");
  if (std::filesystem::is_directory(file, ec))
    throw InputError(name, 0, "is a directory, not a file");
  checkInputSize(file);
  std::ifstream in(file, std::ios::binary);
  std::string text;
  if (in) {
    in.seekg(0, std::ios::end);
    text.resize(static_cast<std::size_t>(std::max<std::streamoff>(in.tellg(), 0)));
    in.seekg(0, std::ios::beg);
    in.read(text.data(), static_cast<std::streamsize>(text.size()));
  }
  if (!in) throw InputError(name, 0, std::string("cannot read file: ") + std::strerror(errno));
  return text;
}

}  // namespace traverse::io
