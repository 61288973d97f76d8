// The panels' widgets and the check that each fits the column (see widgets.h).
#include "ui/widgets.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

namespace ui {
namespace {

// The widest label a widget may have beside it.
constexpr const char* kWidestLabel = "first-bounce cache";

std::string format_float(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace

float label_column() {
  return ImGui::CalcTextSize(kWidestLabel).x + ImGui::GetStyle().ItemInnerSpacing.x;
}

float width_beside(const char* label) {
  const ImGuiStyle& style = ImGui::GetStyle();
  return ImGui::CalcTextSize(label).x + 2.0f * style.FramePadding.x + style.ItemSpacing.x;
}

bool section(PanelState& ps, const char* name, ImGuiTreeNodeFlags flags) {
  if (ps.expand_all) ImGui::SetNextItemOpen(true);
  return ImGui::CollapsingHeader(name, flags);
}

bool tree_node(PanelState& ps, const char* name) {
  if (ps.expand_all) ImGui::SetNextItemOpen(true);
  return ImGui::TreeNode(name);
}

void check_fit(PanelState& ps, const char* label, const std::string& value, float box_w) {
  const float right = ImGui::GetWindowPos().x + ImGui::GetWindowContentRegionMax().x;
  if (ImGui::GetItemRectMax().x > right + 0.5f)
    ps.layout_problems.push_back(std::string("\"") + label + "\" runs past the panel's edge");
  if (!value.empty() &&
      ImGui::CalcTextSize(value.c_str()).x + 2.0f * ImGui::GetStyle().FramePadding.x > box_w)
    ps.layout_problems.push_back(std::string("\"") + label + "\": the value \"" + value +
                                 "\" does not fit its box");
}

namespace {

bool float_widget(PanelState& ps, const char* label, float* v, int n, bool is_slider, float speed,
                  float lo, float hi, const char* format, ImGuiSliderFlags flags) {
  const float w = ImGui::CalcItemWidth();
  bool e = false;
  if (is_slider)
    e = n == 1 ? ImGui::SliderFloat(label, v, lo, hi, format, flags)
               : ImGui::SliderFloat3(label, v, lo, hi, format, flags);
  else
    e = n == 1 ? ImGui::DragFloat(label, v, speed, lo, hi, format, flags)
               : ImGui::DragFloat3(label, v, speed, lo, hi, format, flags);
  // The value of largest magnitude has the longest text; three values share the width.
  float widest = v[0];
  for (int i = 1; i < n; ++i) widest = std::fabs(v[i]) > std::fabs(widest) ? v[i] : widest;
  const float box = n == 1 ? w : (w - 2.0f * ImGui::GetStyle().ItemInnerSpacing.x) / 3.0f;
  check_fit(ps, label, format_float(format, widest), box);
  return e;
}

}  // namespace

bool slider(PanelState& ps, const char* label, float* v, int n, float lo, float hi,
            const char* format) {
  return float_widget(ps, label, v, n, true, 0.0f, lo, hi, format, 0);
}

bool drag(PanelState& ps, const char* label, float* v, int n, float speed, float lo, float hi,
          const char* format, ImGuiSliderFlags flags) {
  return float_widget(ps, label, v, n, false, speed, lo, hi, format, flags);
}

bool setting_widget(Workbench& wb, PanelState& ps, const char* key, const char* label, float speed,
                    const char* format, double view_hi) {
  using T = tracer::SettingType;
  const tracer::Setting* s = tracer::find_setting(key);
  if (!s) return false;
  const nlohmann::json v = s->get(wb.scene());
  nlohmann::json next = v;
  bool edited = false;
  const double hi = view_hi > 0.0 ? std::min(view_hi, s->hi) : s->hi;
  const float frame_w = ImGui::CalcItemWidth();
  switch (s->type) {
    case T::kBool: {
      bool b = v.get<bool>();
      edited = ImGui::Checkbox(label, &b);
      next = b;
      check_fit(ps, label);
      break;
    }
    case T::kChoice: {
      std::string items;
      int current = 0;
      for (size_t i = 0; i < s->choices.size(); ++i) {
        items += s->choices[i] + '\0';
        if (s->choices[i] == v.get<std::string>()) current = int(i);
      }
      edited = ImGui::Combo(label, &current, items.c_str());
      next = s->choices[size_t(current)];
      // The preview beside the arrow button (a square of the frame's height).
      check_fit(ps, label, s->choices[size_t(current)], frame_w - ImGui::GetFrameHeight());
      break;
    }
    case T::kInt: {
      int i = int(v.get<double>());
      float box = frame_w;
      if (s->effect == tracer::SettingEffect::kResize || s->hi - s->lo > 1e6) {
        edited = ImGui::InputInt(label, &i, 1, 100, ImGuiInputTextFlags_EnterReturnsTrue);
        // The text box beside the - and + buttons.
        box -= 2.0f * (ImGui::GetFrameHeight() + ImGui::GetStyle().ItemInnerSpacing.x);
      } else {
        edited = ImGui::SliderInt(label, &i, int(s->lo), int(hi));
      }
      next = i;
      check_fit(ps, label, std::to_string(i), box);
      break;
    }
    case T::kFloat: {
      float f = float(v.get<double>());
      const float step = speed > 0.0f ? speed
                         : hi < 1e30  ? float(hi - s->lo) / 200.0f
                                      : 0.01f * std::max(1.0f, std::fabs(f));
      edited = drag(ps, label, &f, 1, step, float(s->lo), float(hi), format ? format : "%.3f",
                    ImGuiSliderFlags_AlwaysClamp);
      next = f;
      break;
    }
    case T::kString: {  // a file name, taken when Enter is pressed
      char buf[512];
      std::snprintf(buf, sizeof buf, "%s", v.get<std::string>().c_str());
      edited = ImGui::InputText(label, buf, sizeof buf, ImGuiInputTextFlags_EnterReturnsTrue);
      next = std::string(buf);
      check_fit(ps, label);
      break;
    }
    case T::kVec3: {
      float f[3] = {float(v[0].get<double>()), float(v[1].get<double>()),
                    float(v[2].get<double>())};
      edited =
          drag(ps, label, f, 3, speed > 0.0f ? speed : 0.01f, 0.0f, 0.0f, format ? format : "%.3f");
      next = nlohmann::json::array({f[0], f[1], f[2]});
      break;
    }
  }
  if (ImGui::IsItemHovered()) {
    ImGui::SetTooltip("%s\n%s (--set %s%s%s)", s->help.c_str(),
                      s->unit.empty() ? "" : ("unit: " + s->unit).c_str(), s->key.c_str(),
                      s->flag.empty() ? "" : ", ", s->flag.c_str());
  }
  if (!edited || next == v) return false;
  std::string err;
  if (!wb.set(*s, next, &err)) {
    ps.status = "error: " + err;
    wb.messages.error(err);
    return false;
  }
  return true;
}

}  // namespace ui
