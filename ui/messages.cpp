// The workbench's message log: counts for the status line and the stderr hand-off.
#include "ui/messages.h"

namespace ui {

std::string to_string(const Message& m) {
  switch (m.severity) {
    case Severity::kError:
      return "error: " + m.text;
    case Severity::kWarning:
      return "warning: " + m.text;
    case Severity::kNote:
      return "note: " + m.text;
    case Severity::kInfo:
      break;
  }
  return m.text;
}

size_t MessageLog::count(Severity s) const {
  size_t n = 0;
  for (const Message& m : messages_) n += m.severity == s ? 1 : 0;
  return n;
}

std::string MessageLog::summary() const {
  std::string out;
  auto part = [&](Severity s, const char* one, const char* many) {
    const size_t n = count(s);
    if (n == 0) return;
    if (!out.empty()) out += ", ";
    out += std::to_string(n) + " " + (n == 1 ? one : many);
  };
  part(Severity::kError, "error", "errors");
  part(Severity::kWarning, "warning", "warnings");
  part(Severity::kNote, "note", "notes");
  return out;
}

std::vector<Message> MessageLog::take_unreported() {
  std::vector<Message> fresh(messages_.begin() + long(reported_), messages_.end());
  reported_ = messages_.size();
  return fresh;
}

}  // namespace ui
