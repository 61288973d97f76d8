// Command-line flags and --set derived from the settings table (scene/settings.h).
#include "settings_cli.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>

namespace app {

CLI::Validator finite_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        char* end = nullptr;
        const double d = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0') return "\"" + text + "\" is not a number";
        if (!std::isfinite(d)) return "\"" + text + "\" is not a finite number";
        return "";
      },
      "FINITE");
}

std::string setting_flag_help(const tracer::Setting& s) {
  return s.help + " [" + tracer::setting_values_text(s) + (s.unit.empty() ? "" : " " + s.unit) +
         "; default " + tracer::setting_default_text(s) + "; --set " + s.key + "]";
}

void add_setting_options(CLI::App& cmd, SettingArgs* args, const std::vector<std::string>& sections,
                         const std::vector<std::string>& skip) {
  for (const tracer::Setting& s : tracer::settings_table()) {
    if (s.flag.empty()) continue;
    if (std::find(sections.begin(), sections.end(), s.section()) == sections.end()) continue;
    if (std::find(skip.begin(), skip.end(), s.key) != skip.end()) continue;
    const std::string key = s.key;
    const std::string group = s.section() == "gpu"           ? "GPU (CUDA backend)"
                              : s.section() == "display"     ? "Display and PNG export"
                              : s.section() == "environment" ? "Environment light"
                                                             : "Render settings";
    if (s.bare_flag) {
      cmd.add_flag_function(
             s.flag, [args, key](std::int64_t) { args->flags[key] = "on"; },
             s.help + " [--set " + s.key + "=off undoes a scene file's setting]")
          ->group(group);
      continue;
    }
    cmd.add_option_function<std::string>(
           s.flag, [args, key](const std::string& v) { args->flags[key] = v; },
           setting_flag_help(s))
        ->type_name(s.type == tracer::SettingType::kInt || s.type == tracer::SettingType::kFloat
                        ? "NUMBER"
                    : s.type == tracer::SettingType::kString ? "FILE"
                                                             : "VALUE")
        ->group(group);
  }
  cmd.add_option("--set", args->sets,
                 "Set any setting, KEY=VALUE (repeatable; after the flags), e.g. "
                 "render.max_depth=4 or camera.vfov=30; docs/CLI.md lists the keys")
      ->type_name("KEY=VALUE")
      ->expected(1)  // one assignment per --set, so a scene path after it stays positional
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

bool apply_setting_args(const SettingArgs& args, tracer::Scene* scene, std::string* error) {
  for (const tracer::Setting& s : tracer::settings_table()) {
    const auto it = args.flags.find(s.key);
    if (it == args.flags.end()) continue;
    nlohmann::json value;
    std::string problem = tracer::parse_setting_text(s, it->second, &value);
    if (problem.empty()) problem = tracer::set_setting(*scene, s, value);
    if (!problem.empty()) {
      *error = s.flag + " " + it->second + ": " + problem;
      return false;
    }
  }
  for (const std::string& a : args.sets) {
    const std::string problem = tracer::set_setting_assignment(*scene, a);
    if (!problem.empty()) {
      *error = "--set \"" + a + "\": " + problem;
      return false;
    }
  }
  const std::string camera = tracer::check_camera(*scene);
  if (!camera.empty()) {
    *error = camera;
    return false;
  }
  return true;
}

}  // namespace app
