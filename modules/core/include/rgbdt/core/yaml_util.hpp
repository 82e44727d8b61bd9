#pragma once
/// \file
/// Helpers for reading YAML with errors that name the file, the key and what was expected.
/// Used by the readers in this module and by other modules' config readers.
#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

namespace rgbdt::core {

/// Loads a YAML file; throws rgbdt::core::Error("path: cannot open ..." / "... line L").
YAML::Node load_yaml_file(const std::string& path);
YAML::Node load_yaml_string(const std::string& text, const std::string& source);

/// The child `key` of `node`; throws "source: missing key 'key' (expected ...)".
YAML::Node require_key(const YAML::Node& node, const std::string& key,
                       const std::string& source, const std::string& expected);
double require_double(const YAML::Node& node, const std::string& key, const std::string& source);
int require_int(const YAML::Node& node, const std::string& key, const std::string& source);
std::string require_string(const YAML::Node& node, const std::string& key,
                           const std::string& source);
/// A sequence of exactly `size` numbers (size < 0: any length).
std::vector<double> require_numbers(const YAML::Node& node, const std::string& key,
                                    const std::string& source, int size);

}  // namespace rgbdt::core
