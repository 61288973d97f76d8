// Entry point of `pathtracer`: dispatches to the subcommands. With no arguments it opens the
// workbench window on the built-in Cornell box, or renders it headless when there is no display.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>
#include <iostream>

#include "commands.h"
#include "render_job.h"
#include "scene/loader.h"

namespace app {
bool load_scene_or_report(const std::string& path, tracer::Scene* scene, std::ostream& err) {
  try {
    *scene = path.empty() ? tracer::builtin_default_scene() : tracer::load_scene(path);
    tracer::flatten_small_instances(*scene);
  } catch (const tracer::InputError& e) {
    err << "error: " << e.what() << "\n";
    return false;
  }
  return true;
}

bool report_scene_messages(const tracer::Scene& scene, bool quiet, std::ostream& err) {
  const std::vector<std::string>& warnings = scene.diagnostics.warnings;
  for (const std::string& w : warnings)
    err << (scene.settings.strict ? "error: " : "warning: ") << w << "\n";
  if (!quiet)
    for (const std::string& n : scene.diagnostics.notes) err << "note: " << n << "\n";
  if (!scene.settings.strict || warnings.empty()) return true;
  err << "error: --strict (render.strict): " << warnings.size()
            << (warnings.size() == 1 ? " warning" : " warnings")
            << " about the input; nothing was rendered\n";
  return false;
}
}  // namespace app

int main(int argc, char** argv) {
  CLI::App app{"pathtracer: a CPU/CUDA path tracing workbench"};
  app.set_version_flag("--version", std::string("pathtracer ") + TRACER_VERSION);
  app.require_subcommand(0, 1);
  auto* render = app.add_subcommand("render", "Render a scene headless to PNG or EXR");
  auto* info = app.add_subcommand("info", "Print statistics and needed features of a scene");
  auto* compare = app.add_subcommand("compare", "Compare two images (RMSE, relMSE, means)");
  auto* bench = app.add_subcommand("bench", "Time the backends and GPU designs on a scene");
  auto* gui = app.add_subcommand("gui", "Open the workbench window (the default with no arguments)");
  const app::Runner run_render = app::add_render_command(*render);
  const app::Runner run_info = app::add_info_command(*info);
  const app::Runner run_compare = app::add_compare_command(*compare);
  const app::Runner run_bench = app::add_bench_command(*bench);
  const app::Runner run_gui = app::add_gui_command(*gui);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return app::kExitUsage;
  }
  // Last resort: a failure no command caught (a CUDA error mid-run, a failed thread start) is
  // reported as a message and exit 1, never as std::terminate.
  // Under mpirun only `render` distributes; N copies of another command would race each other.
  if (!*render && app::mpi_environment()) {
    const char* n = std::getenv("OMPI_COMM_WORLD_SIZE");
    if (!n) n = std::getenv("PMI_SIZE");
    if (n && std::atoi(n) > 1) {
      std::cerr << "error: started by mpirun with " << n << " ranks: only `pathtracer render` "
                   "distributes its work; run other commands without mpirun\n";
      return app::kExitUsage;
    }
  }
  try {
    if (*render) return run_render();
    if (*info) return run_info();
    if (*compare) return run_compare();
    if (*bench) return run_bench();
    if (*gui) return run_gui();
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return app::kExitInputError;
  }
  // No subcommand: the workbench window on the built-in scene when there is a display, else a
  // headless render of it.
  const bool display = std::getenv("DISPLAY") || std::getenv("WAYLAND_DISPLAY");
  std::vector<std::string> args = {"pathtracer"};
  if (display) {
    args.push_back("gui");
  } else {
    std::cerr << "pathtracer: no display; rendering the built-in Cornell box to out/default.png "
                 "(see `pathtracer --help`)\n";
    args.insert(args.end(), {"render", "--out", "out/default.png"});
  }
  CLI::App again{"pathtracer"};
  auto* r2 = again.add_subcommand("render");
  auto* g2 = again.add_subcommand("gui");
  const app::Runner run_r2 = app::add_render_command(*r2);
  const app::Runner run_g2 = app::add_gui_command(*g2);
  std::vector<char*> argv2;
  for (auto& a : args) argv2.push_back(a.data());
  try {
    again.parse(int(argv2.size()), argv2.data());
  } catch (const CLI::ParseError& e) {
    return again.exit(e);
  }
  return display ? run_g2() : run_r2();
}
