// Where the workbench draws: a GLFW window (OpenGL 3.3 core), or, for GPU machines without a
// display, an EGL pbuffer with no window at all (same GL drawing, input only from scripts).
#pragma once

#include <memory>
#include <string>

namespace app {

class GuiPlatform {
 public:
  virtual ~GuiPlatform() = default;
  virtual bool should_close() const = 0;
  virtual void begin_frame() = 0;  // poll events, start the backends' ImGui frame
  virtual void end_frame() = 0;    // swap buffers
  virtual void framebuffer_size(int* w, int* h) const = 0;
  virtual std::string description() const = 0;
};

// A GLFW window with ImGui's GLFW + OpenGL3 backends. nullptr and `error` when no window can be
// opened (no display, no OpenGL 3.3).
std::unique_ptr<GuiPlatform> make_glfw_platform(int width, int height, bool vsync,
                                                std::string* error);
// An off-screen EGL pbuffer context with ImGui's OpenGL3 backend only.
std::unique_ptr<GuiPlatform> make_egl_platform(int width, int height, std::string* error);

}  // namespace app
