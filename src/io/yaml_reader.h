// Strict YAML reading shared by rover.yaml and scenario files: unknown keys, wrong types and
// values out of range are InputErrors naming the file, the line and the dotted key.
#pragma once

#include <cmath>
#include <set>
#include <sstream>
#include <string>

#include <yaml-cpp/yaml.h>

#include "traverse/core/error.h"
#include "traverse/core/types.h"

namespace traverse::io::detail {

class YamlReader {
 public:
  explicit YamlReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const YAML::Node& n, const std::string& key,
                         const std::string& what) const {
    const long line = n.IsDefined() ? static_cast<long>(n.Mark().line) + 1 : 0;
    throw InputError(file_, line, "key '" + key + "': " + what);
  }

  /// A mapping's key as text. YAML allows a list or a mapping as a key (`? [a, b]: 1`), which
  /// yaml-cpp cannot convert to a string (it threw YAML::TypedBadConversion past the reader).
  std::string key(const YAML::Node& k, const std::string& prefix) const {
    if (!k.IsScalar() && !k.IsNull())
      fail(k, prefix.empty() ? "(top level)" : prefix,
           "a key must be plain text, not a list or mapping");
    return k.as<std::string>();
  }

  /// Checks that a map holds only the given keys (typos are errors, not silent defaults).
  void onlyKeys(const YAML::Node& map, const std::string& prefix,
                const std::set<std::string>& keys) const {
    if (!map.IsMap()) fail(map, prefix, "expected a mapping");
    for (const auto& kv : map) {
      const std::string k = key(kv.first, prefix);
      if (!keys.count(k)) fail(kv.first, prefix.empty() ? k : prefix + "." + k, "unknown key");
    }
  }

  double number(const YAML::Node& map, const std::string& prefix, const std::string& key,
                double value, double lo, double hi) const {
    const YAML::Node n = map[key];
    if (!n.IsDefined() || n.IsNull()) return value;
    const std::string name = join(prefix, key);
    double v = 0.0;
    if (!n.IsScalar() || !YAML::convert<double>::decode(n, v)) fail(n, name, "expected a number");
    if (!std::isfinite(v)) fail(n, name, "must be finite");
    if (v < lo || v > hi) {
      std::ostringstream os;
      os << "value " << v << " out of range [" << lo << ", " << hi << "]";
      fail(n, name, os.str());
    }
    return v;
  }

  int integer(const YAML::Node& map, const std::string& prefix, const std::string& key, int value,
              int lo, int hi) const {
    const YAML::Node n = map[key];
    if (!n.IsDefined() || n.IsNull()) return value;
    int v = 0;
    if (!n.IsScalar() || !YAML::convert<int>::decode(n, v))
      fail(n, join(prefix, key), "expected an integer");
    if (v < lo || v > hi)
      fail(n, join(prefix, key), "value " + std::to_string(v) + " out of range");
    return v;
  }

  bool boolean(const YAML::Node& map, const std::string& prefix, const std::string& key,
               bool value) const {
    const YAML::Node n = map[key];
    if (!n.IsDefined() || n.IsNull()) return value;
    bool v = false;
    if (!n.IsScalar() || !YAML::convert<bool>::decode(n, v))
      fail(n, join(prefix, key), "expected true or false");
    return v;
  }

  std::string string(const YAML::Node& map, const std::string& prefix, const std::string& key,
                     std::string value) const {
    const YAML::Node n = map[key];
    if (!n.IsDefined() || n.IsNull()) return value;
    if (!n.IsScalar()) fail(n, join(prefix, key), "expected a string");
    return n.as<std::string>();
  }

  Vec3d vec3(const YAML::Node& map, const std::string& prefix, const std::string& key,
             Vec3d value) const {
    const YAML::Node n = map[key];
    if (!n.IsDefined() || n.IsNull()) return value;
    if (!n.IsSequence() || n.size() != 3)
      fail(n, join(prefix, key), "expected a list of 3 numbers");
    for (int i = 0; i < 3; ++i) {
      double v = 0.0;
      if (!n[i].IsScalar() || !YAML::convert<double>::decode(n[i], v) || !std::isfinite(v)) {
        fail(n, join(prefix, key), "expected a list of 3 finite numbers");
      }
      value[i] = v;
    }
    return value;
  }

  YAML::Node section(const YAML::Node& root, const std::string& key,
                     const std::set<std::string>& keys) const {
    const YAML::Node n = root[key];
    if (!n.IsDefined() || n.IsNull()) return YAML::Node(YAML::NodeType::Map);
    onlyKeys(n, key, keys);
    return n;
  }

  static std::string join(const std::string& prefix, const std::string& key) {
    return prefix.empty() ? key : prefix + "." + key;
  }

 private:
  std::string file_;
};

}  // namespace traverse::io::detail
