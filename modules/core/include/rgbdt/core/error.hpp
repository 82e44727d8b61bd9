#pragma once
/// \file
/// Errors thrown by rgbdt libraries. Invalid arguments use std::invalid_argument;
/// problems with files, devices and data use rgbdt::core::Error, whose message always
/// names what was being read and what was expected.
#include <stdexcept>
#include <string>

namespace rgbdt::core {

/// A failure with context: the file (or device), the key/value at fault and what was
/// expected. what() returns all of it as one line.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
  Error(const std::string& source, const std::string& message)
      : std::runtime_error(source.empty() ? message : source + ": " + message),
        source_(source) {}

  /// The file or device the error is about (may be empty).
  const std::string& source() const { return source_; }

 private:
  std::string source_;
};

}  // namespace rgbdt::core
