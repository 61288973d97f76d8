// The workbench's ImGui panels (a status line with the Messages list, then Scene, Material,
// Camera, Render, Stats, Display, Export) and the viewport with mouse and keyboard navigation.
// Each edit goes through Workbench::changed.
#pragma once

#include <imgui.h>

#include <string>
#include <vector>

#include "ui/workbench.h"

namespace ui {

struct PanelState {
  char export_path[512] = "out/workbench.png";
  char save_path[512] = "out/workbench_scene.json";
  char scene_path[512] = "";
  char reference_path[512] = "";
  bool show_ui = true;
  ImTextureID texture = nullptr;  // the accumulated image, width() x height()
  std::string status;             // last action's result, shown in the status line
  bool interop = false;           // the GPU writes the texture through CUDA/GL interop
  bool show_messages = false;     // the Messages list under the status line is open
  size_t errors_seen = 0;         // a new error opens the list
  bool expand_all = false;        // open every panel and tree node in the next frame
  int listed_selection = -1;      // the object the Scene list last scrolled to
  char env_path[512] = "";        // the Environment panel's file field
  std::string env_path_shown;     // the scene's environment.file when the field was last synced
  ImTextureID env_texture = nullptr;  // Workbench::environment_preview, uploaded by the app
  int env_preview_w = 0, env_preview_h = 0;
  // Widgets of the last frame whose label ran past the column or whose box was too narrow for
  // its value (empty when the panels fit the window; the tests check it at 1280x720).
  std::vector<std::string> layout_problems;
};

// Builds every window for this frame. Returns true when the user asked to quit.
bool draw_workbench(Workbench& wb, PanelState& ps);

}  // namespace ui
