// The subcommands of the `pathtracer` executable; each registers its options on a CLI11 app and
// runs when selected, returning the process exit status.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

namespace app {

using Runner = std::function<int()>;

Runner add_render_command(CLI::App& app);
Runner add_info_command(CLI::App& app);
Runner add_compare_command(CLI::App& app);
Runner add_bench_command(CLI::App& app);
Runner add_gui_command(CLI::App& app);

// Exit codes: 0 success, 1 bad input or failed render, 2 bad command line.
constexpr int kExitInputError = 1;
constexpr int kExitUsage = 2;

}  // namespace app
