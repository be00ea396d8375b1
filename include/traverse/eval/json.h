// A tiny JSON writer for the evaluation outputs (metrics.json, `bench accuracy --json`;
// ../shared/docs/outputs.md). Objects and arrays (an array's elements one per line, or on the
// array's line inside a compact object), two-space indentation, keys in the order written.
//
// Numbers use std::to_chars' shortest round-trip form, so a reader gets back the exact double;
// a non-finite number is written as `null` (JSON has no NaN or infinity, and a metric that
// blew up must not be mistaken for a number). Strings are escaped per RFC 8259 §7.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace traverse::eval {

/// The JSON text of a number: shortest round-trip, or "null" when not finite.
std::string jsonNumber(double value);
/// The JSON text of a string, quotes included.
std::string jsonString(std::string_view text);

class JsonWriter {
 public:
  /// Opens an object (as the document, or as the value of the preceding key). A compact object
  /// is written on one line: {"mean": 1, "std": 2}.
  JsonWriter& beginObject(bool compact = false);
  JsonWriter& endObject();
  /// Opens an array as the value of the preceding key (or an element of an enclosing array).
  JsonWriter& beginArray();
  JsonWriter& endArray();
  JsonWriter& key(std::string_view name);
  JsonWriter& number(double value);
  JsonWriter& integer(long long value);
  JsonWriter& boolean(bool value);
  JsonWriter& string(std::string_view text);

  /// The document so far, with a final newline once the outermost object is closed.
  const std::string& text() const { return out_; }

 private:
  struct Level {
    bool compact = false;
    bool empty = true;
    bool array = false;
  };
  void raw(std::string_view token);
  void element();  ///< inside an array: the separator before the next element
  void newline();  ///< line break and the indentation of the current depth
  std::vector<Level> stack_;
  std::string out_;
};

/// Writes `text` to "<file>.tmp" and renames it over `file`, so a reader never sees half a
/// file and a failure leaves the previous one intact. Throws std::runtime_error naming the file.
void writeTextAtomically(const std::filesystem::path& file, const std::string& text);

}  // namespace traverse::eval
