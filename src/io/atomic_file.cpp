#include "traverse/io/atomic_file.h"

#include <fstream>
#include <stdexcept>
#include <string>

namespace traverse::io {

void writeFileAtomically(const std::filesystem::path& file, std::string_view text) {
  const std::filesystem::path tmp(file.string() + ".tmp");
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f.write(text.data(), static_cast<std::streamsize>(text.size()));
    f.flush();
    if (!f) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw std::runtime_error("cannot write " + tmp.string());
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw std::runtime_error("cannot rename " + tmp.string() + " to " + file.string() + ": " +
                             ec.message());
  }
}

}  // namespace traverse::io
