// `pathtracer gui`: the workbench window. The frame loop reads top to bottom: poll, run due script
// commands, render this frame's samples, update the display texture (through CUDA/GL interop on
// the GPU, a texture upload on the CPU), build the panels, draw, swap. --frames, --set, --script
// and --screenshot run it without a person (CI uses them under xvfb-run). Every error, warning and
// note of the workbench goes to stderr too, once.
#define GL_GLEXT_PROTOTYPES
#include <GL/gl.h>
#include <GL/glext.h>
#include <imgui.h>
#include <imgui_impl_opengl3.h>

#include <chrono>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "backends/backend_select.h"
#include "commands.h"
#include "settings_cli.h"
#include "gui_platform.h"
#include "image/image.h"
#include "scene/loader.h"
#include "ui/panels.h"

namespace app {
namespace {

struct GuiOptions {
  std::string scene;
  int width = 1600, height = 900;
  int frames = 0;  // 0: run until closed
  int until_spp = 0;     // 0: no sample-count stop
  SettingArgs settings;  // the table's flags and --set, applied to the scene before the window opens
  std::string script, screenshot, export_path, stats_json;
  bool egl = false;
  bool vsync = true;
};

// One scripted step: runs when its frame is reached, or (frame < 0) once the image has converged
// to the target spp/time. Steps run in file order.
struct ScriptStep {
  long frame = 0;
  bool when_converged = false;
  std::string command, argument;
  int line = 0;
};

// The script's commands, declared once: the parser, its message and --help read this list.
struct ScriptCommand {
  const char* name;
  const char* argument;  // "" when it takes none
  const char* help;
};
constexpr ScriptCommand kScriptCommands[] = {
    {"set", "KEY=VALUE", "any --set key, checked as in the window"},
    {"export", "FILE", "the image (.png/.exr) and its .json sidecar"},
    {"screenshot", "FILE", "the window as PNG"},
    {"save", "FILE", "the scene as JSON"},
    {"load", "FILE", "another scene"},
    {"reference", "FILE", "a reference image for the relMSE"},
    {"reset", "", "restart the accumulator"},
    {"select", "OBJECT", "select the object of that name (the Material panel opens its material)"},
    {"expand", "", "open every panel and tree node (to look at the layout)"},
    {"quit", "", "quit after this frame (--screenshot and --export are still written)"},
};

std::string script_command_names() {
  std::string out;
  for (const ScriptCommand& c : kScriptCommands)
    out += (out.empty() ? "" : ", ") + std::string(c.name);
  return out;
}

bool parse_script(const std::string& path, std::vector<ScriptStep>* steps, std::string* error) {
  std::ifstream f(path);
  if (!f) {
    *error = path + ": cannot open the script; nothing was run";
    return false;
  }
  std::string text;
  int line_no = 0;
  while (std::getline(f, text)) {
    ++line_no;
    const size_t start = text.find_first_not_of(" \t");
    if (start == std::string::npos || text[start] == '#') continue;
    const size_t colon = text.find(':');
    if (colon == std::string::npos) {
      *error = path + ":" + std::to_string(line_no) + ": expected \"FRAME: COMMAND\" or "
               "\"converged: COMMAND\"; nothing was run";
      return false;
    }
    ScriptStep s;
    s.line = line_no;
    std::string when = text.substr(start, colon - start);
    while (!when.empty() && when.back() == ' ') when.pop_back();
    if (when == "converged") {
      s.when_converged = true;
    } else {
      char* end = nullptr;
      s.frame = std::strtol(when.c_str(), &end, 10);
      if (when.empty() || *end != '\0' || s.frame < 0) {
        *error = path + ":" + std::to_string(line_no) + ": \"" + when +
                 "\" is neither a frame number nor \"converged\"; nothing was run";
        return false;
      }
    }
    std::string rest = text.substr(colon + 1);
    const size_t c0 = rest.find_first_not_of(" \t");
    rest = c0 == std::string::npos ? "" : rest.substr(c0);
    const size_t sp = rest.find(' ');
    s.command = rest.substr(0, sp);
    s.argument = sp == std::string::npos ? "" : rest.substr(sp + 1);
    bool known = false;
    for (const ScriptCommand& c : kScriptCommands) known |= s.command == c.name;
    if (!known) {
      *error = path + ":" + std::to_string(line_no) + ": unknown command \"" + s.command + "\" (" +
               script_command_names() + "); nothing was run";
      return false;
    }
    steps->push_back(s);
  }
  return true;
}

bool select_by_name(ui::Workbench& wb, const std::string& name, std::string* error) {
  std::vector<std::string> names;
  for (const tracer::ObjectInfo& o : wb.scene().objects) {
    if (o.name == name) {
      wb.select_object(int(names.size()));
      return true;
    }
    names.push_back(o.name);
  }
  const std::string guess = tracer::did_you_mean(name, names);
  *error = "no object named \"" + name + "\"" +
           (guess.empty() ? "" : " (did you mean \"" + guess + "\"?)") + "; nothing was selected";
  return false;
}

void take_screenshot(const std::string& path, const GuiPlatform& platform) {
  int w = 0, h = 0;
  platform.framebuffer_size(&w, &h);
  std::vector<uint8_t> rgba(size_t(w) * h * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadBuffer(GL_BACK);
  glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  for (size_t i = 3; i < rgba.size(); i += 4) rgba[i] = 255;
  tracer::write_png_rgba8(path, w, h, rgba.data(), /*bottom_up=*/true);
}

// The image texture, filled from host memory or from a pixel buffer the GPU wrote into.
struct DisplayTexture {
  GLuint texture = 0, pbo = 0;
  int width = 0, height = 0;
  ~DisplayTexture() {
    if (pbo) glDeleteBuffers(1, &pbo);
    if (texture) glDeleteTextures(1, &texture);
  }
  // (Re)allocates for w x h; returns true when the storage changed.
  bool ensure(int w, int h) {
    if (texture && w == width && h == height) return false;
    if (!texture) glGenTextures(1, &texture);
    glBindTexture(GL_TEXTURE_2D, texture);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, w, h, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
    if (!pbo) glGenBuffers(1, &pbo);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, pbo);
    glBufferData(GL_PIXEL_UNPACK_BUFFER, GLsizeiptr(w) * h * 4, nullptr, GL_STREAM_DRAW);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    width = w;
    height = h;
    return true;
  }
  void upload_host(const std::vector<uint32_t>& rgba) {
    glBindTexture(GL_TEXTURE_2D, texture);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  }
  void upload_from_pbo() {
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, pbo);
    glBindTexture(GL_TEXTURE_2D, texture);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
  }
};

int run_gui(const GuiOptions& o) {
  // Script and --set errors are fatal before any window opens (headless runs must fail loudly).
  std::vector<ScriptStep> steps;
  std::string error;
  if (!o.script.empty() && !parse_script(o.script, &steps, &error)) {
    std::cerr << "error: " << error << "\n";
    return kExitInputError;
  }
  const bool scripted = o.frames > 0 || o.until_spp > 0;
  std::string load_error;
  tracer::Scene scene;
  try {
    scene = o.scene.empty() ? tracer::builtin_default_scene() : tracer::load_scene(o.scene);
    tracer::flatten_small_instances(scene);
  } catch (const tracer::InputError& e) {
    if (scripted) {  // a bad scene is an error, not something to look at
      std::cerr << "error: " << e.what() << "\n";
      return kExitInputError;
    }
    load_error = std::string(e.what()) + " (showing the built-in Cornell box instead)";
    scene = tracer::builtin_default_scene();
  }
  if (!apply_setting_args(o.settings, &scene, &error)) {
    std::cerr << "error: " << error << "\n";
    return kExitUsage;
  }
  if (o.until_spp > 0) scene.settings.spp = o.until_spp;  // the accumulator stops there
  // --strict fails a scripted run on the scene's warnings, as `render` does; an interactive
  // window shows them instead.
  if (scripted && scene.settings.strict && !report_scene_messages(scene, true))
    return kExitInputError;

  std::unique_ptr<GuiPlatform> platform =
      o.egl ? make_egl_platform(o.width, o.height, &error)
            : make_glfw_platform(o.width, o.height, o.vsync && !scripted, &error);
  if (!platform) {
    std::cerr << "error: " << error << "; use `pathtracer render` for a headless image\n";
    return kExitInputError;
  }
  const tracer::BackendChoice backend = scene.settings.backend;
  const int threads = scene.settings.threads;
  ui::Workbench wb(std::move(scene), backend, threads);
  if (!load_error.empty()) wb.messages.error(load_error);
  // The log's new errors, warnings (the scene's too) and notes, each once; results of actions
  // ("exported ...") stay in the window.
  auto report = [&wb] {
    for (const ui::Message& m : wb.messages.take_unreported())
      if (m.severity != ui::Severity::kInfo) std::cerr << ui::to_string(m) << "\n";
  };
  report();
  ui::PanelState ps;
  if (!o.export_path.empty()) snprintf(ps.export_path, sizeof ps.export_path, "%s", o.export_path.c_str());
  std::ofstream stats_out;
  if (!o.stats_json.empty()) stats_out.open(o.stats_json);

  DisplayTexture tex;
  DisplayTexture env_tex;  // the Environment panel's preview of the map
  std::vector<uint32_t> env_rgba;
  std::unique_ptr<tracer::GlDisplayBuffer> interop;
  bool interop_failed = false;
  int exit_code = 0;
  size_t next_step = 0;
  bool quit = false;
  std::vector<uint32_t> rgba;
  const auto t0 = std::chrono::steady_clock::now();
  for (long frame = 0; !quit && !platform->should_close(); ++frame) {
    const auto frame_start = std::chrono::steady_clock::now();
    platform->begin_frame();
    // Scripted steps due now, in order.
    std::string screenshot_now;
    while (next_step < steps.size()) {
      const ScriptStep& s = steps[next_step];
      if (s.when_converged ? !(wb.converged() && wb.stats().spp > 0) : frame < s.frame) break;
      ++next_step;
      const std::string where = o.script + ":" + std::to_string(s.line) + ": ";
      std::string err;
      if (s.command == "set") {
        if (!wb.apply(s.argument, &err)) err = where + err;
      } else if (s.command == "export") {
        err = wb.export_image(s.argument);
        if (!err.empty()) err = where + err;
      } else if (s.command == "save") {
        err = wb.save_scene(s.argument);
        if (!err.empty()) err = where + err;
      } else if (s.command == "load") {
        if (!wb.load_scene(s.argument, &err)) err = where + err;
      } else if (s.command == "reference") {
        if (!wb.load_reference(s.argument, &err)) err = where + err;
      } else if (s.command == "screenshot") {
        screenshot_now = s.argument;
      } else if (s.command == "reset") {
        wb.changed(ui::Edit::kSettings);
      } else if (s.command == "select") {
        if (!select_by_name(wb, s.argument, &err)) err = where + err;
      } else if (s.command == "expand") {
        ps.expand_all = true;
      } else if (s.command == "quit") {
        quit = true;  // after this frame, which is the last one
      }
      if (!err.empty()) {
        wb.messages.error(err);
        exit_code = kExitInputError;
      }
      // An edit takes effect in update(): later steps wait for the frame that shows it.
      if (s.command == "set" || s.command == "load" || s.command == "reset") break;
    }
    wb.update();

    const int w = wb.width(), h = wb.height();
    const bool resizing = w != tex.width || h != tex.height;
    if (resizing) interop.reset();  // unregister before the buffer is reallocated
    const bool resized = tex.ensure(w, h) || resizing;
    bool uploaded = false;
    // The denoised view goes through host memory (the denoiser's output is there).
    const tracer::Renderer* gpu =
        wb.denoise_view() || wb.aov_view() ? nullptr : wb.gpu_renderer();
    if (gpu) {
      try {
        if (resized || !interop) {
          interop.reset();  // unregister before the buffer is reallocated
          if (!interop_failed) interop = std::make_unique<tracer::GlDisplayBuffer>(tex.pbo);
        }
      } catch (const std::exception& e) {
        interop_failed = true;
        wb.messages.note(std::string("CUDA/OpenGL interop unavailable (") + e.what() +
                         "); the image goes through host memory");
      }
      if (interop && gpu->samples_done() > 0) {
        try {
          interop->write_display(*gpu, wb.display().scale(), wb.display().tone_map);
          tex.upload_from_pbo();
          uploaded = true;
          ps.interop = true;
        } catch (const std::exception& e) {
          interop.reset();
          interop_failed = true;
          wb.messages.error(std::string("CUDA/OpenGL interop failed (") + e.what() +
                            "); the image goes through host memory");
        }
      }
    } else {
      interop.reset();
      ps.interop = false;
    }
    int fw = 0, fh = 0;
    if (!uploaded && wb.fetch_display(rgba, fw, fh) && fw == tex.width && fh == tex.height)
      tex.upload_host(rgba);
    ps.texture = reinterpret_cast<ImTextureID>(static_cast<intptr_t>(tex.texture));
    if (wb.environment_preview(env_rgba, ps.env_preview_w, ps.env_preview_h) &&
        ps.env_preview_w > 0) {
      env_tex.ensure(ps.env_preview_w, ps.env_preview_h);
      env_tex.upload_host(env_rgba);
    }
    ps.env_texture = ps.env_preview_w > 0
                         ? reinterpret_cast<ImTextureID>(static_cast<intptr_t>(env_tex.texture))
                         : nullptr;

    ImGui::NewFrame();
    if (ui::draw_workbench(wb, ps)) quit = true;
    ImGui::Render();
    int dw = 0, dh = 0;
    platform->framebuffer_size(&dw, &dh);
    glViewport(0, 0, dw, dh);
    glClearColor(0.1f, 0.1f, 0.1f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    // The last frame: --frames reached, a script's quit, or --until-spp's samples in the image
    // with every script step run (the render may also stop short of them, e.g. at
    // render.time_limit_s: then it says so).
    bool last = quit || (o.frames > 0 && frame + 1 >= o.frames);
    if (o.until_spp > 0 && next_step == steps.size() && wb.stats().spp > 0 &&
        (wb.stats().spp >= uint32_t(o.until_spp) || wb.converged())) {
      if (wb.stats().spp < uint32_t(o.until_spp))
        wb.messages.warning("the render stopped at " + std::to_string(wb.stats().spp) +
                            " spp, before --until-spp " + std::to_string(o.until_spp) +
                            " (render.time_limit_s or a script's render.spp)");
      last = true;
    }
    if (!screenshot_now.empty()) take_screenshot(screenshot_now, *platform);
    if (last && !o.screenshot.empty()) take_screenshot(o.screenshot, *platform);
    platform->end_frame();
    const double frame_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - frame_start)
            .count();
    if (stats_out) {
      const auto& st = wb.stats();
      nlohmann::json j = {
          {"frame", frame},
          {"t", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()},
          {"spp", st.spp},
          {"resets", st.resets},
          {"frame_ms", frame_ms},
          {"render_ms", st.ms_per_frame},
          {"spp_per_s", st.samples_per_s},
          {"backend", wb.backend_name()},
          {"kernel", st.last.kernel},
          {"interop", ps.interop},
          {"exposure", wb.display().exposure},
          {"relmse_halves", st.relmse_halves},
          {"selected_object",
           wb.selected_object < 0
               ? nlohmann::json(nullptr)
               : nlohmann::json(wb.scene().objects[size_t(wb.selected_object)].name)},
          {"material",
           wb.selected_material < 0 || size_t(wb.selected_material) >= wb.scene().materials.size()
               ? nlohmann::json(nullptr)
               : nlohmann::json(wb.scene().materials[size_t(wb.selected_material)].name)},
          {"layout_problems", ps.layout_problems}};
      stats_out << j.dump() << "\n";
    }
    if (last) {
      if (!o.export_path.empty()) {
        const std::string err = wb.export_image(o.export_path);
        if (!err.empty()) {
          wb.messages.error(err);
          exit_code = kExitInputError;
        }
      }
      quit = true;
    }
    report();
  }
  return exit_code;
}

}  // namespace

Runner add_gui_command(CLI::App& cmd) {
  auto o = std::make_shared<GuiOptions>();
  cmd.add_option("scene", o->scene, "Scene file (.json, .pbrt, .obj, .gltf, .glb, .ply); default: built-in Cornell box");
  cmd.add_option("--window", o->width, "Window width")->check(CLI::Range(320, 16384));
  cmd.add_option("--window-height", o->height, "Window height")->check(CLI::Range(240, 16384));
  cmd.add_option("--frames", o->frames, "Quit after this many frames (window frames, not samples)")
      ->check(CLI::Range(1, 100000000));
  cmd.add_option("--until-spp", o->until_spp,
                 "Quit once the image has N samples per pixel (sets render.spp to N; "
                 "--screenshot and --export show that image)")
      ->check(CLI::Range(1, 1 << 30));
  std::string commands;
  for (const ScriptCommand& c : kScriptCommands)
    commands +=
        std::string("\n  ") + c.name + (c.argument[0] ? " " : "") + c.argument + ": " + c.help;
  cmd.add_option("--script", o->script,
                 "Script of timed edits: lines \"FRAME: COMMAND\" or \"converged: COMMAND\"; "
                 "commands:" +
                     commands)
      ->check(CLI::ExistingFile);
  cmd.add_option(
      "--screenshot", o->screenshot,
      "Save the window as PNG at the last frame (--frames, --until-spp or a script's quit)");
  cmd.add_option("--export", o->export_path, "Export the image (.png/.exr + .json) at the last frame");
  cmd.add_option("--stats-json", o->stats_json, "Write one JSON line of statistics per frame");
  cmd.add_flag("--egl", o->egl, "Draw into an off-screen EGL pbuffer instead of a window");
  cmd.add_flag("!--no-vsync", o->vsync, "Do not wait for the display's refresh");
  add_setting_options(cmd, &o->settings, {"render", "gpu", "display", "environment"});
  return [o] { return run_gui(*o); };
}

}  // namespace app
