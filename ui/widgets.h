// The panels' widgets, each checked against the column it is drawn in: a setting of the settings
// table as a widget of its type, sliders and drags for the Material panel's fields, sections
// that a script's `expand` opens, and check_fit(), which records in PanelState::layout_problems a
// label that runs past the column or a box too narrow for its value.
#pragma once

#include <imgui.h>

#include <string>

#include "ui/panels.h"
#include "ui/workbench.h"

namespace ui {

// The label column right of every widget: the widest label a widget may have beside it
// (longer ones are shortened, with a tooltip). The panels push -label_column() as item width.
float label_column();
// The width a button labelled `label` takes on the same line after another item.
float width_beside(const char* label);

// A collapsing section or tree node; PanelState::expand_all opens it.
bool section(PanelState& ps, const char* name, ImGuiTreeNodeFlags flags = 0);
bool tree_node(PanelState& ps, const char* name);

// After a widget: records it when its label runs past the column's edge, or when its box
// (box_w wide) is too narrow for `value` (skipped when value is "").
void check_fit(PanelState& ps, const char* label, const std::string& value = "",
               float box_w = 0.0f);

// One setting of the settings table as a widget of its type, with the table's help, range and
// key as its tooltip; an edit goes through Workbench::set (the table's check, then the reset the
// setting's effect asks for). `speed` (drags) 0: a hundredth of the range or of the value;
// `view_hi` narrows a slider's range for the hand (typed values may go up to the table's).
bool setting_widget(Workbench& wb, PanelState& ps, const char* key, const char* label,
                    float speed = 0.0f, const char* format = nullptr, double view_hi = 0.0);

// n = 1 or 3 floats as a slider or a drag, checked with check_fit.
bool slider(PanelState& ps, const char* label, float* v, int n, float lo, float hi,
            const char* format);
bool drag(PanelState& ps, const char* label, float* v, int n, float speed, float lo, float hi,
          const char* format, ImGuiSliderFlags flags = 0);

}  // namespace ui
