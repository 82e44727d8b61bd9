#include "rgbdt/core/yaml_util.hpp"

#include <fstream>
#include <sstream>

#include "rgbdt/core/error.hpp"

namespace rgbdt::core {

YAML::Node load_yaml_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path, "cannot open file for reading");
  std::stringstream ss;
  ss << in.rdbuf();
  return load_yaml_string(ss.str(), path);
}

YAML::Node load_yaml_string(const std::string& text, const std::string& source) {
  try {
    YAML::Node node = YAML::Load(text);
    if (!node.IsMap()) throw Error(source, "expected a YAML mapping at the top level");
    return node;
  } catch (const YAML::Exception& e) {
    std::ostringstream os;
    os << "not valid YAML at line " << e.mark.line + 1 << ", column " << e.mark.column + 1
       << ": " << e.msg;
    throw Error(source, os.str());
  }
}

YAML::Node require_key(const YAML::Node& node, const std::string& key, const std::string& source,
                       const std::string& expected) {
  if (!node.IsMap() || !node[key]) {
    throw Error(source, "missing key '" + key + "' (expected " + expected + ")");
  }
  return node[key];
}

namespace {
template <typename T>
T convert(const YAML::Node& value, const std::string& key, const std::string& source,
          const char* expected) {
  try {
    if (!value.IsScalar()) throw YAML::Exception(value.Mark(), "not a scalar");
    return value.as<T>();
  } catch (const YAML::Exception&) {
    std::ostringstream os;
    os << "key '" << key << "' has value ";
    if (value.IsScalar()) os << "'" << value.Scalar() << "'"; else os << "that is not a scalar";
    os << ", expected " << expected;
    throw Error(source, os.str());
  }
}
}  // namespace

double require_double(const YAML::Node& node, const std::string& key, const std::string& source) {
  return convert<double>(require_key(node, key, source, "a number"), key, source, "a number");
}

int require_int(const YAML::Node& node, const std::string& key, const std::string& source) {
  return convert<int>(require_key(node, key, source, "an integer"), key, source, "an integer");
}

std::string require_string(const YAML::Node& node, const std::string& key,
                           const std::string& source) {
  return convert<std::string>(require_key(node, key, source, "a string"), key, source, "a string");
}

std::vector<double> require_numbers(const YAML::Node& node, const std::string& key,
                                    const std::string& source, int size) {
  const std::string expected =
      size < 0 ? "a list of numbers" : "a list of " + std::to_string(size) + " numbers";
  const YAML::Node seq = require_key(node, key, source, expected);
  if (!seq.IsSequence() || (size >= 0 && static_cast<int>(seq.size()) != size)) {
    std::ostringstream os;
    os << "key '" << key << "' has ";
    if (seq.IsSequence()) os << seq.size() << " values"; else os << "a value that is not a list";
    os << ", expected " << expected;
    throw Error(source, os.str());
  }
  std::vector<double> out;
  for (size_t i = 0; i < seq.size(); ++i) {
    out.push_back(convert<double>(seq[i], key + "[" + std::to_string(i) + "]", source, "a number"));
  }
  return out;
}

}  // namespace rgbdt::core
