#include "app_config.hpp"

#include <yaml-cpp/yaml.h>

#include <cstdio>
#include <cstring>
#include <iterator>
#include <memory>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace rgbdt::apps {
namespace {

/// The config file named on the command line (`--config F` or `--config=F`), or "".
std::string config_path_in(int argc, const char* const* argv) {
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--config") == 0 && i + 1 < argc) return argv[i + 1];
    if (std::strncmp(argv[i], "--config=", 9) == 0) return argv[i] + 9;
  }
  return {};
}

/// The option that `key` names in `app`: its long name, with `_` read as `-`, or a
/// positional's name.
const CLI::Option* option_for(const CLI::App& app, std::string key) {
  for (char& c : key) {
    if (c == '_') c = '-';
  }
  if (const CLI::Option* op = app.get_option_no_throw("--" + key)) return op;
  return app.get_option_no_throw(key);
}

const CLI::App* subcommand_for(const CLI::App& app, const std::string& name) {
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    if (sub->get_name() == name) return sub;
  }
  return nullptr;
}

bool is_config_or_help(const CLI::App& app, const CLI::Option* op) {
  return op == app.get_config_ptr() || op == app.get_help_ptr() || op == app.get_help_all_ptr();
}

/// The long options and subcommand names of `app`, for the message on an unknown key.
std::string keys_of(const CLI::App& app) {
  std::string out;
  for (const CLI::Option* op : app.get_options()) {
    if (is_config_or_help(app, op) || op->get_lnames().empty()) continue;
    out += (out.empty() ? "" : ", ") + op->get_lnames().front();
  }
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    out += (out.empty() ? "" : ", ") + sub->get_name() + " (a mapping)";
  }
  return out.empty() ? "none" : out;
}

/// The first line of `text` that is an INI section header (`[SECTION]`), with its number, or
/// an empty string: an INI file given to `--config` gets a message that says so.
std::string ini_section_line(const std::string& text, int& line_number) {
  static const std::regex kSection(R"(^\s*\[[A-Za-z0-9_ .:-]+\]\s*$)");
  std::istringstream in(text);
  std::string line;
  for (line_number = 1; std::getline(in, line); ++line_number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (std::regex_match(line, kSection)) return line;
  }
  return {};
}

/// Reads the YAML into CLI11's items, checking every key against the app so that a typo is an
/// error naming the file and line instead of a value silently left at its default.
class YamlConfig : public CLI::Config {
 public:
  YamlConfig(const CLI::App* app, std::string path, std::string ini_hint)
      : app_(app), path_(std::move(path)), ini_hint_(std::move(ini_hint)) {}

  std::string to_config(const CLI::App* app, bool, bool, std::string) const override {
    return effective_config_yaml(*app);
  }

  std::vector<CLI::ConfigItem> from_config(std::istream& in) const override {
    std::string text;
    text.reserve(4096);
    char buffer[4096];
    while (in.read(buffer, sizeof buffer) || in.gcount() > 0) {
      text.append(buffer, static_cast<std::size_t>(in.gcount()));
      if (text.size() > core::kMaxYamlBytes) {
        throw CLI::ConfigError(path_ + ": larger than " + std::to_string(core::kMaxYamlBytes) +
                               " bytes, expected a YAML file of option values");
      }
    }
    std::vector<CLI::ConfigItem> items;
    try {
      const YAML::Node root = core::load_yaml_string(text, path_);
      collect(*app_, core::YamlField(root, path_), {}, items);
    } catch (const core::Error& e) {
      int line = 0;
      const std::string section = ini_section_line(text, line);
      if (section.empty()) throw CLI::ConfigError(e.what());
      throw CLI::ConfigError(std::string(e.what()) + "\n" + path_ +
                             " looks like an INI file (line " + std::to_string(line) + ": " +
                             section +
                             "); --config takes a YAML file of option values (examples in "
                             "config/)" +
                             (ini_hint_.empty() ? "" : "; " + ini_hint_));
    }
    return items;
  }

 private:
  void collect(const CLI::App& app, const core::YamlField& map,
               const std::vector<std::string>& parents, std::vector<CLI::ConfigItem>& items) const {
    for (const auto& [key, value] : map.entries("a mapping of option names to values")) {
      if (const CLI::App* sub = subcommand_for(app, key); sub != nullptr && value.is_map()) {
        std::vector<std::string> inner = parents;
        inner.push_back(key);
        collect(*sub, value, inner, items);
        continue;
      }
      const CLI::Option* op = option_for(app, key);
      if (op == nullptr || is_config_or_help(app, op)) {
        value.fail("which names no option of " + app.get_name() +
                   "; expected one of: " + keys_of(app));
      }
      if (value.node().IsNull())
        continue;  // `key: ~` (as the effective configuration writes an unset option)
      CLI::ConfigItem item;
      item.parents = parents;
      item.name = op->get_lnames().empty() ? op->get_name() : op->get_lnames().front();
      if (value.is_sequence()) {
        const std::size_t n = value.expect_sequence("a list of values", 10000);
        for (std::size_t i = 0; i < n; ++i)
          item.inputs.push_back(value.item(i).as_string("a value"));
      } else {
        item.inputs.push_back(value.as_string("a value for " + item.name));
      }
      items.push_back(std::move(item));
    }
  }

  const CLI::App* app_;
  std::string path_;
  std::string ini_hint_;
};

/// One option's effective value: what the command line or the file gave, else its default.
struct Entry {
  std::string key;
  std::vector<std::string> values;
  bool is_flag = false;
  bool flag_value = false;
};

struct Section {
  std::vector<Entry> entries;
  std::vector<std::pair<std::string, Section>> subsections;
};

Section section_of(const CLI::App& app) {
  Section s;
  for (const CLI::Option* op : app.get_options()) {
    if (is_config_or_help(app, op)) continue;
    Entry e;
    e.key = op->get_lnames().empty() ? op->get_name() : op->get_lnames().front();
    if (e.key.empty()) continue;
    if (op->get_expected_min() == 0) {
      e.is_flag = true;
      if (op->count() > 0) {
        try {
          e.flag_value = op->as<bool>();
        } catch (const CLI::Error&) {
          e.flag_value = true;
        }
      }
    } else if (op->count() > 0) {
      e.values = op->results();
    } else if (!op->get_default_str().empty()) {
      e.values = {op->get_default_str()};
    }
    s.entries.push_back(std::move(e));
  }
  for (const CLI::App* sub : app.get_subcommands())
    s.subsections.emplace_back(sub->get_name(), section_of(*sub));
  return s;
}

void emit(YAML::Emitter& out, const Section& s) {
  out << YAML::BeginMap;
  for (const Entry& e : s.entries) {
    out << YAML::Key << e.key << YAML::Value;
    if (e.is_flag) {
      out << e.flag_value;
    } else if (e.values.empty()) {
      out << YAML::Null;
    } else if (e.values.size() == 1) {
      out << e.values.front();
    } else {
      out << YAML::Flow << e.values;
    }
  }
  for (const auto& [name, sub] : s.subsections) {
    out << YAML::Key << name << YAML::Value;
    emit(out, sub);
  }
  out << YAML::EndMap;
}

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char hex[8];
          std::snprintf(hex, sizeof hex, "\\u%04x", c);
          out += hex;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

void emit_json(std::ostream& out, const Section& s) {
  out << "{";
  const char* sep = "";
  for (const Entry& e : s.entries) {
    out << sep << json_string(e.key) << ": ";
    sep = ", ";
    if (e.is_flag) {
      out << (e.flag_value ? "true" : "false");
    } else if (e.values.empty()) {
      out << "null";
    } else if (e.values.size() == 1) {
      out << json_string(e.values.front());
    } else {
      out << "[";
      for (std::size_t i = 0; i < e.values.size(); ++i)
        out << (i ? ", " : "") << json_string(e.values[i]);
      out << "]";
    }
  }
  for (const auto& [name, sub] : s.subsections) {
    out << sep << json_string(name) << ": ";
    sep = ", ";
    emit_json(out, sub);
  }
  out << "}";
}

}  // namespace

void add_config_option(CLI::App& app, int argc, const char* const* argv,
                       const std::string& ini_hint) {
  app.option_defaults()->always_capture_default();
  app.config_formatter(std::make_shared<YamlConfig>(&app, config_path_in(argc, argv), ini_hint));
  app.set_config("--config", "",
                 "YAML file of option values: one key per long option name (without --), a "
                 "mapping per subcommand; the command line overrides it (examples in config/)");
}

std::string effective_config_yaml(const CLI::App& app) {
  YAML::Emitter out;
  emit(out, section_of(app));
  return std::string(out.c_str()) + "\n";
}

std::string effective_config_json(const CLI::App& app) {
  std::ostringstream out;
  emit_json(out, section_of(app));
  return out.str();
}

}  // namespace rgbdt::apps
