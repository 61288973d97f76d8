// The workbench's messages (errors, warnings, notes, results of actions), kept for the Messages
// list and its count in the status line, and handed to the window once each for stderr.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace ui {

enum class Severity { kInfo, kNote, kWarning, kError };  // kInfo: "exported out/a.png"

struct Message {
  Severity severity = Severity::kInfo;
  std::string text;  // without the "warning: " prefix
};

// "error: TEXT", "warning: TEXT", "note: TEXT", or TEXT for kInfo.
std::string to_string(const Message& m);

class MessageLog {
 public:
  void add(Severity s, std::string text) { messages_.push_back({s, std::move(text)}); }
  void error(std::string text) { add(Severity::kError, std::move(text)); }
  void warning(std::string text) { add(Severity::kWarning, std::move(text)); }
  void note(std::string text) { add(Severity::kNote, std::move(text)); }
  void info(std::string text) { add(Severity::kInfo, std::move(text)); }

  const std::vector<Message>& all() const { return messages_; }
  bool empty() const { return messages_.empty(); }
  size_t count(Severity s) const;
  // The counts for the status line: "1 error, 3 warnings", "2 notes", "" when there is nothing
  // but results of actions.
  std::string summary() const;
  // The messages added since the last call, oldest first: the window prints each one once.
  std::vector<Message> take_unreported();

 private:
  std::vector<Message> messages_;
  size_t reported_ = 0;
};

}  // namespace ui
