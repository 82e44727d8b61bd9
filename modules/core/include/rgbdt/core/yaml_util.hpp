#pragma once
/// \file
/// Helpers for reading YAML with errors that name the file, the key path (e.g.
/// `cameras.rgb.intrinsics`), the value found and what was expected. Used by the readers in
/// this module and by other modules' config readers.
///
/// Every document loaded here is also checked for duplicate keys (yaml-cpp keeps the first
/// and ignores the rest; here they are an error naming the key and its line), for its size
/// (at most kMaxYamlBytes) and for its nesting and node count, so that no contract reader
/// walks an unbounded tree.
#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace rgbdt::core {

/// Largest YAML file the readers accept [bytes]; contracts are far smaller.
constexpr std::size_t kMaxYamlBytes = 16u << 20;

/// Loads a YAML file; throws rgbdt::core::Error("path: cannot open ..." / "... line L").
/// The top level must be a mapping; duplicate keys are refused.
YAML::Node load_yaml_file(const std::string& path);
YAML::Node load_yaml_string(const std::string& text, const std::string& source);

/// A YAML node together with the file it came from and its key path from the document
/// root. The accessors check the node's kind and value and throw rgbdt::core::Error with
///   "<file>: key '<path>' has value '<value>' (line L), expected <what>"
/// so that no yaml-cpp exception ("invalid node ...") escapes a reader.
class YamlField {
 public:
  YamlField(YAML::Node node, std::string file, std::string path = {});

  const YAML::Node& node() const { return node_; }
  const std::string& file() const { return file_; }
  /// Key path from the root, e.g. "views[2].images.rgb"; empty for the root itself.
  const std::string& path() const { return path_; }

  bool is_map() const { return node_.IsMap(); }
  bool is_sequence() const { return node_.IsSequence(); }

  /// True when this is a mapping holding `key` (with any value, also null).
  bool has(const std::string& key) const;
  /// The child `key`; throws "missing key '<path>.<key>' (expected <expected>)" when this
  /// is not a mapping or lacks it.
  YamlField at(const std::string& key, const std::string& expected) const;
  /// The child `key` when present.
  std::optional<YamlField> find(const std::string& key) const;

  /// Checks this is a mapping / a list (of at most max_items items); throws otherwise.
  void expect_map(const std::string& expected) const;
  std::size_t expect_sequence(const std::string& expected, std::size_t max_items = 100000) const;
  /// Item i of a list (call expect_sequence first).
  YamlField item(std::size_t i) const;
  /// The entries of a mapping, in file order, with their keys as strings (every key must
  /// be a plain scalar).
  std::vector<std::pair<std::string, YamlField>> entries(const std::string& expected) const;

  /// A finite number written in full (".inf", ".nan", "0x64", "1.5abc" are errors).
  double as_double(const std::string& expected = "a finite number") const;
  /// A finite number within [lo, hi].
  double as_double_in(double lo, double hi, const std::string& expected) const;
  /// A decimal integer within [lo, hi].
  long long as_integer(long long lo, long long hi, const std::string& expected) const;
  /// A scalar string; non-empty unless allow_empty.
  std::string as_string(const std::string& expected = "a string", bool allow_empty = false) const;
  /// A list of exactly `size` finite numbers (size < 0: any length up to max_items).
  std::vector<double> as_numbers(int size, const std::string& expected = {},
                                 std::size_t max_items = 100000) const;

  /// Throws "<file>: key '<path>' has value ..., <problem>". `problem` says what was
  /// expected, e.g. "expected a radius in (0, 5] m".
  [[noreturn]] void fail(const std::string& problem) const;
  /// The value as printed in errors: a short, printable rendering of a scalar, or the
  /// node's kind ("a mapping", "a list", "nothing").
  std::string describe_value() const;
  /// "key '<path>'" (or "the document" for the root) with the line when known.
  std::string where() const;

 private:
  YAML::Node node_;
  std::string file_;
  std::string path_;
};

/// "parent.key", or "key" when parent is empty.
std::string yaml_key_path(const std::string& parent, const std::string& key);

/// The child `key` of `node`; throws "source: missing key 'key' (expected ...)".
YAML::Node require_key(const YAML::Node& node, const std::string& key,
                       const std::string& source, const std::string& expected);
/// A finite number written in full (see rgbdt/core/parse.hpp).
double require_double(const YAML::Node& node, const std::string& key, const std::string& source);
int require_int(const YAML::Node& node, const std::string& key, const std::string& source);
std::string require_string(const YAML::Node& node, const std::string& key,
                           const std::string& source);
/// A sequence of exactly `size` finite numbers (size < 0: any length).
std::vector<double> require_numbers(const YAML::Node& node, const std::string& key,
                                    const std::string& source, int size);

}  // namespace rgbdt::core
