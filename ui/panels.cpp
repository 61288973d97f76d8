// ImGui panels of the workbench. Layout: the viewport fills the window left of a fixed-width
// control column; the column opens with the status line (message counts, the last action's
// result, the Messages list), then one collapsing section per panel. Widgets fill the column but
// a fixed label column on their right, so no label and no value is clipped at 1280x720.
#include "ui/panels.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "materials/metals.h"
#include "ui/widgets.h"

namespace ui {
namespace {

constexpr float kColumnWidth = 460.0f;
constexpr float kMessagesHeight = 150.0f;  // the Messages list scrolls beyond this
// Letter keys: ImGui 1.86's key indices are the platform's, and GLFW's are upper-case ASCII.

void viewport(Workbench& wb, PanelState& ps, ImVec2 pos, ImVec2 size) {
  ImGui::SetNextWindowPos(pos);
  ImGui::SetNextWindowSize(size);
  ImGui::Begin("Viewport", nullptr,
               ImGuiWindowFlags_NoTitleBar | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoMove |
                   ImGuiWindowFlags_NoScrollbar | ImGuiWindowFlags_NoBringToFrontOnFocus);
  const ImVec2 avail = ImGui::GetContentRegionAvail();
  const float aspect = float(wb.width()) / float(wb.height());
  ImVec2 img(avail.x, avail.x / aspect);
  if (img.y > avail.y) img = ImVec2(avail.y * aspect, avail.y);
  const ImVec2 cursor = ImGui::GetCursorPos();
  ImGui::SetCursorPos(ImVec2(cursor.x + 0.5f * (avail.x - img.x), cursor.y + 0.5f * (avail.y - img.y)));
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  if (ps.texture) ImGui::Image(ps.texture, img);
  else ImGui::Dummy(img);
  const bool hovered = ImGui::IsItemHovered();
  ImGuiIO& io = ImGui::GetIO();
  const float u = (io.MousePos.x - origin.x) / img.x, v = (io.MousePos.y - origin.y) / img.y;
  if (hovered) {
    // Left drag orbits, right drag pans, the wheel zooms; a click selects, Ctrl+click (or a
    // middle click) focuses the lens on the surface under the cursor.
    if (ImGui::IsMouseDragging(ImGuiMouseButton_Left)) {
      wb.orbit(io.MouseDelta.x * 0.3f, io.MouseDelta.y * 0.3f);
    } else if (ImGui::IsMouseDragging(ImGuiMouseButton_Right)) {
      wb.pan(-io.MouseDelta.x / img.x, io.MouseDelta.y / img.y);
    }
    if (io.MouseWheel != 0.0f) wb.zoom(std::pow(0.9f, io.MouseWheel));
    if (ImGui::IsMouseReleased(ImGuiMouseButton_Left) &&
        ImGui::GetMouseDragDelta(ImGuiMouseButton_Left, 0.0f).x == 0.0f &&
        ImGui::GetMouseDragDelta(ImGuiMouseButton_Left, 0.0f).y == 0.0f) {
      if (io.KeyCtrl) {
        if (wb.focus_at(u, v)) ps.status = "focus set to the surface under the cursor";
      } else {
        wb.select_object(wb.pick_object(u, v));
      }
    }
    if (ImGui::IsMouseClicked(ImGuiMouseButton_Middle) && wb.focus_at(u, v))
      ps.status = "focus set to the surface under the cursor";
  }
  if (!io.WantTextInput) {
    const float step = 0.02f;
    float f = 0, r = 0, up = 0;
    if (ImGui::IsKeyDown('W')) f += step;
    if (ImGui::IsKeyDown('S') && !io.KeyCtrl) f -= step;
    if (ImGui::IsKeyDown('D')) r += step;
    if (ImGui::IsKeyDown('A')) r -= step;
    if (ImGui::IsKeyDown('E')) up += step;
    if (ImGui::IsKeyDown('Q')) up -= step;
    if (f != 0 || r != 0 || up != 0) wb.fly(f, r, up);
  }
  // The frame's figures over the image, so they stay visible with the panels hidden.
  char line[256];
  const std::string counts = wb.messages.summary();
  char denoised[48] = "";
  if (wb.aov_view())
    std::snprintf(denoised, sizeof denoised, "  showing an AOV (Display)");
  else if (const uint32_t d = wb.shown_denoised_spp())
    std::snprintf(denoised, sizeof denoised, "  denoised (%u spp)", d);
  std::snprintf(line, sizeof line, "%u spp  %.1f spp/s  %.0f Mrays/s  %s%s%s%s", wb.stats().spp,
                wb.stats().samples_per_s, wb.stats().mrays_per_s, wb.backend_name().c_str(),
                denoised, counts.empty() ? "" : "  ", counts.c_str());
  ImGui::GetWindowDrawList()->AddText(ImVec2(origin.x + 8, origin.y + 8), IM_COL32(255, 255, 0, 255),
                                      line);
  if (wb.loading())  // the scene shown stays until the new one is ready
    ImGui::GetWindowDrawList()->AddText(
        ImVec2(origin.x + 8, origin.y + 8 + ImGui::GetTextLineHeightWithSpacing()),
        IM_COL32(255, 255, 0, 255), ("loading " + wb.loading_status()).c_str());
  ImGui::End();
}

void scene_panel(Workbench& wb, PanelState& ps) {
  if (!section(ps, "Scene", ImGuiTreeNodeFlags_DefaultOpen)) return;
  ImGui::TextWrapped("%s", wb.scene().source.c_str());
  ImGui::SetNextItemWidth(-width_beside("Load"));
  ImGui::InputText("##scenepath", ps.scene_path, sizeof ps.scene_path);
  ImGui::SameLine();
  // The file loads on a thread: the scene shown renders on until the new one is ready.
  const bool busy = wb.loading();
  if (busy) ImGui::BeginDisabled();
  if (ImGui::Button("Load")) {
    std::string err;
    if (!wb.start_loading(ps.scene_path, &err)) wb.messages.error(err);
  }
  if (busy) ImGui::EndDisabled();
  if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
    ImGui::SetTooltip(".json scene, .obj, .gltf/.glb, .ply or pbrt-v4 .pbrt (docs/SCENE_FORMAT.md); "
                      "it loads in the background while the scene shown renders on");
  check_fit(ps, "Load");
  const std::string load_status = wb.loading_status();
  if (!load_status.empty()) {
    const bool failed = load_status.rfind("error", 0) == 0;
    if (failed) ImGui::PushStyleColor(ImGuiCol_Text, IM_COL32(255, 90, 90, 255));
    ImGui::TextWrapped("%s%s", busy ? "loading " : "", load_status.c_str());
    if (failed) ImGui::PopStyleColor();
  }
  const auto& objects = wb.scene().objects;
  // As tall as the list up to 8 lines, then it scrolls.
  const float list_h =
      ImGui::GetTextLineHeightWithSpacing() * float(std::clamp<size_t>(objects.size(), 2, 8)) +
      2.0f * ImGui::GetStyle().FramePadding.y;
  if (ImGui::BeginListBox("##objects", ImVec2(-FLT_MIN, list_h))) {
    for (size_t i = 0; i < objects.size(); ++i) {
      const std::string label = objects[i].name + "  (" + objects[i].kind + ")";
      if (ImGui::Selectable(label.c_str(), wb.selected_object == int(i))) wb.select_object(int(i));
      // An object selected elsewhere (a click in the viewport, a script) scrolls into view.
      if (wb.selected_object == int(i) && ps.listed_selection != int(i)) ImGui::SetScrollHereY();
    }
    ps.listed_selection = wb.selected_object;
    ImGui::EndListBox();
  }
  const int mat = wb.material_of(wb.selected_object);
  if (mat >= 0)
    ImGui::TextWrapped("selected: %s, material \"%s\"",
                       wb.scene().objects[size_t(wb.selected_object)].name.c_str(),
                       wb.scene().materials[size_t(mat)].name.c_str());
}

void material_panel(Workbench& wb, PanelState& ps) {
  if (!section(ps, "Material", ImGuiTreeNodeFlags_DefaultOpen)) return;
  auto& mats = wb.scene().materials;
  if (mats.empty()) return;
  wb.selected_material = std::clamp(wb.selected_material, 0, int(mats.size()) - 1);
  if (ImGui::BeginCombo("material", mats[size_t(wb.selected_material)].name.c_str())) {
    for (size_t i = 0; i < mats.size(); ++i)
      if (ImGui::Selectable(mats[i].name.c_str(), int(i) == wb.selected_material))
        wb.selected_material = int(i);
    ImGui::EndCombo();
  }
  check_fit(ps, "material");
  tracer::Material& m = mats[size_t(wb.selected_material)].material;
  bool changed = false;
  int type = int(m.type);
  if (ImGui::Combo("type", &type,
                   "diffuse\0mirror\0dielectric\0conductor\0subsurface\0coated diffuse\0"
                   "diffuse transmission\0")) {
    m.type = tracer::MaterialType(type);
    changed = true;
  }
  check_fit(ps, "type");
  const bool sss = m.type == tracer::MaterialType::kSubsurface;
  const bool metal = m.type == tracer::MaterialType::kConductor;
  const bool ior_metal = metal && (m.flags & tracer::kMaterialConductorIor);
  const bool coated = m.type == tracer::MaterialType::kCoatedDiffuse;
  const bool sheet = m.type == tracer::MaterialType::kDiffuseTransmission;
  if (metal) {
    // Schlick (F0 = a colour, glTF's model) or a complex index: a named metal or eta and k.
    const std::vector<std::string> names = tracer::metal_names();
    std::string current = ior_metal ? "eta, k" : "Schlick F0";
    for (const tracer::NamedMetal& nm : tracer::named_metals())
      if (ior_metal && nm.eta == m.eta && nm.k == m.k) current = nm.name;
    if (ImGui::BeginCombo("Fresnel", current.c_str())) {
      if (ImGui::Selectable("Schlick F0", !ior_metal)) {
        m.flags &= ~tracer::kMaterialConductorIor;
        changed = true;
      }
      for (const tracer::NamedMetal& nm : tracer::named_metals()) {
        if (ImGui::Selectable(nm.name, current == nm.name)) {
          if (!ior_metal) m.albedo = vec3(1.0f);  // F0 becomes a tint
          m.flags |= tracer::kMaterialConductorIor;
          m.eta = nm.eta;
          m.k = nm.k;
          changed = true;
        }
      }
      ImGui::EndCombo();
    }
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip(
          "Schlick's approximation with F0 = the colour, or the exact Fresnel\n"
          "equations of a measured metal's complex index eta + i k");
    check_fit(ps, "Fresnel");
  }
  if (!sss) {
    changed |= ImGui::ColorEdit3(m.type == tracer::MaterialType::kDiffuse ? "base colour"
                                 : metal && !ior_metal                    ? "F0 colour"
                                 : coated                                 ? "base colour"
                                 : sheet                                  ? "reflectance"
                                                                          : "tint",
                                 &m.albedo.x);
    check_fit(ps, "base colour");
  }
  if (sheet) {
    changed |= ImGui::ColorEdit3("transmittance", &m.transmittance.x);
    check_fit(ps, "transmittance");
  }
  if (ior_metal) {
    changed |= drag(ps, "eta", &m.eta.x, 3, 0.01f, 0.01f, 10.0f, "%.3f");
    changed |= drag(ps, "k", &m.k.x, 3, 0.01f, 0.0f, 20.0f, "%.3f");
  }
  if (m.type == tracer::MaterialType::kDielectric || metal || coated)
    changed |= slider(ps, "roughness", &m.roughness, 1, 0.0f, 1.0f, "%.3f");
  if (metal) {
    // Anisotropy: a second roughness across the tangent (the world y axis on the surface).
    bool aniso = m.roughness_v >= 0.0f;
    if (ImGui::Checkbox("anisotropic", &aniso)) {
      m.roughness_v = aniso ? m.roughness : -1.0f;
      changed = true;
    }
    check_fit(ps, "anisotropic");
    if (aniso) changed |= slider(ps, "roughness v", &m.roughness_v, 1, 0.0f, 1.0f, "%.3f");
  }
  if (coated) {
    changed |= slider(ps, "coat IOR", &m.ior, 1, 1.0f, 3.0f, "%.3f");
    changed |= drag(ps, "coat absorption", &m.absorption.x, 3, 0.001f, 0.0f, 1e3f, "%.4f");
    changed |= drag(ps, "coat thickness", &m.thickness, 1, 0.001f, 0.0f, 1e3f, "%.4f");
  }
  if (sss) {
    // Edited as the artist's pair (surface colour, mean free path) and shown as coefficients.
    const vec3 sigma_t = m.scattering + m.absorption;
    vec3 mfp = 1.0f / glm::max(sigma_t, vec3(1e-6f));
    vec3 single = m.scattering / glm::max(sigma_t, vec3(1e-12f));
    bool e = drag(ps, "mean free path", &mfp.x, 3, 0.01f * tracer::max_component(mfp), 1e-4f, 1e6f,
                  "%.4g");
    e |= slider(ps, "scatter albedo", &single.x, 3, 0.0f, 1.0f, "%.4f");
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip("single-scattering albedo: scattering / (scattering + absorption)");
    if (e) {
      const vec3 st = 1.0f / glm::max(mfp, vec3(1e-4f));
      m.scattering = glm::clamp(single, vec3(0.0f), vec3(1.0f)) * st;
      m.absorption = st - m.scattering;
      changed = true;
    }
    changed |= slider(ps, "anisotropy g", &m.g, 1, -0.95f, 0.95f, "%.2f");
    changed |= slider(ps, "IOR", &m.ior, 1, 1.0f, 3.0f, "%.3f");
    bool smooth = m.flags & tracer::kMaterialSmoothExit;
    if (ImGui::Checkbox("smooth exit (else diffuse)", &smooth)) {
      m.flags = smooth ? (m.flags | tracer::kMaterialSmoothExit)
                       : (m.flags & ~tracer::kMaterialSmoothExit);
      changed = true;
    }
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip(
          "How a random walk leaves the medium. Diffuse (default): the boundary scatters the\n"
          "light out as a Lambertian sheet with the smooth boundary's energy fractions, and\n"
          "light sampling works at the exit point (far less noise). Smooth: refraction through\n"
          "the dielectric boundary, reachable by BSDF sampling only (materials.NAME.exit)");
    check_fit(ps, "smooth exit (else diffuse)");
  }
  if (m.type == tracer::MaterialType::kDielectric) {
    changed |= slider(ps, "IOR", &m.ior, 1, 1.01f, 3.0f, "%.3f");
    bool schlick = m.flags & tracer::kMaterialSchlickFresnel;
    const bool toggled = ImGui::Checkbox("Schlick Fresnel (else exact)", &schlick);
    check_fit(ps, "Schlick Fresnel (else exact)");
    if (toggled) {
      m.flags = schlick ? (m.flags | tracer::kMaterialSchlickFresnel)
                        : (m.flags & ~tracer::kMaterialSchlickFresnel);
      changed = true;
    }
    changed |= drag(ps, "absorption", &m.absorption.x, 3, 0.001f, 0.0f, 1e3f, "%.4f");
  }
  float strength = tracer::max_component(m.emission);
  vec3 colour = strength > 0.0f ? m.emission / strength : vec3(1.0f);
  bool e = ImGui::ColorEdit3("emission colour", &colour.x);
  check_fit(ps, "emission colour");
  e |= drag(ps, "emission strength", &strength, 1, 0.05f, 0.0f, 1e6f, "%.3f");
  if (e) {
    m.emission = colour * std::max(strength, 0.0f);
    changed = true;
  }
  bool two = m.flags & tracer::kMaterialTwoSidedEmission;
  const bool toggled = ImGui::Checkbox("two-sided emission", &two);
  check_fit(ps, "two-sided emission");
  if (toggled) {
    m.flags = two ? (m.flags | tracer::kMaterialTwoSidedEmission)
                  : (m.flags & ~tracer::kMaterialTwoSidedEmission);
    changed = true;
  }
  m.albedo = glm::clamp(m.albedo, vec3(0.0f), vec3(1.0f));
  m.absorption = glm::max(m.absorption, vec3(0.0f));
  // A sheet cannot send on more than it receives: the transmittance gives way to the reflectance.
  m.transmittance = glm::clamp(m.transmittance, vec3(0.0f), vec3(1.0f) - m.albedo);
  if (changed) wb.changed(Edit::kMaterial);
}

void camera_panel(Workbench& wb, PanelState& ps) {
  if (!section(ps, "Camera")) return;
  const tracer::CameraDesc& c = wb.scene().camera;
  const float dist = std::max(1e-6f, glm::length(c.look_at - c.position));
  setting_widget(wb, ps, "camera.position", "position", 0.01f * dist);
  setting_widget(wb, ps, "camera.look_at", "look at", 0.01f * dist);
  setting_widget(wb, ps, "camera.vfov", "vertical FOV", 0.2f, "%.1f deg");
  setting_widget(wb, ps, "camera.aperture", "aperture radius", 0.001f * dist, "%.4f");
  setting_widget(wb, ps, "camera.focus_distance", "focus distance", 0.005f * dist, "%.3f");
  if (ImGui::Button("Reset view (F)")) wb.reset_view();
  ImGui::TextWrapped(
      "Viewport: left drag orbits, right drag pans, wheel zooms, W/A/S/D/Q/E fly, click selects, "
      "Ctrl+click or middle click focuses on the surface under the cursor.");
}

// The environment light: its map (a file field and Load; None drops it), how the map is read and
// placed, and what camera rays see; a preview of the map. Every edit goes through the settings
// table (Workbench::set), so it restarts the image and a new file is read and checked there.
void environment_panel(Workbench& wb, PanelState& ps) {
  if (!section(ps, "Environment")) return;
  const std::string& file = wb.scene().environment.file;
  if (file != ps.env_path_shown) {  // the scene changed it (a load, a script): show its value
    std::snprintf(ps.env_path, sizeof ps.env_path, "%s", file.c_str());
    ps.env_path_shown = file;
  }
  auto set_file = [&](const std::string& path) {
    std::string err;
    const tracer::Setting* s = tracer::find_setting("environment.file");
    if (wb.set(*s, nlohmann::json(path), &err)) {
      ps.status = path.empty() ? "environment map removed" : "environment map " + path + " loaded";
    } else {
      ps.status = "error: " + err;
      wb.messages.error(err);
    }
  };
  const float buttons = width_beside("Load##env") + width_beside("None##env");
  ImGui::SetNextItemWidth(-buttons);
  const bool enter = ImGui::InputText("##envpath", ps.env_path, sizeof ps.env_path,
                                      ImGuiInputTextFlags_EnterReturnsTrue);
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip("%s\n(--set environment.file, --env)",
                      tracer::find_setting("environment.file")->help.c_str());
  ImGui::SameLine();
  if (ImGui::Button("Load##env") || enter) set_file(ps.env_path);
  ImGui::SameLine();
  if (ImGui::Button("None##env")) set_file("");
  check_fit(ps, "None##env");
  ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyleColorVec4(ImGuiCol_TextDisabled));
  ImGui::TextWrapped("map: %s", wb.environment_summary().c_str());
  ImGui::PopStyleColor();
  setting_widget(wb, ps, "environment.mapping", "mapping");
  setting_widget(wb, ps, "environment.strength", "strength", 0.01f, "%.3f", 10.0);
  setting_widget(wb, ps, "environment.rotation", "rotation", 0.5f, "%.1f deg");
  setting_widget(wb, ps, "environment.visible", "visible to the camera");
  setting_widget(wb, ps, "environment.background", "background", 0.01f);
  setting_widget(wb, ps, "environment.color", "constant colour", 0.01f);
  if (ps.env_texture && ps.env_preview_w > 0 && ps.env_preview_h > 0) {
    const float w = std::min(ImGui::GetContentRegionAvail().x, 256.0f);
    ImGui::Image(ps.env_texture, ImVec2(w, w * float(ps.env_preview_h) / float(ps.env_preview_w)));
  }
}

// The lights that are no geometry: the scene's distant, point and spot lights, each a tree node
// with its position or direction, its intensity or irradiance and, for spot lights, the cone.
// Every edit goes through lights.NAME.FIELD (Workbench::apply), so it is checked as on the
// command line and restarts the image.
void lights_panel(Workbench& wb, PanelState& ps) {
  if (!section(ps, "Lights")) return;
  const tracer::Scene& scene = wb.scene();
  if (scene.point_lights.empty() && scene.distant_lights.empty()) {
    ImGui::TextWrapped(
        "No point, spot or distant lights (the scene file's \"lights\"; pbrt's LightSource). "
        "Emissive objects are edited as materials, the environment above.");
    return;
  }
  auto edit = [&](const std::string& name, const char* field, const float* v, int n) {
    std::string value;
    char num[32];
    for (int i = 0; i < n; ++i) {
      std::snprintf(num, sizeof num, "%.9g", double(v[i]));
      value += (i ? "," : "") + std::string(num);
    }
    std::string err;
    if (!wb.apply("lights." + name + "." + field + "=" + value, &err)) {
      ps.status = "error: " + err;
      wb.messages.error(err);
    }
  };
  const float reach = std::max(1.0f, glm::length(scene.camera.look_at - scene.camera.position));
  // Copies: an edit may change the scene's lists while they are drawn.
  const std::vector<tracer::PointLightDesc> points = scene.point_lights;
  const std::vector<tracer::DistantLightDesc> suns = scene.distant_lights;
  for (size_t i = 0; i < points.size(); ++i) {
    tracer::PointLightDesc d = points[i];
    ImGui::PushID(int(i));
    const std::string title = d.name + (d.spot ? " (spot)" : " (point)");
    if (tree_node(ps, title.c_str())) {
      if (drag(ps, "position", &d.position.x, 3, 0.005f * reach, -1e30f, 1e30f, "%.3f"))
        edit(d.name, "position", &d.position.x, 3);
      const float peak = std::max(1e-3f, tracer::max_component(d.intensity));
      if (drag(ps, "intensity (W/sr)", &d.intensity.x, 3, 0.005f * peak, 0.0f, 1e30f, "%.4g"))
        edit(d.name, "intensity", &d.intensity.x, 3);
      if (d.spot) {
        if (drag(ps, "direction", &d.direction.x, 3, 0.01f, -1e30f, 1e30f, "%.3f"))
          edit(d.name, "direction", &d.direction.x, 3);
        if (slider(ps, "cone angle", &d.cone_angle_deg, 1, 0.1f, 180.0f, "%.1f deg"))
          edit(d.name, "cone_angle", &d.cone_angle_deg, 1);
        if (slider(ps, "cone delta angle", &d.cone_delta_angle_deg, 1, 0.0f, d.cone_angle_deg,
                   "%.1f deg"))
          edit(d.name, "cone_delta_angle", &d.cone_delta_angle_deg, 1);
        if (ImGui::IsItemHovered())
          ImGui::SetTooltip(
              "the falloff's width: full intensity within cone - delta of the "
              "axis, none beyond the cone angle");
      }
      ImGui::TreePop();
    }
    ImGui::PopID();
  }
  for (size_t i = 0; i < suns.size(); ++i) {
    tracer::DistantLightDesc d = suns[i];
    ImGui::PushID(int(points.size() + i));
    const std::string title = d.name + " (distant)";
    if (tree_node(ps, title.c_str())) {
      if (drag(ps, "direction", &d.direction.x, 3, 0.01f, -1e30f, 1e30f, "%.3f"))
        edit(d.name, "direction", &d.direction.x, 3);
      const float peak = std::max(1e-3f, tracer::max_component(d.irradiance));
      if (drag(ps, "irradiance", &d.irradiance.x, 3, 0.005f * peak, 0.0f, 1e30f, "%.4g"))
        edit(d.name, "irradiance", &d.irradiance.x, 3);
      if (slider(ps, "angular diameter", &d.angular_diameter_deg, 1, 0.0f, 10.0f, "%.2f deg"))
        edit(d.name, "angular_diameter", &d.angular_diameter_deg, 1);
      ImGui::TreePop();
    }
    ImGui::PopID();
  }
}

void render_panel(Workbench& wb, PanelState& ps) {
  if (!section(ps, "Render", ImGuiTreeNodeFlags_DefaultOpen)) return;
  setting_widget(wb, ps, "render.backend", "backend");
  ImGui::TextDisabled("%s: %s", wb.backend_name().c_str(), wb.device_name().c_str());
  setting_widget(wb, ps, "render.max_depth", "max depth", 0.0f, nullptr, 64);
  setting_widget(wb, ps, "render.nee", "next-event estimation");
  ImGui::SameLine();
  setting_widget(wb, ps, "render.mis", "MIS");
  setting_widget(wb, ps, "render.russian_roulette", "Russian roulette");
  ImGui::SameLine();
  ImGui::SetNextItemWidth(std::max(40.0f, ImGui::GetContentRegionAvail().x -
                                              ImGui::CalcTextSize("from depth").x -
                                              ImGui::GetStyle().ItemInnerSpacing.x));
  setting_widget(wb, ps, "render.rr_start_depth", "from depth", 0.0f, nullptr, 16);
  setting_widget(wb, ps, "render.jitter", "pixel jitter");
  setting_widget(wb, ps, "render.sampler", "sampler");
  setting_widget(wb, ps, "render.light_sampler", "light sampler");
  setting_widget(wb, ps, "render.guiding", "path guiding");
  setting_widget(wb, ps, "render.mnee", "manifold NEE (glass, mirrors)");
  if (wb.settings().mnee && !wb.mnee_has_casters()) {
    ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyleColorVec4(ImGuiCol_TextDisabled));
    ImGui::TextWrapped("  nothing in this scene to connect through or reflect off (no smooth "
                       "glass, flat mirrors or mirror spheres): renders as without it");
    ImGui::PopStyleColor();
  }
  setting_widget(wb, ps, "render.light_tracing", "light tracing (caustics)");
  const float yield = wb.light_path_yield();
  if (wb.settings().light_tracing &&
      (!wb.settings().jitter || yield < tracer::kLightTracingMinYield)) {
    ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyleColorVec4(ImGuiCol_TextDisabled));
    if (!wb.settings().jitter)
      ImGui::TextWrapped("  off while pixel jitter is off (splats need jittered pixels)");
    else if (yield < 0.0f)
      ImGui::TextWrapped("  no light path to find in this scene (no area light, or no mirror, "
                         "glass or glossy metal): renders as without it");
    else
      ImGui::TextWrapped("  only %.2f%% of its light paths reach the camera through a mirror, "
                         "glass or metal (below %.1f%%): the path tracer renders alone",
                         100.0f * yield, 100.0f * tracer::kLightTracingMinYield);
    ImGui::PopStyleColor();
  }
  setting_widget(wb, ps, "render.filter", "pixel filter");
  setting_widget(wb, ps, "render.filter_radius", "filter radius", 0.05f, "%.2f px (0: default)");
  setting_widget(wb, ps, "render.clamp", "clamp (0: off)", 0.1f, "%.2f");
  setting_widget(wb, ps, "render.width", "width");
  setting_widget(wb, ps, "render.height", "height");
  setting_widget(wb, ps, "render.spp", "stop at spp");
  setting_widget(wb, ps, "render.time_limit_s", "stop after s", 1.0f, "%.1f");
  setting_widget(wb, ps, "render.samples_per_frame", "samples/frame", 0.0f, nullptr, 256);
  ImGui::Checkbox("pause", &wb.paused);
  ImGui::SameLine();
  if (ImGui::Button("Reset accumulator (R)")) wb.changed(Edit::kSettings);
  if (tree_node(ps, "GPU")) {
    setting_widget(wb, ps, "gpu.kernel", "kernel");
    setting_widget(wb, ps, "gpu.compaction", "compaction");
    setting_widget(wb, ps, "gpu.tail", "tail below", 0.01f, "%.2f of paths");
    setting_widget(wb, ps, "gpu.sort", "material sorting");
    setting_widget(wb, ps, "gpu.cache", "first-bounce cache");
    setting_widget(wb, ps, "gpu.flat", "flat list (small scenes)");
    ImGui::TreePop();
  }
}

// relMSE against time since the last reset, log-log, as `pathtracer bench --error` plots it:
// decade grid, the 1e-2 and 1e-3 levels dashed, and the fitted slope (-1 when unbiased).
void error_curve_plot(const std::vector<tracer::Checkpoint>& curve) {
  double x0 = 1e300, x1 = 0, y0 = 1e300, y1 = 0;
  for (const auto& c : curve) {
    if (!(c.seconds > 0) || !(c.error.relmse > 0)) continue;
    x0 = std::min(x0, c.seconds), x1 = std::max(x1, c.seconds);
    y0 = std::min(y0, c.error.relmse), y1 = std::max(y1, c.error.relmse);
  }
  if (!(x1 > x0) || !(y1 > 0)) return;
  const double lx0 = std::floor(std::log10(x0)), lx1 = std::max(lx0 + 1, std::ceil(std::log10(x1)));
  const double ly0 = std::floor(std::log10(std::min(y0, 1e-3))), ly1 = std::max(ly0 + 1, std::ceil(std::log10(y1)));
  const ImVec2 size(ImGui::GetContentRegionAvail().x, 140.0f);
  const ImVec2 p0 = ImGui::GetCursorScreenPos();
  const ImVec2 p1(p0.x + size.x, p0.y + size.y);
  ImDrawList* dl = ImGui::GetWindowDrawList();
  dl->PushClipRect(p0, p1, true);  // levels and lines outside the axes' range stay inside
  dl->AddRectFilled(p0, p1, IM_COL32(20, 20, 24, 255));
  auto pt = [&](double x, double y) {
    return ImVec2(p0.x + float((std::log10(x) - lx0) / (lx1 - lx0)) * size.x,
                  p1.y - float((std::log10(y) - ly0) / (ly1 - ly0)) * size.y);
  };
  for (double k = lx0; k <= lx1; k += 1) {
    const float x = pt(std::pow(10.0, k), 1.0).x;
    dl->AddLine(ImVec2(x, p0.y), ImVec2(x, p1.y), IM_COL32(70, 70, 80, 255));
  }
  for (double k = ly0; k <= ly1; k += 1) {
    const float y = pt(1.0, std::pow(10.0, k)).y;
    dl->AddLine(ImVec2(p0.x, y), ImVec2(p1.x, y), IM_COL32(70, 70, 80, 255));
  }
  for (double level : {1e-2, 1e-3}) {
    const float y = pt(1.0, level).y;
    for (float x = p0.x; x < p1.x; x += 8.0f)
      dl->AddLine(ImVec2(x, y), ImVec2(std::min(x + 4.0f, p1.x), y), IM_COL32(200, 200, 120, 255));
  }
  std::vector<ImVec2> line;
  for (const auto& c : curve)
    if (c.seconds > 0 && c.error.relmse > 0) line.push_back(pt(c.seconds, c.error.relmse));
  dl->AddPolyline(line.data(), int(line.size()), IM_COL32(90, 170, 255, 255), 0, 2.0f);
  dl->PopClipRect();
  ImGui::Dummy(size);
  const tracer::ConvergenceSummary sum = tracer::summarize(curve);
  ImGui::TextDisabled("relMSE 1e%.0f..1e%.0f against time 1e%.0f..1e%.0f s", ly0, ly1, lx0, lx1);
  ImGui::TextDisabled("log-log; dashed: relMSE 1e-2 and 1e-3");
  if (sum.slope_points >= 3) ImGui::TextWrapped("%s", sum.verdict.c_str());
  if (sum.to_1e2.seconds >= 0 && !sum.to_1e2.extrapolated)
    ImGui::Text("relMSE 1e-2 after %.3g s", sum.to_1e2.seconds);
  if (sum.to_1e3.seconds >= 0 && !sum.to_1e3.extrapolated)
    ImGui::Text("relMSE 1e-3 after %.3g s", sum.to_1e3.seconds);
}

void stats_panel(Workbench& wb, PanelState& ps) {
  if (!section(ps, "Stats", ImGuiTreeNodeFlags_DefaultOpen)) return;
  const WorkbenchStats& s = wb.stats();
  ImGui::Text("%u spp%s, %.1f s, %.1f spp/s", s.spp, wb.converged() ? " (done)" : "", s.elapsed_s,
              s.samples_per_s);
  ImGui::Text("%.2f ms per frame, %.0f Mrays/s, %.1f UI fps", s.ms_per_frame, s.mrays_per_s,
              ImGui::GetIO().Framerate);
  ImGui::Text("NaN/Inf samples rejected: %llu", (unsigned long long)s.nonfinite);
  ImGui::TextWrapped("%s", wb.shown_image().c_str());
  if (s.guide.on) {
    ImGui::TextWrapped("path guiding: %s", s.guide.describe().c_str());
    if (!s.guide.frozen())
      ImGui::ProgressBar(float(s.guide.trained_samples) / float(tracer::kGuideTrainSamples),
                         ImVec2(-1, 0), "guide training");
  }
  if (s.relmse_halves >= 0) {
    ImGui::Text("half-buffer relMSE: %.3g", s.relmse_halves);
    if (!tracer::independent_halves(wb.settings().sampler)) {
      ImGui::SameLine();
      ImGui::TextDisabled("(reads high with sobol)");
      if (ImGui::IsItemHovered())
        ImGui::SetTooltip(
            "The Sobol sequence's even and odd samples fill each other's gaps, so the two\n"
            "halves differ more than independent estimates would: 2-3x at 16-4096 spp on\n"
            "the Cornell box. The sobol-pairs sampler makes them independent.");
    }
  } else
    ImGui::TextDisabled("half-buffer relMSE: needs more samples");
  if (s.relmse_reference >= 0) ImGui::Text("relMSE against the reference: %.3g", s.relmse_reference);
  if (s.error_curve.size() >= 2) error_curve_plot(s.error_curve);
  ImGui::Text("kernel: %s%s", s.last.kernel.c_str(), ps.interop ? " (CUDA/GL interop)" : "");
  if (!s.last.specialization.empty()) ImGui::TextWrapped("variant: %s", s.last.specialization.c_str());
  if (!s.last.note.empty()) ImGui::TextWrapped("%s", s.last.note.c_str());
  if (s.last.gpu) {
    // What resolve_gpu_options() decided for the switches asked for, with its reasons.
    const tracer::EffectiveGpuOptions& g = *s.last.gpu;
    size_t switches = 0;
    for (const auto& o : g.overrides) switches += o.path ? 0 : 1;
    char title[96];
    snprintf(title, sizeof title, "GPU design: %zu switch%s overridden###gpudesign", switches,
             switches == 1 ? "" : "es");
    if (tree_node(ps, title)) {
      for (const auto& o : g.overrides)
        ImGui::TextWrapped("%s %s: %s -> %s (%s)", o.path ? "path" : "switch", o.name.c_str(),
                           o.requested.c_str(), o.effective.c_str(), o.reason.c_str());
      ImGui::TextDisabled("build: %s", g.build_variant.c_str());
      ImGui::TreePop();
    }
  }
  const tracer::StageTimes& t = s.last.stages;
  if (t.intersect > 0 || t.megakernel > 0) {
    ImGui::TextWrapped("ms per sample: gen %.3f  isect %.3f  sort %.3f", t.generate, t.intersect,
                       t.sort);
    ImGui::TextWrapped("  shade %.3f  shadow %.3f  compact %.3f  mega %.3f", t.shade, t.shadow,
                       t.compact, t.megakernel);
    if (t.trace > 0)
      ImGui::TextWrapped("  trace %.3f (shadow rays with the next bounce's rays)", t.trace);
    if (t.mnee > 0) ImGui::TextWrapped("  mnee %.3f (manifold NEE's solves)", t.mnee);
    if (t.light > 0) ImGui::TextWrapped("  light %.3f (light tracing's paths)", t.light);
    if (t.tail_from > 0)
      ImGui::TextWrapped("  tail %.3f (the megakernel from bounce %u on)", t.tail, t.tail_from);
  }
  if (!s.last.alive_per_bounce.empty()) {
    std::vector<float> alive(s.last.alive_per_bounce.begin(), s.last.alive_per_bounce.end());
    ImGui::PlotHistogram(t.tail_from > 0 ? "paths alive\nper bounce\n(to the tail)"
                                         : "paths alive\nper bounce",
                         alive.data(), int(alive.size()), 0, nullptr, 0.0f, alive[0],
                         ImVec2(0, 60));
  }
  if (tree_node(ps, "Reference image")) {
    ImGui::SetNextItemWidth(-width_beside("Load"));
    ImGui::InputText("##ref", ps.reference_path, sizeof ps.reference_path);
    ImGui::SameLine();
    if (ImGui::Button("Load##ref")) {
      std::string err;
      ps.status = wb.load_reference(ps.reference_path, &err)
                      ? std::string("reference ") + ps.reference_path + " loaded"
                      : "error: " + err;
      if (!err.empty()) wb.messages.error(err);
    }
    check_fit(ps, "Load (reference)");
    ImGui::TreePop();
  }
}

void display_panel(Workbench& wb, PanelState& ps) {
  if (!section(ps, "Display", ImGuiTreeNodeFlags_DefaultOpen)) return;
  setting_widget(wb, ps, "display.exposure", "exposure", 0.05f, "%+.2f stops", 8.0);
  setting_widget(wb, ps, "display.tonemap", "tone map");
  setting_widget(wb, ps, "display.denoise", "denoise");
  setting_widget(wb, ps, "display.view", "show");
  if (wb.display().denoise != tracer::DenoiseMode::kOff && !tracer::denoiser_available())
    ImGui::TextColored(ImVec4(1.0f, 0.45f, 0.35f, 1.0f), "denoiser absent: %s",
                       tracer::denoiser_status().c_str());
}

void export_now(Workbench& wb, PanelState& ps) {
  const std::string err = wb.export_image(ps.export_path);
  ps.status = err.empty() ? std::string("saved ") + ps.export_path + " (+ .json)" : "error: " + err;
  if (!err.empty()) wb.messages.error(err);
}

// The column's first lines, never scrolled away: the message counts (a button that opens the
// Messages list; a new error opens it by itself), the last action's result, and the list.
void status_line(Workbench& wb, PanelState& ps) {
  const MessageLog& log = wb.messages;
  const size_t errors = log.count(Severity::kError);
  if (errors > ps.errors_seen) ps.show_messages = true;
  ps.errors_seen = errors;
  const std::string counts = log.summary();
  const ImU32 colour = errors                          ? IM_COL32(255, 90, 90, 255)
                       : log.count(Severity::kWarning) ? IM_COL32(255, 200, 60, 255)
                                                       : IM_COL32(200, 200, 200, 255);
  ImGui::PushStyleColor(ImGuiCol_Text, colour);
  const std::string button = (counts.empty() ? std::string("no warnings") : counts) +
                             (log.empty()        ? ""
                              : ps.show_messages ? " (hide)"
                                                 : " (show)") +
                             "###messages";
  if (ImGui::SmallButton(button.c_str())) ps.show_messages = !ps.show_messages;
  ImGui::PopStyleColor();
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("Messages: errors, warnings, notes, results");
  if (!ps.status.empty()) {
    const bool error = ps.status.rfind("error", 0) == 0;
    if (error) ImGui::PushStyleColor(ImGuiCol_Text, IM_COL32(255, 90, 90, 255));
    ImGui::TextWrapped("%s", ps.status.c_str());
    if (error) ImGui::PopStyleColor();
  }
  if (ps.show_messages && !log.empty()) {
    // As tall as its lines up to kMessagesHeight, then it scrolls; newest first.
    const float line = ImGui::GetTextLineHeightWithSpacing();
    const float h = std::min(kMessagesHeight, line * float(log.all().size() + 1));
    ImGui::BeginChild("Messages", ImVec2(0, h), true);
    for (auto it = log.all().rbegin(); it != log.all().rend(); ++it) {
      const ImU32 c = it->severity == Severity::kError     ? IM_COL32(255, 90, 90, 255)
                      : it->severity == Severity::kWarning ? IM_COL32(255, 200, 60, 255)
                                                           : IM_COL32(200, 200, 200, 255);
      ImGui::PushStyleColor(ImGuiCol_Text, c);
      ImGui::TextWrapped("%s", to_string(*it).c_str());
      ImGui::PopStyleColor();
    }
    ImGui::EndChild();
  }
  ImGui::Separator();
}

void export_panel(Workbench& wb, PanelState& ps) {
  if (!section(ps, "Export", ImGuiTreeNodeFlags_DefaultOpen)) return;
  ImGui::InputText("image", ps.export_path, sizeof ps.export_path);
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip(".png (tone-mapped) or .exr (linear), with a .json sidecar");
  check_fit(ps, "image");
  if (ImGui::Button("Export image (Ctrl+S)")) export_now(wb, ps);
  ImGui::InputText("scene", ps.save_path, sizeof ps.save_path);
  if (ImGui::IsItemHovered()) ImGui::SetTooltip(".json that reloads every edit");
  check_fit(ps, "scene");
  if (ImGui::Button("Save scene")) {
    const std::string err = wb.save_scene(ps.save_path);
    ps.status = err.empty() ? std::string("saved ") + ps.save_path : "error: " + err;
    if (!err.empty()) wb.messages.error(err);
  }
}

}  // namespace

bool draw_workbench(Workbench& wb, PanelState& ps) {
  ImGuiIO& io = ImGui::GetIO();
  if (!io.WantTextInput) {
    if (ImGui::IsKeyPressed(ImGui::GetKeyIndex(ImGuiKey_Tab)) || ImGui::IsKeyPressed('H')) ps.show_ui = !ps.show_ui;
    if (ImGui::IsKeyPressed('R')) wb.changed(Edit::kSettings);
    if (ImGui::IsKeyPressed('F')) wb.reset_view();
    if (io.KeyCtrl && ImGui::IsKeyPressed('S')) export_now(wb, ps);
  }
  ps.layout_problems.clear();
  const ImVec2 display = io.DisplaySize;
  const float column = ps.show_ui ? kColumnWidth : 0.0f;
  viewport(wb, ps, ImVec2(0, 0), ImVec2(display.x - column, display.y));
  if (!ps.show_ui) return false;
  ImGui::SetNextWindowPos(ImVec2(display.x - column, 0));
  ImGui::SetNextWindowSize(ImVec2(column, display.y));
  // The scroll bar always shows, so opening a panel never reflows the column.
  ImGui::Begin("Workbench", nullptr,
               ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoMove |
                   ImGuiWindowFlags_AlwaysVerticalScrollbar);
  // Anything wider than the column (last frame's content) makes it scroll sideways.
  if (ImGui::GetScrollMaxX() > 0.0f)
    ps.layout_problems.push_back("the panel column's content is wider than the column");
  status_line(wb, ps);
  ImGui::PushItemWidth(-label_column());
  scene_panel(wb, ps);
  material_panel(wb, ps);
  camera_panel(wb, ps);
  environment_panel(wb, ps);
  lights_panel(wb, ps);
  render_panel(wb, ps);
  stats_panel(wb, ps);
  display_panel(wb, ps);
  export_panel(wb, ps);
  ImGui::PopItemWidth();
  ImGui::TextDisabled("Tab/H hides the panels, R resets, Ctrl+S exports");
  ImGui::End();
  ps.expand_all = false;
  return false;
}

}  // namespace ui
