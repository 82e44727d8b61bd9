#pragma once
/// \file
/// Logging for libraries that must not print by themselves. Libraries call
/// rgbdt::core::log(); nothing is shown until an application installs a sink
/// (e.g. set_log_sink(stderr_log_sink)).
#include <functional>
#include <sstream>
#include <string>
#include <string_view>

namespace rgbdt::core {

enum class LogLevel { kDebug = 0, kInfo = 1, kWarning = 2, kError = 3 };

using LogSink = std::function<void(LogLevel, std::string_view)>;

/// Installs the process-wide sink (thread-safe); an empty function silences logging.
void set_log_sink(LogSink sink);
/// Messages below this level are dropped before formatting reaches the sink.
void set_log_level(LogLevel level);
LogLevel log_level();
/// Sends one message to the sink, if any.
void log(LogLevel level, std::string_view message);
/// A ready-made sink that prints "[level] message" to stderr, for apps.
void stderr_log_sink(LogLevel level, std::string_view message);
const char* to_string(LogLevel level);

/// Convenience: log_info("found ", n, " points").
template <typename... Args>
void log_at(LogLevel level, const Args&... args) {
  if (level < log_level()) return;
  std::ostringstream os;
  (os << ... << args);
  log(level, os.str());
}
template <typename... Args> void log_debug(const Args&... a) { log_at(LogLevel::kDebug, a...); }
template <typename... Args> void log_info(const Args&... a) { log_at(LogLevel::kInfo, a...); }
template <typename... Args> void log_warning(const Args&... a) { log_at(LogLevel::kWarning, a...); }
template <typename... Args> void log_error(const Args&... a) { log_at(LogLevel::kError, a...); }

}  // namespace rgbdt::core
