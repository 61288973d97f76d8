// Errors and warnings about user input. Every message reads "path:line: problem; what was done"
// so that a user can jump to the spot; a fatal one is thrown as InputError.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "core/math.h"

namespace tracer {

struct SourceLoc {
  std::string path;
  int line = 0;  // 0 when unknown (binary files); then only the path is printed
  std::string str() const { return line > 0 ? path + ":" + std::to_string(line) : path; }
};

// A fatal problem with user input. what() is the full "path:line: problem; what was done" text.
class InputError : public std::runtime_error {
 public:
  InputError(const SourceLoc& loc, const std::string& problem,
             const std::string& action = "nothing was rendered")
      : std::runtime_error(loc.str() + ": " + problem + "; " + action) {}
};

// Collects non-fatal warnings (something in the input was wrong or dropped; --strict makes them
// errors) and notes (a choice the loader made for the user, such as a framing camera); each is
// printed once by the front end (stderr or UI).
struct Diagnostics {
  std::vector<std::string> warnings;
  std::vector<std::string> notes;
  void warn(const SourceLoc& loc, const std::string& problem, const std::string& action) {
    warnings.push_back(loc.str() + ": " + problem + "; " + action);
  }
  void note(const SourceLoc& loc, const std::string& text) {
    notes.push_back(loc.str() + ": " + text);
  }
};

// "[1, 2, 3]" for messages, with `digits` significant digits.
std::string vec3_str(vec3 v, int digits = 6);

// The closest candidate by edit distance, or "" when none is close enough to be a likely typo.
std::string did_you_mean(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace tracer
