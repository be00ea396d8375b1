// Writing a file so that nothing already written is lost: the text goes to "<file>.tmp", which
// is renamed over the file only when complete (a failure leaves the previous file intact).
#pragma once

#include <filesystem>
#include <string_view>

namespace traverse::io {

/// Throws std::runtime_error naming the file when it cannot be written or renamed.
void writeFileAtomically(const std::filesystem::path& file, std::string_view text);

}  // namespace traverse::io
