#pragma once
/// \file
/// `--config FILE` for every app: a YAML file of option values, one key per long option name
/// (without the leading `--`; `_` may stand for `-`), a nested mapping per subcommand.
/// Options given on the command line override the file. A key that names no option of the
/// app, a duplicate key, a mapping where a value belongs or a value an option's check refuses
/// is an error naming the file, the key and its line. The files in config/ are examples.
///
///   # rgbdt_mapper --config config/mapping.yaml SESSION --out MAP
///   resolution: 0.05        # [m]
///   icp: rgicp
///
/// effective_config_yaml / effective_config_json give every option with the value the app
/// runs with (from the command line, the file or its default), for reports and summaries.
#include <CLI/CLI.hpp>

#include <string>

namespace rgbdt::apps {

/// Adds `--config FILE` to `app`. Call right after constructing `app`, before its options
/// and subcommands are added: it also makes every option record its default, so that the
/// effective configuration can name it. argv is read for the file's name (CLI11 does not
/// hand it to the reader), to put it in error messages. A file that is not a YAML mapping but
/// has an INI section line (`[SECTION]`) is refused with a message that says it looks like an
/// INI file, followed by `ini_hint`: where the app takes an INI instead, if anywhere.
void add_config_option(CLI::App& app, int argc, const char* const* argv,
                       const std::string& ini_hint = "");

/// Every option of `app` and of its parsed subcommands (help, `--config` and options without
/// a long name excepted) with its effective value, as YAML that `--config` reads back.
std::string effective_config_yaml(const CLI::App& app);

/// The same as a JSON object (values as strings or lists of strings; flags as true/false).
std::string effective_config_json(const CLI::App& app);

}  // namespace rgbdt::apps
