// Errors with context. Bad input is an InputError: file, line (0 when not line-specific) and
// what is wrong; the CLI prints it as one line "file:line: message" and exits with code 2.
#pragma once

#include <stdexcept>
#include <string>

namespace traverse {

class InputError : public std::runtime_error {
 public:
  InputError(std::string file, long line, std::string what)
      : std::runtime_error(format(file, line, what)),
        file_(std::move(file)),
        line_(line),
        message_(std::move(what)) {}

  const std::string& file() const { return file_; }
  long line() const { return line_; }
  const std::string& message() const { return message_; }

 private:
  static std::string format(const std::string& file, long line, const std::string& what) {
    return line > 0 ? file + ":" + std::to_string(line) + ": " + what : file + ": " + what;
  }
  std::string file_;
  long line_;
  std::string message_;
};

/// A computation the data made impossible (a covariance that is not positive definite, a
/// weight that would be infinite): the caller may fall back, unlike a std::logic_error, which is
/// a bug and must surface.
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace traverse
