// The settings table on the command line: one flag per setting that has one (help, choices and
// default from the table) and --set KEY=VALUE for every setting, applied after the scene file in
// the order given: flags first, then each --set.
#pragma once

#include <CLI/CLI.hpp>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "scene/scene.h"

namespace app {

struct SettingArgs {
  std::map<std::string, std::string> flags;  // setting key -> the flag's text, as given
  std::vector<std::string> sets;             // --set KEY=VALUE, in order
};

// Adds the flags of the settings whose section is in `sections` ("render", "gpu", "display"),
// except those in `skip` (keys), and --set. `args` must outlive the parse.
void add_setting_options(CLI::App& cmd, SettingArgs* args, const std::vector<std::string>& sections,
                         const std::vector<std::string>& skip = {});

// Applies the flags, then each --set, to the scene. On a problem returns false with
// "--max-depth 0: ..." or "--set \"KEY=VALUE\": ..." in *error.
bool apply_setting_args(const SettingArgs& args, tracer::Scene* scene, std::string* error);

// For the few numeric options outside the table: refuses NaN and infinities (CLI11's Range lets
// NaN through, as every comparison with it is false).
CLI::Validator finite_number();

// The table's help for a flag: its text, the accepted values and the default.
std::string setting_flag_help(const tracer::Setting& s);

}  // namespace app
