#include "rgbdt/core/yaml_util.hpp"

#include <fstream>
#include <map>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/parse.hpp"

namespace rgbdt::core {
namespace {

// Contracts nest a few levels; a deeper or larger tree is not one of ours.
constexpr int kMaxDepth = 64;
constexpr std::size_t kMaxNodes = 1000000;

std::string line_of(const YAML::Node& node) {
  const YAML::Mark m = node.Mark();
  return m.line >= 0 ? std::to_string(m.line + 1) : std::string("?");
}

std::string printable(const std::string& text, std::size_t max_chars = 60) {
  std::string out;
  for (const char ch : text) {
    if (out.size() >= max_chars) {
      out += "...";
      break;
    }
    const auto c = static_cast<unsigned char>(ch);
    out += (c >= 0x20 && c < 0x7f) ? ch : '?';
  }
  return out;
}

struct TreeCheck {
  const std::string& source;
  std::size_t nodes = 0;

  void walk(const YAML::Node& node, const std::string& path, int depth) {
    if (++nodes > kMaxNodes) {
      throw Error(source, "more than " + std::to_string(kMaxNodes) +
                              " YAML nodes (aliases expand too far?), expected a small document");
    }
    if (depth > kMaxDepth) {
      throw Error(source, "key '" + path + "' (line " + line_of(node) + ") is nested deeper than " +
                              std::to_string(kMaxDepth) + " levels, expected a shallow document");
    }
    if (node.IsMap()) {
      std::map<std::string, std::string> seen;  // key -> line of its first use
      for (auto it = node.begin(); it != node.end(); ++it) {
        if (!it->first.IsScalar()) {
          throw Error(source, "a key under '" + (path.empty() ? std::string("the top level") : path) +
                                  "' (line " + line_of(it->first) +
                                  ") is not a plain word, expected scalar keys");
        }
        const std::string key = it->first.Scalar();
        const std::string child = yaml_key_path(path, key);
        const auto [pos, inserted] = seen.emplace(key, line_of(it->first));
        if (!inserted) {
          throw Error(source, "key '" + printable(child) + "' appears twice (lines " + pos->second +
                                  " and " + line_of(it->first) + "), expected each key once");
        }
        walk(it->second, child, depth + 1);
      }
    } else if (node.IsSequence()) {
      for (std::size_t i = 0; i < node.size(); ++i) {
        walk(node[i], path + "[" + std::to_string(i) + "]", depth + 1);
      }
    }
  }
};

}  // namespace

std::string yaml_key_path(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

YAML::Node load_yaml_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path, "cannot open file for reading");
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0 || static_cast<std::size_t>(size) > kMaxYamlBytes) {
    throw Error(path, "file of " + std::to_string(size) + " bytes, expected a YAML file of at most " +
                          std::to_string(kMaxYamlBytes) + " bytes");
  }
  in.seekg(0, std::ios::beg);
  std::stringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw Error(path, "read failed");
  return load_yaml_string(ss.str(), path);
}

YAML::Node load_yaml_string(const std::string& text, const std::string& source) {
  if (text.size() > kMaxYamlBytes) {
    throw Error(source, "text of " + std::to_string(text.size()) +
                            " bytes, expected a YAML document of at most " +
                            std::to_string(kMaxYamlBytes) + " bytes");
  }
  YAML::Node node;
  try {
    node = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    std::ostringstream os;
    os << "not valid YAML at line " << e.mark.line + 1 << ", column " << e.mark.column + 1
       << ": " << e.msg;
    throw Error(source, os.str());
  }
  if (!node.IsMap()) throw Error(source, "expected a YAML mapping at the top level");
  TreeCheck{source}.walk(node, "", 0);
  return node;
}

// ---------------------------------------------------------------------------------------
// YamlField

// A missing child (yaml-cpp's "zombie" node) throws on every question but IsDefined(); it
// is kept as an empty node so that errors about it can be raised.
YamlField::YamlField(YAML::Node node, std::string file, std::string path)
    : node_(node.IsDefined() ? std::move(node) : YAML::Node()), file_(std::move(file)), path_(std::move(path)) {}

std::string YamlField::where() const {
  std::string w = path_.empty() ? std::string("the document") : "key '" + printable(path_, 200) + "'";
  const YAML::Mark m = node_.Mark();
  if (m.line >= 0) w += " (line " + std::to_string(m.line + 1) + ")";
  return w;
}

std::string YamlField::describe_value() const {
  if (node_.IsScalar()) return "'" + printable(node_.Scalar()) + "'";
  if (node_.IsMap()) return "a mapping";
  if (node_.IsSequence()) {
    // Short lists of scalars are shown as written, e.g. [-1.2, 0].
    std::string items;
    for (std::size_t i = 0; i < node_.size() && items.size() <= 60; ++i) {
      if (!node_[i].IsScalar()) {
        items.clear();
        break;
      }
      items += (i ? ", " : "") + printable(node_[i].Scalar(), 20);
    }
    if (!items.empty() && items.size() <= 60) return "[" + items + "]";
    return "a list of " + std::to_string(node_.size()) + " items";
  }
  return "nothing";
}

void YamlField::fail(const std::string& problem) const {
  throw Error(file_, where() + " has value " + describe_value() + ", " + problem);
}

bool YamlField::has(const std::string& key) const {
  if (!node_.IsMap()) return false;
  const YAML::Node& n = node_;
  return static_cast<bool>(n[key]);
}

YamlField YamlField::at(const std::string& key, const std::string& expected) const {
  const std::string child = yaml_key_path(path_, key);
  if (!node_.IsMap()) {
    fail("expected a mapping holding key '" + printable(key) + "' (" + expected + ")");
  }
  if (!has(key)) {
    std::string msg = "missing key '" + printable(child, 200) + "' (expected " + expected + ")";
    if (!path_.empty()) msg += " in " + where();
    throw Error(file_, msg);
  }
  const YAML::Node& n = node_;
  return YamlField(n[key], file_, child);
}

std::optional<YamlField> YamlField::find(const std::string& key) const {
  if (!has(key)) return std::nullopt;
  const YAML::Node& n = node_;
  return YamlField(n[key], file_, yaml_key_path(path_, key));
}

void YamlField::expect_map(const std::string& expected) const {
  if (!node_.IsMap()) fail("expected " + expected);
}

std::size_t YamlField::expect_sequence(const std::string& expected, std::size_t max_items) const {
  if (!node_.IsSequence()) fail("expected " + expected);
  if (node_.size() > max_items) {
    fail("expected " + expected + " of at most " + std::to_string(max_items) + " items");
  }
  return node_.size();
}

YamlField YamlField::item(std::size_t i) const {
  if (!node_.IsSequence() || i >= node_.size()) {
    fail("expected a list with an item " + std::to_string(i));
  }
  return YamlField(node_[i], file_, path_ + "[" + std::to_string(i) + "]");
}

std::vector<std::pair<std::string, YamlField>> YamlField::entries(const std::string& expected) const {
  expect_map(expected);
  std::vector<std::pair<std::string, YamlField>> out;
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    if (!it->first.IsScalar()) fail("expected " + expected + " with plain keys");
    const std::string key = it->first.Scalar();
    out.emplace_back(key, YamlField(it->second, file_, yaml_key_path(path_, key)));
  }
  return out;
}

double YamlField::as_double(const std::string& expected) const {
  if (!node_.IsScalar()) fail("expected " + expected);
  const auto v = parse_finite_double(node_.Scalar());
  if (!v) fail("expected " + expected);
  return *v;
}

double YamlField::as_double_in(double lo, double hi, const std::string& expected) const {
  const double v = as_double(expected);
  if (!(v >= lo && v <= hi)) fail("expected " + expected);
  return v;
}

long long YamlField::as_integer(long long lo, long long hi, const std::string& expected) const {
  if (!node_.IsScalar()) fail("expected " + expected);
  const auto v = parse_integer(node_.Scalar(), lo, hi);
  if (!v) fail("expected " + expected);
  return *v;
}

std::string YamlField::as_string(const std::string& expected, bool allow_empty) const {
  if (!node_.IsScalar()) fail("expected " + expected);
  if (!allow_empty && node_.Scalar().empty()) fail("expected " + expected);
  return node_.Scalar();
}

std::vector<double> YamlField::as_numbers(int size, const std::string& expected,
                                          std::size_t max_items) const {
  const std::string what = !expected.empty() ? expected
                           : size < 0        ? std::string("a list of finite numbers")
                                             : "a list of " + std::to_string(size) + " finite numbers";
  if (!node_.IsSequence()) fail("expected " + what);
  if ((size >= 0 && node_.size() != static_cast<std::size_t>(size)) ||
      (size < 0 && node_.size() > max_items)) {
    throw Error(file_, where() + " has " + std::to_string(node_.size()) + " values, expected " + what);
  }
  std::vector<double> out;
  out.reserve(node_.size());
  for (std::size_t i = 0; i < node_.size(); ++i) out.push_back(item(i).as_double("a finite number"));
  return out;
}

// ---------------------------------------------------------------------------------------
// Plain-node helpers (the source already names the file and the section).

YAML::Node require_key(const YAML::Node& node, const std::string& key, const std::string& source,
                       const std::string& expected) {
  return YamlField(node, source).at(key, expected).node();
}

double require_double(const YAML::Node& node, const std::string& key, const std::string& source) {
  return YamlField(node, source).at(key, "a number").as_double("a finite number");
}

int require_int(const YAML::Node& node, const std::string& key, const std::string& source) {
  return static_cast<int>(
      YamlField(node, source).at(key, "an integer").as_integer(-2147483647LL - 1, 2147483647LL, "an integer"));
}

std::string require_string(const YAML::Node& node, const std::string& key,
                           const std::string& source) {
  return YamlField(node, source).at(key, "a string").as_string("a string");
}

std::vector<double> require_numbers(const YAML::Node& node, const std::string& key,
                                    const std::string& source, int size) {
  const std::string expected =
      size < 0 ? "a list of numbers" : "a list of " + std::to_string(size) + " numbers";
  return YamlField(node, source).at(key, expected).as_numbers(size, expected);
}

}  // namespace rgbdt::core
