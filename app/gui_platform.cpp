// GLFW window and EGL pbuffer platforms for the workbench, both driving ImGui's OpenGL3 backend.
#include "gui_platform.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <chrono>
#include <iostream>

namespace app {
namespace {

class GlfwPlatform final : public GuiPlatform {
 public:
  explicit GlfwPlatform(GLFWwindow* w) : window_(w) {}
  ~GlfwPlatform() override {
    if (ImGui::GetIO().BackendRendererUserData) ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
    glfwDestroyWindow(window_);
    glfwTerminate();
  }
  bool should_close() const override { return glfwWindowShouldClose(window_); }
  void begin_frame() override {
    glfwPollEvents();
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
  }
  void end_frame() override { glfwSwapBuffers(window_); }
  void framebuffer_size(int* w, int* h) const override { glfwGetFramebufferSize(window_, w, h); }
  std::string description() const override { return "GLFW window"; }

 private:
  GLFWwindow* window_;
};

void glfw_error(int code, const char* what) {
  std::cerr << "glfw: error " << code << ": " << what << "\n";
}

class EglPlatform final : public GuiPlatform {
 public:
  EglPlatform(EGLDisplay d, EGLSurface s, EGLContext c, int w, int h)
      : display_(d), surface_(s), context_(c), width_(w), height_(h) {
    last_ = std::chrono::steady_clock::now();
  }
  ~EglPlatform() override {
    if (ImGui::GetIO().BackendRendererUserData) ImGui_ImplOpenGL3_Shutdown();
    ImGui::DestroyContext();
    eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display_, context_);
    eglDestroySurface(display_, surface_);
    eglTerminate(display_);
  }
  bool should_close() const override { return false; }
  void begin_frame() override {
    ImGuiIO& io = ImGui::GetIO();
    io.DisplaySize = ImVec2(float(width_), float(height_));
    const auto now = std::chrono::steady_clock::now();
    io.DeltaTime = std::max(1e-4f, std::chrono::duration<float>(now - last_).count());
    last_ = now;
    ImGui_ImplOpenGL3_NewFrame();
  }
  void end_frame() override { eglSwapBuffers(display_, surface_); }
  void framebuffer_size(int* w, int* h) const override {
    *w = width_;
    *h = height_;
  }
  std::string description() const override { return "EGL pbuffer (no window)"; }

 private:
  EGLDisplay display_;
  EGLSurface surface_;
  EGLContext context_;
  int width_, height_;
  std::chrono::steady_clock::time_point last_;
};

void init_imgui() {
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini beside the user's files
  ImGui::StyleColorsDark();
}

}  // namespace

std::unique_ptr<GuiPlatform> make_glfw_platform(int width, int height, bool vsync,
                                                std::string* error) {
  glfwSetErrorCallback(glfw_error);
  if (!glfwInit()) {
    *error = "cannot initialise GLFW (is there a display? DISPLAY is " +
             std::string(getenv("DISPLAY") ? getenv("DISPLAY") : "unset") + ")";
    return nullptr;
  }
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  GLFWwindow* window = glfwCreateWindow(width, height, "pathtracer workbench", nullptr, nullptr);
  if (!window) {
    glfwTerminate();
    *error = "cannot open an OpenGL 3.3 core window";
    return nullptr;
  }
  glfwMakeContextCurrent(window);
  glfwSwapInterval(vsync ? 1 : 0);
  init_imgui();
  ImGui_ImplGlfw_InitForOpenGL(window, true);
  auto platform = std::make_unique<GlfwPlatform>(window);
  if (!ImGui_ImplOpenGL3_Init("#version 330")) {
    *error = "cannot load the OpenGL 3.3 functions (ImGui's loader needs libGL.so.1)";
    return nullptr;  // the platform's destructor closes the window
  }
  return platform;
}

std::unique_ptr<GuiPlatform> make_egl_platform(int width, int height, std::string* error) {
  EGLDisplay display = eglGetDisplay(EGL_DEFAULT_DISPLAY);
  EGLint major = 0, minor = 0;
  if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor)) {
    // Headless NVIDIA machines: take the first EGL device directly.
    auto query = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    auto get = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
        eglGetProcAddress("eglGetPlatformDisplayEXT"));
    EGLDeviceEXT devices[8];
    EGLint count = 0;
    if (!query || !get || !query(8, devices, &count) || count == 0) {
      *error = "no EGL display or device";
      return nullptr;
    }
    display = get(EGL_PLATFORM_DEVICE_EXT, devices[0], nullptr);
    if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor)) {
      *error = "eglInitialize failed on the EGL device";
      return nullptr;
    }
  }
  const EGLint config_attribs[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RED_SIZE, 8,
                                   EGL_GREEN_SIZE,   8,               EGL_BLUE_SIZE, 8,
                                   EGL_ALPHA_SIZE,   8,               EGL_RENDERABLE_TYPE,
                                   EGL_OPENGL_BIT,   EGL_NONE};
  EGLConfig config;
  EGLint n = 0;
  if (!eglChooseConfig(display, config_attribs, &config, 1, &n) || n == 0) {
    *error = "no EGL config with an OpenGL pbuffer";
    eglTerminate(display);
    return nullptr;
  }
  const EGLint pbuffer_attribs[] = {EGL_WIDTH, width, EGL_HEIGHT, height, EGL_NONE};
  EGLSurface surface = eglCreatePbufferSurface(display, config, pbuffer_attribs);
  eglBindAPI(EGL_OPENGL_API);
  const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 3,
                                    EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                    EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attribs);
  if (surface == EGL_NO_SURFACE || context == EGL_NO_CONTEXT ||
      !eglMakeCurrent(display, surface, surface, context)) {
    *error = "cannot create an EGL OpenGL 3.3 context";
    eglTerminate(display);
    return nullptr;
  }
  eglSwapInterval(display, 0);
  init_imgui();
  auto platform = std::make_unique<EglPlatform>(display, surface, context, width, height);
  if (!ImGui_ImplOpenGL3_Init("#version 330")) {
    *error = "cannot load the OpenGL 3.3 functions (ImGui's loader needs libGL.so.1)";
    return nullptr;
  }
  return platform;
}

}  // namespace app
