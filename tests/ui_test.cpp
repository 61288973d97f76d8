// The workbench model without a window: edits by name, what resets the accumulator and what does
// not, re-convergence after an edit, export, scene saving that reloads every edit, navigation and
// picking, the message log, the selection that opens a material; and the panels drawn by ImGui
// without a window (no GL): they fit at 1280x720 and 1600x900, a new error opens the Messages.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "cpu/cpu_backend.h"
#include "image/image.h"
#include "scene/loader.h"
#include "test_util.h"
#include "ui/panels.h"
#include "ui/workbench.h"

namespace {

std::string tmpdir() {
  static std::string dir = [] {
    char tmpl[] = "/tmp/pathtracer_ui_XXXXXX";
    return std::string(mkdtemp(tmpl));
  }();
  return dir;
}

// Runs UI frames until the accumulator reaches the target (bounded in time).
void converge(ui::Workbench& wb) {
  const auto start = std::chrono::steady_clock::now();
  while (!wb.converged() && std::chrono::steady_clock::now() - start < std::chrono::seconds(60)) {
    wb.update();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(wb.converged()) << "did not converge within a minute";
}

std::unique_ptr<ui::Workbench> small_cornell(uint32_t spp) {
  auto wb = std::make_unique<ui::Workbench>(tracer::builtin_default_scene(),
                                            tracer::BackendChoice::kCpu);
  std::string err;
  EXPECT_TRUE(wb->apply("render.width=48", &err)) << err;
  EXPECT_TRUE(wb->apply("render.height=48", &err)) << err;
  EXPECT_TRUE(wb->apply("render.spp=" + std::to_string(spp), &err)) << err;
  return wb;
}

TEST(Workbench, ApplyRejectsBadEditsWithReasons) {
  auto wb = small_cornell(4);
  std::string err;
  EXPECT_FALSE(wb->apply("camera.vfov=500", &err));
  EXPECT_NE(err.find("179"), std::string::npos) << err;
  EXPECT_FALSE(wb->apply("materials.whte.albedo=1,1,1", &err));
  EXPECT_NE(err.find("did you mean \"white\""), std::string::npos) << err;
  EXPECT_FALSE(wb->apply("materials.white.albedo=2,0,0", &err));
  EXPECT_FALSE(wb->apply("camera.fov=40", &err));
  EXPECT_NE(err.find("did you mean"), std::string::npos) << err;
  EXPECT_FALSE(wb->apply("no equals sign", &err));
  EXPECT_FALSE(wb->apply("render.nee=maybe", &err));
  EXPECT_FALSE(wb->apply("render.sampler=halton", &err));
  EXPECT_TRUE(wb->apply("render.sampler=random", &err)) << err;
  EXPECT_EQ(wb->settings().sampler, tracer::kSamplerRandom);
  EXPECT_TRUE(wb->apply("render.sampler=sobol", &err)) << err;
  EXPECT_EQ(wb->settings().sampler, tracer::kSamplerSobol);
  EXPECT_FALSE(wb->apply("camera.position=1,2", &err));
  EXPECT_FALSE(wb->apply("materials.white.ior=nan", &err));
  // GPU switches (the CPU backend ignores them, but they are kept for a switch to the GPU).
  EXPECT_TRUE(wb->gpu_options().flat_list);
  EXPECT_TRUE(wb->apply("gpu.flat=off", &err)) << err;
  EXPECT_FALSE(wb->gpu_options().flat_list);
  EXPECT_TRUE(wb->gpu_options().first_bounce_cache) << "gpu.flat sets only its own switch";
  // The design paths are build variants now (gpu_options.h), not keys.
  EXPECT_FALSE(wb->apply("gpu.fuse=off", &err));
  EXPECT_FALSE(wb->apply("gpu.flat=sometimes", &err));
  EXPECT_NE(err.find("on or off"), std::string::npos) << err;
  // Compaction: auto, shade (in the shade kernel), cub (a CUB select) or off.
  using C = tracer::Compaction;
  EXPECT_EQ(wb->gpu_options().compaction, C::kAuto);
  EXPECT_TRUE(wb->apply("gpu.compaction=cub", &err)) << err;
  EXPECT_EQ(wb->gpu_options().compaction, C::kCub);
  EXPECT_TRUE(wb->apply("gpu.compaction=shade", &err)) << err;
  EXPECT_EQ(wb->gpu_options().compaction, C::kShade);
  EXPECT_TRUE(wb->apply("gpu.compaction=off", &err)) << err;
  EXPECT_EQ(wb->gpu_options().compaction, C::kOff);
  EXPECT_TRUE(wb->apply("gpu.compaction=auto", &err)) << err;
  EXPECT_EQ(wb->gpu_options().compaction, C::kAuto);
  EXPECT_FALSE(wb->apply("gpu.compaction=thrust", &err));
  EXPECT_NE(err.find("auto, shade, cub or off"), std::string::npos) << err;
  EXPECT_TRUE(wb->apply("gpu.tail=0.5", &err)) << err;
  EXPECT_EQ(wb->gpu_options().tail_fraction, 0.5f);
  EXPECT_FALSE(wb->apply("gpu.tail=2", &err));
  EXPECT_FALSE(wb->apply("gpu.tail=nan", &err));
}

TEST(Workbench, EditsResetAndDisplayChangesDoNot) {
  auto wb = small_cornell(8);
  converge(*wb);
  const uint64_t resets = wb->stats().resets;
  const uint32_t spp = wb->stats().spp;
  std::string err;
  ASSERT_TRUE(wb->apply("display.exposure=1.5", &err)) << err;
  ASSERT_TRUE(wb->apply("display.tonemap=aces", &err)) << err;
  wb->update();
  EXPECT_EQ(wb->stats().resets, resets) << "a display edit must not reset";
  EXPECT_GE(wb->stats().spp, spp);
  for (const char* edit : {"materials.white.albedo=0.5,0.5,0.5", "camera.vfov=45",
                           "render.max_depth=4", "render.nee=off"}) {
    const uint64_t before = wb->stats().resets;
    ASSERT_TRUE(wb->apply(edit, &err)) << err;
    EXPECT_FALSE(wb->converged()) << edit << ": the accumulator must restart";
    wb->update();  // the same frame that applies the edit resets
    EXPECT_EQ(wb->stats().resets, before + 1) << edit;
    EXPECT_LT(wb->stats().spp, 8u) << edit;
  }
}

// The Display panel's AOV view and denoiser never restart the render; the view shows the AOV,
// the denoised view is what the Stats line and the overlay say.
TEST(Workbench, AovViewAndDenoiserShowWithoutRestarting) {
  auto wb = small_cornell(16);
  std::string err;
  ASSERT_TRUE(wb->apply("render.spp=0", &err)) << err;  // keeps rendering
  for (int i = 0; i < 20; ++i) {
    wb->update();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const uint64_t resets = wb->stats().resets;
  ASSERT_TRUE(wb->apply("display.view=albedo", &err)) << err;
  std::vector<uint32_t> rgba;
  int w = 0, h = 0;
  bool shown = false;
  const auto start = std::chrono::steady_clock::now();
  while (!shown && std::chrono::steady_clock::now() - start < std::chrono::seconds(30)) {
    wb->update();
    // The back wall (white, albedo 0.73 in the built-in box) at the image's centre.
    if (wb->fetch_display(rgba, w, h) && w == 48 && (rgba[24 * 48 + 24] & 0xffffffu) != 0)
      shown = true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(shown) << "the albedo view stayed black";
  const uint32_t c = rgba[24 * 48 + 24];
  const float expected = tracer::linear_to_srgb(0.73f) * 255.0f;  // the box's white albedo
  EXPECT_NEAR(float(c & 0xffu), expected, 3.0f);
  EXPECT_NE(wb->shown_image().find("albedo AOV"), std::string::npos) << wb->shown_image();
  EXPECT_EQ(wb->stats().resets, resets) << "showing an AOV must not restart";
  ASSERT_TRUE(wb->apply("display.view=image", &err)) << err;
  if (!tracer::denoiser_available()) {
    ASSERT_TRUE(wb->apply("display.denoise=on", &err)) << err;
    EXPECT_NE(wb->shown_image().find("absent"), std::string::npos) << wb->shown_image();
    GTEST_SKIP() << "denoiser absent: " << tracer::denoiser_status();
  }
  ASSERT_TRUE(wb->apply("display.denoise=on", &err)) << err;
  const auto t0 = std::chrono::steady_clock::now();
  while (wb->shown_denoised_spp() == 0 &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(30)) {
    wb->update();
    wb->fetch_display(rgba, w, h);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_GT(wb->shown_denoised_spp(), 0u);
  EXPECT_NE(wb->shown_image().find("denoised at"), std::string::npos) << wb->shown_image();
  EXPECT_EQ(wb->stats().resets, resets) << "the denoiser must not restart";
}

TEST(Workbench, ReconvergesToTheEditedSceneAndSavesIt) {
  auto wb = small_cornell(64);
  converge(*wb);
  const std::string before = tmpdir() + "/before.exr", after = tmpdir() + "/after.exr";
  ASSERT_EQ(wb->export_image(before), "");
  std::string err;
  ASSERT_TRUE(wb->apply("materials.red.albedo=0.05,0.05,0.65", &err)) << err;
  converge(*wb);
  ASSERT_EQ(wb->export_image(after), "");
  const std::string saved = tmpdir() + "/edited.json";
  ASSERT_EQ(wb->save_scene(saved), "");
  // The saved scene reloads the edit...
  tracer::Scene s = tracer::load_scene(saved);
  const uint32_t red = s.find_material("red");
  ASSERT_NE(red, tracer::kInvalid);
  EXPECT_NEAR(s.materials[red].material.albedo.z, 0.65f, 1e-6f);
  EXPECT_EQ(s.settings.width, 48);
  // ...and a fresh render of it agrees with the workbench's image, not the image before.
  std::string log;
  const std::string ref = tmpdir() + "/ref.exr";
  ASSERT_EQ(test::run_command(test::pathtracer_exe() + " render -q " + saved +
                                  " --spp 512 --backend cpu --out " + ref, &log), 0) << log;
  const tracer::ImageRGB r = tracer::read_image(ref);
  const double e_after = tracer::compare_images(tracer::read_image(after), r).relmse;
  const double e_before = tracer::compare_images(tracer::read_image(before), r).relmse;
  EXPECT_LT(e_after, 0.05);
  EXPECT_GT(e_before, 10 * e_after);
}

TEST(Workbench, NavigationAndPicking) {
  auto wb = small_cornell(1);
  wb->update();
  const tracer::CameraDesc c0 = wb->scene().camera;
  wb->orbit(20.0f, 10.0f);
  const tracer::CameraDesc& c1 = wb->scene().camera;
  EXPECT_NEAR(glm::length(c1.position - c1.look_at), glm::length(c0.position - c0.look_at), 1e-2f);
  EXPECT_GT(glm::length(c1.position - c0.position), 1.0f);
  wb->reset_view();
  EXPECT_EQ(wb->scene().camera.position, c0.position);
  wb->update();
  // The middle of the left edge is the red wall; the centre top is the ceiling or the light.
  const int left = wb->pick_object(0.05f, 0.5f);
  ASSERT_GE(left, 0);
  EXPECT_EQ(wb->scene().objects[size_t(left)].name, "red wall");
  EXPECT_EQ(wb->pick_object(1.5f, 0.5f), -1);
  ASSERT_TRUE(wb->focus_at(0.5f, 0.5f));
  // The back wall is at z = 555 and the camera at z = -800 looking down +z.
  const float f = wb->scene().camera.focus_distance;
  EXPECT_GT(f, 800.0f);
  EXPECT_LT(f, 1400.0f);
}

TEST(Workbench, BadSceneKeepsTheCurrentOne) {
  auto wb = small_cornell(1);
  std::string err;
  EXPECT_FALSE(wb->load_scene(test::data_dir() + "/bad/unknown_key.json", &err));
  EXPECT_NE(err.find("unknown_key.json"), std::string::npos) << err;
  EXPECT_EQ(wb->scene().source, "<built-in>");
  EXPECT_NE(wb->export_image("/proc/forbidden/x.png"), "");
}

// The Scene panel's Load takes every format load_scene reads: a pbrt-v4 file (with a PLY mesh
// beside it) replaces the scene and renders; a broken one names file:line and keeps the old one.
TEST(Workbench, LoadsPbrtScenesAndKeepsTheOldOneOnAnError) {
  auto wb = small_cornell(1);
  const std::string dir = tmpdir() + "/pbrt_load";
  std::filesystem::create_directories(dir);
  {
    std::ofstream ply(dir + "/quad.ply");
    ply << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
           "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
           "end_header\n-5 -5 0\n5 -5 0\n5 5 0\n-5 5 0\n4 0 1 2 3\n";
    std::ofstream f(dir + "/scene.pbrt");
    f << "LookAt 0 0 10  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n"
         "Film \"rgb\" \"integer xresolution\" 32 \"integer yresolution\" 24\n"
         "WorldBegin\n"
         "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [2 2 2]\n"
         "  Translate 0 0 4\n  Shape \"sphere\" \"float radius\" 0.5\nAttributeEnd\n"
         "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
         "Shape \"plymesh\" \"string filename\" \"quad.ply\"\n";
    std::ofstream bad(dir + "/bad.pbrt");
    bad << "WorldBegin\nShape \"trianglemesh\" \"integer indices\" [0 1 7]\n"
           "  \"point3 P\" [0 0 0 1 0 0 0 1 0]\n";
  }
  std::string err;
  ASSERT_TRUE(wb->load_scene(dir + "/scene.pbrt", &err)) << err;
  EXPECT_EQ(wb->width(), 32);
  EXPECT_EQ(wb->scene().settings.height, 24);
  EXPECT_EQ(wb->scene().source, dir + "/scene.pbrt");
  EXPECT_TRUE(wb->apply("render.spp=2", &err)) << err;
  converge(*wb);
  ASSERT_EQ(wb->export_image(dir + "/out.exr"), "");
  const tracer::ImageRGB img = tracer::read_image(dir + "/out.exr");
  double sum = 0;
  for (float v : img.pixels) sum += v;
  EXPECT_GT(sum, 0.0) << "the lit quad renders";

  EXPECT_FALSE(wb->load_scene(dir + "/bad.pbrt", &err));
  EXPECT_NE(err.find("bad.pbrt:2"), std::string::npos) << err;
  EXPECT_EQ(wb->scene().source, dir + "/scene.pbrt") << "the loaded scene stays";
}

TEST(Workbench, LoadsInTheBackgroundWhileTheOldSceneRenders) {
  auto wb = small_cornell(0);  // renders on until stopped
  const std::string dir = tmpdir() + "/bg_load";
  std::filesystem::create_directories(dir);
  {
    // 720,000 triangles: long enough to load that the old scene renders meanwhile.
    std::ofstream f(dir + "/land.json");
    f << R"({"camera": {"position": [-5, 20, -5], "look_at": [50, 0, 50]},
      "render": {"width": 40, "height": 30},
      "environment": {"color": [0.5, 0.6, 0.8]},
      "materials": {"rock": {"albedo": [0.5, 0.5, 0.5]}},
      "objects": [{"type": "terrain", "size": [100, 0, 100], "resolution": 600,
                   "height": 10, "material": "rock"}]})";
    std::ofstream bad(dir + "/bad.json");
    bad << "{\"objects\": [{\"type\": \"spere\"}]}";
  }
  const std::string old_source = wb->scene().source;
  wb->update();
  std::string err;
  ASSERT_TRUE(wb->start_loading(dir + "/land.json", &err)) << err;
  EXPECT_FALSE(wb->start_loading(dir + "/land.json", &err));
  EXPECT_NE(err.find("still loading"), std::string::npos) << err;
  EXPECT_NE(wb->loading_status().find("land.json: "), std::string::npos) << wb->loading_status();
  uint32_t frames_while_loading = 0, spp_while_loading = 0;
  const auto start = std::chrono::steady_clock::now();
  while (wb->loading() && std::chrono::steady_clock::now() - start < std::chrono::seconds(120)) {
    wb->update();
    if (wb->loading()) {
      ++frames_while_loading;
      spp_while_loading = std::max(spp_while_loading, wb->stats().spp);
      EXPECT_EQ(wb->scene().source, old_source) << "the old scene stays until the new is ready";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_FALSE(wb->loading()) << "the load did not finish within two minutes";
  EXPECT_EQ(wb->scene().source, dir + "/land.json");
  EXPECT_EQ(wb->scene().mesh.indices.size(), 720000u);
  EXPECT_EQ(wb->width(), 40);
  EXPECT_NE(wb->loading_status().find("loaded land.json: 720000 triangles"), std::string::npos)
      << wb->loading_status();
  EXPECT_GT(frames_while_loading, 0u) << "the UI kept running frames while it loaded";
  EXPECT_GT(spp_while_loading, 0u) << "the old scene rendered while the new one loaded";
  // The new scene renders (its compiled form came with the load).
  EXPECT_TRUE(wb->apply("render.spp=2", &err)) << err;
  converge(*wb);
  EXPECT_EQ(wb->stats().spp, 2u);

  // A broken file: the error is posted and the scene shown stays.
  const size_t errors = wb->messages.count(ui::Severity::kError);
  ASSERT_TRUE(wb->start_loading(dir + "/bad.json", &err)) << err;
  while (wb->loading()) {
    wb->update();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_EQ(wb->scene().source, dir + "/land.json");
  EXPECT_EQ(wb->messages.count(ui::Severity::kError), errors + 1);
  EXPECT_NE(wb->messages.all().back().text.find("bad.json:1"), std::string::npos)
      << wb->messages.all().back().text;
  EXPECT_EQ(wb->loading_status().rfind("error: ", 0), 0u) << wb->loading_status();
}

TEST(Workbench, ErrorCurveAgainstAReferenceFallsAsOneOverTime) {
  // A 48x48 reference of the built-in box (independent seed, 1024 spp) with its variance.
  tracer::Scene scene = tracer::builtin_default_scene();
  scene.settings.width = scene.settings.height = 48;
  scene.settings.seed = 99;
  const tracer::CompiledScene cs(scene, 48, 48);
  tracer::CpuRenderer cpu;
  cpu.set_scene(cs, tracer::make_integrator_settings(scene.settings));
  cpu.render(1024);
  tracer::ImageRGB even, odd;
  cpu.half_images(&even, &odd);
  const std::string ref = tmpdir() + "/curve_ref.exr";
  tracer::write_image(ref, cpu.image());
  tracer::write_image(tmpdir() + "/curve_ref.variance.exr", tracer::variance_from_halves(even, odd));

  auto wb = small_cornell(128);
  wb->update();
  std::string err;
  ASSERT_TRUE(wb->load_reference(ref, &err)) << err;
  converge(*wb);
  for (int i = 0; i < 3; ++i) wb->update();  // the estimate after the last pass
  const auto& curve = wb->stats().error_curve;
  ASSERT_GE(curve.size(), 4u);
  EXPECT_LT(curve.back().error.relmse, curve.front().error.relmse / 8)
      << curve.front().spp << " spp -> " << curve.back().spp << " spp";
  const tracer::ConvergenceSummary sum = tracer::summarize(curve);
  EXPECT_NEAR(sum.slope, -1.0, 0.25) << sum.verdict;
  // An edit resets the curve; a reference of another size is refused with the reason.
  ASSERT_TRUE(wb->apply("camera.vfov=45", &err)) << err;
  wb->update();
  EXPECT_LE(wb->stats().error_curve.size(), 1u);
  ASSERT_TRUE(wb->apply("render.width=40", &err)) << err;
  EXPECT_FALSE(wb->load_reference(ref, &err));
  EXPECT_NE(err.find("48x48"), std::string::npos) << err;
}

TEST(UiMessages, SceneWarningsAreLoggedAndHandedOutOnce) {
  // One warning (the missing library) and two notes (the framing camera, the default light).
  const std::string file = test::data_dir() + "/bad/missing_mtl.obj";
  ui::Workbench wb(tracer::load_scene(file), tracer::BackendChoice::kCpu);
  EXPECT_EQ(wb.messages.count(ui::Severity::kWarning), 1u);
  EXPECT_EQ(wb.messages.count(ui::Severity::kNote), 2u);
  EXPECT_EQ(wb.messages.summary(), "1 warning, 2 notes");
  auto fresh = wb.messages.take_unreported();
  size_t warnings = 0;
  for (const auto& m : fresh) warnings += m.severity == ui::Severity::kWarning ? 1 : 0;
  EXPECT_EQ(warnings, 1u);
  EXPECT_NE(ui::to_string(fresh.front()).find("warning: "), std::string::npos);
  wb.update();
  wb.update();
  EXPECT_TRUE(wb.messages.take_unreported().empty()) << "each message is handed out once";
  // A later warning of the scene (validation after an edit, say) is logged at the next frame.
  wb.scene().diagnostics.warnings.push_back("later.json:3: something; continued");
  wb.update();
  fresh = wb.messages.take_unreported();
  ASSERT_EQ(fresh.size(), 1u);
  EXPECT_EQ(fresh[0].text, "later.json:3: something; continued");
  // Loading a scene logs its warnings (again, for this load); an error counts in the summary.
  std::string err;
  ASSERT_TRUE(wb.load_scene(file, &err)) << err;
  wb.update();
  EXPECT_EQ(wb.messages.take_unreported().size(), 3u);
  wb.messages.error("out/x.png: cannot be written");
  EXPECT_EQ(wb.messages.summary(), "1 error, 3 warnings, 4 notes");
  wb.messages.info("exported out/y.png");
  EXPECT_EQ(wb.messages.summary(), "1 error, 3 warnings, 4 notes") << "results of actions are not counted";
}

TEST(UiSelection, TheMaterialPanelOpensOnTheSelectedObjectsMaterial) {
  ui::Workbench wb(tracer::builtin_default_scene(), tracer::BackendChoice::kCpu);
  const auto& scene = wb.scene();
  auto name_of = [&](int material) { return scene.materials[size_t(material)].name; };
  // On start, the first object and its material.
  ASSERT_EQ(wb.selected_object, 0);
  EXPECT_EQ(scene.objects[0].name, "floor");
  EXPECT_EQ(name_of(wb.selected_material), "white");
  int red_wall = -1, light = -1;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    if (scene.objects[i].name == "red wall") red_wall = int(i);
    if (scene.objects[i].name == "light") light = int(i);
  }
  ASSERT_GE(red_wall, 0);
  ASSERT_GE(light, 0);
  wb.select_object(red_wall);
  EXPECT_EQ(name_of(wb.selected_material), "red");
  wb.select_object(light);
  EXPECT_EQ(name_of(wb.selected_material), "light");
  // Picking in the viewport selects through the same call.
  wb.update();
  wb.select_object(wb.pick_object(0.05f, 0.5f));
  EXPECT_EQ(name_of(wb.selected_material), "red");
  // Nothing selected: the material stays where it was (the user may pick any in the combo).
  wb.select_object(-1);
  EXPECT_EQ(wb.selected_object, -1);
  EXPECT_EQ(name_of(wb.selected_material), "red");
  // A new scene selects its first object.
  std::string err;
  ASSERT_TRUE(wb.load_scene(test::source_dir() + "/assets/scenes/subsurface.json", &err)) << err;
  EXPECT_EQ(wb.selected_object, 0);
  EXPECT_EQ(wb.selected_material, wb.material_of(0));
}

// Dear ImGui without a window or GL: the panels are built and laid out, not drawn.
class HeadlessImGui {
 public:
  HeadlessImGui(float width, float height) {
    context_ = ImGui::CreateContext();
    ImGuiIO& io = ImGui::GetIO();
    io.IniFilename = nullptr;
    io.DisplaySize = ImVec2(width, height);
    io.DeltaTime = 1.0f / 60.0f;
    unsigned char* pixels = nullptr;
    int w = 0, h = 0;
    io.Fonts->GetTexDataAsRGBA32(&pixels, &w, &h);  // the default font, as in the window
    ImGui::StyleColorsDark();
  }
  ~HeadlessImGui() { ImGui::DestroyContext(context_); }
  // A few frames: the column's width is checked against the previous frame's content.
  void frames(ui::Workbench& wb, ui::PanelState& ps, int n = 3) {
    for (int i = 0; i < n; ++i) {
      ImGui::NewFrame();
      ui::draw_workbench(wb, ps);
      ImGui::Render();
    }
  }

 private:
  ImGuiContext* context_;
};

std::string joined(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += s + "\n";
  return out;
}

TEST(UiPanels, FitAt1280x720And1600x900WithEveryPanelOpen) {
  for (const ImVec2 size : {ImVec2(1280, 720), ImVec2(1600, 900)}) {
    SCOPED_TRACE(std::to_string(int(size.x)) + "x" + std::to_string(int(size.y)));
    ui::Workbench wb(tracer::builtin_default_scene(), tracer::BackendChoice::kCpu);
    std::string err;
    ASSERT_TRUE(wb.apply("render.spp=1", &err)) << err;
    wb.update();
    wb.messages.error(std::string(300, 'x') + ": a long error that has to wrap; nothing was done");
    HeadlessImGui imgui(size.x, size.y);
    ui::PanelState ps;
    ps.status = "error: " + std::string(200, 'y');
    ps.expand_all = true;
    // Every material type shows other widgets; the selected object's material is the floor's.
    for (const char* type : {"diffuse", "mirror", "dielectric", "conductor", "subsurface",
                             "coated_diffuse", "diffuse_transmission"}) {
      ASSERT_TRUE(wb.apply(std::string("materials.white.type=") + type, &err)) << err;
      wb.update();
      imgui.frames(wb, ps);
      EXPECT_TRUE(ps.layout_problems.empty()) << type << ":\n" << joined(ps.layout_problems);
      EXPECT_FALSE(ps.expand_all) << "expand opens the panels once";
    }
  }
}

TEST(UiPanels, LightsPanelFitsWithEveryKindOfLight) {
  tracer::Scene scene = tracer::builtin_default_scene();
  tracer::PointLightDesc bulb;
  bulb.name = "a point light with a rather long name";
  bulb.position = tracer::vec3(278.0f, 400.0f, 278.0f);
  bulb.intensity = tracer::vec3(30000.0f);
  tracer::PointLightDesc stage = bulb;
  stage.name = "stage";
  stage.spot = true;
  tracer::DistantLightDesc sun;
  sun.name = "sun";
  scene.point_lights = {bulb, stage};
  scene.distant_lights = {sun};
  for (const ImVec2 size : {ImVec2(1280, 720), ImVec2(1600, 900)}) {
    ui::Workbench wb(scene, tracer::BackendChoice::kCpu);
    std::string err;
    ASSERT_TRUE(wb.apply("render.spp=1", &err)) << err;
    HeadlessImGui imgui(size.x, size.y);
    ui::PanelState ps;
    ps.expand_all = true;
    imgui.frames(wb, ps);
    EXPECT_TRUE(ps.layout_problems.empty()) << joined(ps.layout_problems);
    // Drawing them edits nothing.
    EXPECT_EQ(wb.scene().point_lights[1].cone_angle_deg, 30.0f);
    EXPECT_EQ(wb.scene().point_lights[0].position, bulb.position);
  }
}

TEST(UiPanels, TheLayoutCheckSeesClippedLabels) {
  // The check above is not vacuous: with twice the font size the labels no longer fit.
  ui::Workbench wb(tracer::builtin_default_scene(), tracer::BackendChoice::kCpu);
  HeadlessImGui imgui(1280, 720);
  ImGui::GetIO().FontGlobalScale = 2.0f;
  ui::PanelState ps;
  ps.expand_all = true;
  imgui.frames(wb, ps);
  EXPECT_FALSE(ps.layout_problems.empty());
}

TEST(UiPanels, ANewErrorOpensTheMessagesAndItsSelectionStays) {
  ui::Workbench wb(tracer::builtin_default_scene(), tracer::BackendChoice::kCpu);
  HeadlessImGui imgui(1280, 720);
  ui::PanelState ps;
  wb.messages.warning("a.json:1: a warning; continued");
  imgui.frames(wb, ps);
  EXPECT_FALSE(ps.show_messages) << "warnings are counted in the status line, not opened";
  wb.messages.error("out/x.png: cannot be written; nothing was exported");
  imgui.frames(wb, ps, 1);
  EXPECT_TRUE(ps.show_messages) << "an error opens the list";
  ps.show_messages = false;  // the user closes it
  imgui.frames(wb, ps);
  EXPECT_FALSE(ps.show_messages) << "the same error does not reopen it";
  // Drawing the panels does not move the material away from the user's choice.
  wb.selected_material = 3;
  imgui.frames(wb, ps);
  EXPECT_EQ(wb.selected_material, 3);
}

}  // namespace
