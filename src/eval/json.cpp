#include "traverse/eval/json.h"

#include "traverse/io/atomic_file.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

namespace traverse::eval {

std::string jsonNumber(double value) {
  if (!std::isfinite(value)) return "null";
  char buf[32];
  return std::string(buf, std::to_chars(buf, buf + sizeof buf, value).ptr);
}

std::string jsonString(std::string_view text) {
  std::string out = "\"";
  for (const char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\b':
        out += "\\b";
        break;
      case '\f':
        out += "\\f";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
          out += buf;
        } else {
          out += c;  // UTF-8 passes through unchanged (RFC 8259 §8.1)
        }
    }
  }
  return out + "\"";
}

JsonWriter& JsonWriter::beginObject(bool compact) {
  element();
  // A nested object inherits compactness: everything inside a one-line object stays on it.
  compact = compact || (!stack_.empty() && stack_.back().compact);
  out_ += "{";
  stack_.push_back(Level{compact, true, false});
  return *this;
}

JsonWriter& JsonWriter::beginArray() {
  if (stack_.empty()) throw std::logic_error("JsonWriter: array outside an object");
  element();
  out_ += "[";
  stack_.push_back(Level{stack_.back().compact, true, true});
  return *this;
}

JsonWriter& JsonWriter::endArray() {
  if (stack_.empty() || !stack_.back().array)
    throw std::logic_error("JsonWriter: endArray without beginArray");
  const Level level = stack_.back();
  stack_.pop_back();
  if (!level.compact && !level.empty) newline();
  out_ += "]";
  return *this;
}

void JsonWriter::element() {
  if (stack_.empty() || !stack_.back().array) return;
  Level& level = stack_.back();
  if (!level.empty) out_ += ",";
  if (level.compact) {
    if (!level.empty) out_ += " ";
  } else {
    newline();
  }
  level.empty = false;
}

JsonWriter& JsonWriter::endObject() {
  if (stack_.empty() || stack_.back().array)
    throw std::logic_error("JsonWriter: endObject without beginObject");
  const Level level = stack_.back();
  stack_.pop_back();
  if (!level.compact && !level.empty) newline();
  out_ += "}";
  if (stack_.empty()) out_ += "\n";
  return *this;
}

JsonWriter& JsonWriter::key(std::string_view name) {
  if (stack_.empty() || stack_.back().array)
    throw std::logic_error("JsonWriter: key outside an object");
  Level& level = stack_.back();
  if (!level.empty) out_ += ",";
  if (level.compact) {
    if (!level.empty) out_ += " ";
  } else {
    newline();
  }
  level.empty = false;
  out_ += jsonString(name) + ": ";
  return *this;
}

void JsonWriter::newline() {
  // Appended piecewise: "\n" + std::string(n, ' ') trips GCC 12's -Wrestrict false positive.
  out_ += '\n';
  out_.append(2 * stack_.size(), ' ');
}

void JsonWriter::raw(std::string_view token) {
  if (stack_.empty()) throw std::logic_error("JsonWriter: value outside an object");
  element();
  out_ += token;
}

JsonWriter& JsonWriter::number(double value) {
  raw(jsonNumber(value));
  return *this;
}

JsonWriter& JsonWriter::integer(long long value) {
  raw(std::to_string(value));
  return *this;
}

JsonWriter& JsonWriter::boolean(bool value) {
  raw(value ? "true" : "false");
  return *this;
}

JsonWriter& JsonWriter::string(std::string_view text) {
  raw(jsonString(text));
  return *this;
}

void writeTextAtomically(const std::filesystem::path& file, const std::string& text) {
  io::writeFileAtomically(file, text);
}

}  // namespace traverse::eval
