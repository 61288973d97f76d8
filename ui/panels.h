// The workbench's ImGui panels (Scene, Material, Camera, Render, Stats, Display, Export) and the
// viewport with mouse and keyboard navigation. Each edit goes through Workbench::changed.
#pragma once

#include <imgui.h>

#include <string>

#include "ui/workbench.h"

namespace ui {

struct PanelState {
  char export_path[512] = "out/workbench.png";
  char save_path[512] = "out/workbench_scene.json";
  char scene_path[512] = "";
  char reference_path[512] = "";
  bool show_ui = true;
  ImTextureID texture = nullptr;  // the accumulated image, width() x height()
  std::string status;             // last action's result, shown under the panels
  bool interop = false;           // the GPU writes the texture through CUDA/GL interop
};

// Builds every window for this frame. Returns true when the user asked to quit.
bool draw_workbench(Workbench& wb, PanelState& ps);

}  // namespace ui
