#pragma once
// Command-line options derived from a configuration's one declaration (core/params.hpp): every
// field declared with a flag becomes that option, its help carrying the unit, bounds and the
// thesis' equation, its default shown. Plus the two options every configurable command has:
//   --print-config   the whole effective configuration as YAML (defaults, then --config, then
//                    flags), then exit
//   --config FILE    start from FILE (as printed), flags still override.
//
// The options parse into holders, not into the configuration, so that the order is always
// defaults → file → flags: `apply` writes the given flags over a configuration built from the
// file. A holder finds its field in the target by the field's offset within the configuration
// object (the same type: the same layout).
#include <fmt/core.h>
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/io/params_yaml.hpp"
#include "sonar3d/io/yaml_config.hpp"

namespace sonar3d::cli {

// Each field's dotted path -> its flag.
struct FlagCollector : params::PathVisitor<FlagCollector> {
  std::vector<std::pair<std::string, std::string>> names;
  template <class T>
  void field(T&, const params::Param& p) {
    if (!p.cli) return;
    const std::string path = params::join(prefix, p.key);
    // The bounds check says "path (flag) must ..."; the user reads "flag must ...".
    names.emplace_back(path + " (" + p.cli + ")", p.cli);
    names.emplace_back(path, p.cli);
  }
};

template <class C>
class ConfigOptions {
 public:
  // Adds the flagged fields of `defaults` (a default-constructed C unless given) to `cmd`.
  explicit ConfigOptions(CLI::App* cmd, const C& defaults = C()) : root_(defaults) {
    cmd->add_flag("--print-config", print_,
                  "print the whole effective configuration as YAML (defaults, then --config, "
                  "then the flags given) and exit");
    cmd->add_option("--config", file_,
                    "run from this configuration (YAML as --print-config prints it); flags "
                    "given still override")
        ->check(CLI::ExistingFile);
    Binder b{cmd, reinterpret_cast<const char*>(&root_), &appliers_};
    describe(root_, b);
  }

  bool print_requested() const { return print_; }
  const std::string& file() const { return file_; }

  // The effective configuration: defaults, then --config FILE under `key` (the whole file when
  // `key` is empty), then the flags given.
  C resolve(const std::string& key = "") const {
    C c = root_;
    if (!file_.empty()) {
      const YAML::Node doc = yaml::load_file(file_);
      const YAML::Node node = key.empty() ? doc : doc[key];
      if (!key.empty()) {
        require(static_cast<bool>(node),
                file_ + ": no '" + key + "' block (as --print-config prints it)");
        yaml::check_keys(doc, {key}, file_);
      }
      params::read_yaml(node, file_, key, c);
    }
    for (const auto& a : appliers_) a(reinterpret_cast<char*>(&c));
    return c;
  }

  // Each field's dotted path -> its flag, for with_flag_names(): errors of the library name the
  // user's flag, not the field.
  std::vector<std::pair<std::string, std::string>> flag_names() const {
    FlagCollector v;
    C copy = root_;
    describe(copy, v);
    return v.names;
  }

  // With --print-config: prints `config` under `key` (sonar3d <command>'s block, as --config
  // reads it) and returns true; else false.
  bool print_if_requested(const C& config, const std::string& key,
                          const std::string& command) const {
    if (!print_) return false;
    fmt::print("{}", yaml(config, key,
                          "sonar3d " + command +
                              ": the effective configuration (run with --config FILE; flags "
                              "override)"));
    return true;
  }

  // `config` as YAML under `key` (as --config reads it).
  static std::string yaml(const C& config, const std::string& key, const std::string& title) {
    YAML::Emitter out;
    out << YAML::Comment(title);
    if (key.empty()) {
      params::emit_yaml(out, config);
    } else {
      out << YAML::BeginMap << YAML::Key << key << YAML::Value;
      params::emit_yaml(out, config);
      out << YAML::EndMap;
    }
    return std::string(out.c_str()) + "\n";
  }

 private:
  using Applier = std::function<void(char*)>;
  struct Binder {
    CLI::App* cmd;
    const char* base;
    std::vector<Applier>* appliers;
    template <class T>
    void field(T& value, const params::Param& p) {
      // A flag sets the first field declared with it: a nested config that declares the same
      // flag as its parent (the deconvolution's own occlusion settings, say) keeps its field
      // for YAML and Python only.
      if (p.cli == nullptr || cmd->get_option_no_throw(p.cli) != nullptr) return;
      const std::ptrdiff_t offset = reinterpret_cast<const char*>(&value) - base;
      std::string help = p.help;
      if (*p.unit) help += ", " + std::string(p.unit);
      if (p.n_names > 0) help += "; " + params::choices_text(p);
      if (p.bounded()) help += "; " + params::bounds_text(p);
      if (p.eq) help += " (" + std::string(p.eq) + ")";
      if constexpr (std::is_enum_v<T>) {
        // An enum: its name (the declared choices) on the command line.
        auto holder = std::make_shared<std::string>(params::field_text(value, p));
        CLI::Option* opt = cmd->add_option(p.cli, *holder, help);
        opt->default_str(*holder);
        opt->check(CLI::IsMember(std::vector<std::string>(p.names, p.names + p.n_names)));
        const params::Param spec = p;
        appliers->push_back([holder, opt, offset, spec](char* c) {
          if (opt->count() > 0) {
            *reinterpret_cast<T*>(c + offset) =
                params::parse_choice<T>(spec, *holder, std::string(spec.cli));
          }
        });
      } else if constexpr (std::is_same_v<T, params::Box>) {
        // A box: six numbers, xmin ymin zmin xmax ymax zmax.
        auto holder = std::make_shared<std::vector<double>>();
        CLI::Option* opt =
            cmd->add_option(p.cli, *holder, help + "; xmin ymin zmin xmax ymax zmax");
        opt->expected(6);
        opt->default_str(params::field_text(value, p));
        appliers->push_back([holder, opt, offset](char* c) {
          if (opt->count() > 0) {
            const auto& v = *holder;
            *reinterpret_cast<T*>(c + offset) = Eigen::AlignedBox3d(
                Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5]));
          }
        });
      } else if constexpr (std::is_same_v<T, params::Maybe>) {
        // An optional number: absent unless the flag is given (or the file sets it).
        auto holder = std::make_shared<double>(0);
        CLI::Option* opt = cmd->add_option(p.cli, *holder, help);
        opt->default_str(params::field_text(value, p));
        appliers->push_back([holder, opt, offset](char* c) {
          if (opt->count() > 0) *reinterpret_cast<T*>(c + offset) = *holder;
        });
      } else if constexpr (std::is_same_v<T, params::List>) {
        // A list: comma-separated numbers ("0.05,0.2,1").
        auto holder = std::make_shared<params::List>();
        CLI::Option* opt = cmd->add_option(p.cli, *holder, help + "; comma-separated");
        opt->delimiter(',');
        opt->default_str(params::field_text(value, p));
        appliers->push_back([holder, opt, offset](char* c) {
          if (opt->count() > 0) *reinterpret_cast<T*>(c + offset) = *holder;
        });
      } else if constexpr (std::is_same_v<T, bool>) {
        // A switch: its flag turns the default around ("--no-icp" sets run_icp false).
        auto given = std::make_shared<bool>(false);
        const bool to = !value;
        cmd->add_flag(
            p.cli, *given,
            fmt::format("sets {} to {} ({}: {})", p.key, to ? "true" : "false", p.key, help));
        appliers->push_back([given, offset, to](char* c) {
          if (*given) *reinterpret_cast<T*>(c + offset) = to;
        });
      } else {
        auto holder = std::make_shared<T>(value);
        CLI::Option* opt = cmd->add_option(p.cli, *holder, help);
        opt->default_str(params::format_value(value));
        if constexpr (std::is_same_v<T, std::string>) {
          if (p.n_names > 0) {
            opt->check(CLI::IsMember(std::vector<std::string>(p.names, p.names + p.n_names)));
          }
        }
        appliers->push_back([holder, opt, offset](char* c) {
          if (opt->count() > 0) *reinterpret_cast<T*>(c + offset) = *holder;
        });
      }
    }
    template <class G>
    void group(const char*, G& g) {
      describe(g, *this);
    }
  };

  C root_;
  bool print_ = false;
  std::string file_;
  std::vector<Applier> appliers_;
};

}  // namespace sonar3d::cli
