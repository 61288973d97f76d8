// The subcommands of the `pathtracer` executable; each registers its options on a CLI11 app and
// runs when selected, returning the process exit status.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <iostream>
#include <string>

#include "scene/scene.h"

namespace app {

using Runner = std::function<int()>;

Runner add_render_command(CLI::App& app);
Runner add_info_command(CLI::App& app);
Runner add_compare_command(CLI::App& app);
Runner add_bench_command(CLI::App& app);
Runner add_gui_command(CLI::App& app);

// Loads `path`, or the built-in Cornell box when it is empty. On bad input prints the message
// (path:line: problem; what was done) and returns false.
bool load_scene_or_report(const std::string& path, tracer::Scene* scene,
                          std::ostream& err = std::cerr);
// Prints the scene's warnings (and, unless `quiet`, its notes) on stderr, each once. Returns
// false, after saying so, when render.strict makes the warnings errors.
bool report_scene_messages(const tracer::Scene& scene, bool quiet, std::ostream& err = std::cerr);

// Exit codes: 0 success, 1 bad input or failed render, 2 bad command line.
constexpr int kExitInputError = 1;
constexpr int kExitUsage = 2;

}  // namespace app
