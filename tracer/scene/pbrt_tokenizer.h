// The pbrt-v4 scene tokenizer: words (directives, numbers, true/false), quoted strings and
// brackets, each with the file and line it came from; comments (# to the end of the line) are
// skipped. Include'd files are a stack of tokenizers (PbrtInput).
#pragma once

#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "core/diagnostics.h"

namespace tracer {

struct PbrtToken {
  enum Kind { kEnd, kWord, kString, kOpen, kClose };
  Kind kind = kEnd;
  std::string text;                   // the word, or the string with its escapes decoded
  const std::string* file = nullptr;  // owned by the tokenizer, which outlives the load
  int line = 0;

  SourceLoc loc() const { return {file ? *file : std::string(), line}; }
  // For messages: "Shape", "\"diffuse\"", "'['", "the end of the file".
  std::string describe() const;
};

class PbrtTokenizer {
 public:
  PbrtTokenizer(std::string text, std::string path);
  // The next token; kEnd at the end. An unterminated string or a bad escape throws InputError.
  PbrtToken next();
  const std::string& path() const { return path_; }

 private:
  std::string text_, path_;
  size_t pos_ = 0;
  int line_ = 1;
};

// The tokens of a file and of the files it includes, in reading order.
class PbrtInput {
 public:
  explicit PbrtInput(std::string main_path) : main_path_(std::move(main_path)) {}
  // Starts reading `text` (the contents of `path`) before whatever comes next; `from` is the
  // Include directive (for messages). Nesting is limited to 32 levels (a file including itself).
  void push(std::string text, const std::string& path, const SourceLoc& from);
  PbrtToken next();
  const PbrtToken& peek();
  const std::string& main_path() const { return main_path_; }

 private:
  std::string main_path_;
  std::deque<std::unique_ptr<PbrtTokenizer>> files_;  // every file read, kept for token paths
  struct Level {
    PbrtTokenizer* tokens;
    bool has_pending;  // a token of this file peeked before an Include
    PbrtToken pending;
  };
  std::vector<Level> stack_;
  bool has_peek_ = false;
  PbrtToken peek_;
};

// Parses a word token as a number: finite and within float range, else InputError at the token.
double pbrt_number(const PbrtToken& t, const std::string& context);

}  // namespace tracer
