// pbrt-v4 tokens: the rules of pbrt's own tokenizer (src/pbrt/parser.cpp, Tokenizer::Next): a
// word ends at white space, a quote or a bracket; strings may not span lines and take the
// escapes \b \f \n \r \t \\ \' \"; '#' starts a comment that runs to the end of the line.
#include "scene/pbrt_tokenizer.h"

#include <cmath>
#include <cstdlib>

namespace tracer {

std::string PbrtToken::describe() const {
  switch (kind) {
    case kEnd:
      return "the end of the file";
    case kWord:
      return text;
    case kString:
      return "\"" + text + "\"";
    case kOpen:
      return "'['";
    case kClose:
      return "']'";
  }
  return "";
}

PbrtTokenizer::PbrtTokenizer(std::string text, std::string path)
    : text_(std::move(text)), path_(std::move(path)) {}

PbrtToken PbrtTokenizer::next() {
  PbrtToken t;
  t.file = &path_;
  const size_t n = text_.size();
  while (pos_ < n) {
    const char c = text_[pos_];
    if (c == '\n') {
      ++line_;
      ++pos_;
    } else if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
      ++pos_;
    } else if (c == '#') {
      while (pos_ < n && text_[pos_] != '\n' && text_[pos_] != '\r') ++pos_;
    } else {
      break;
    }
  }
  t.line = line_;
  if (pos_ >= n) return t;
  const char c = text_[pos_];
  if (c == '[' || c == ']') {
    t.kind = c == '[' ? PbrtToken::kOpen : PbrtToken::kClose;
    t.text = std::string(1, c);
    ++pos_;
    return t;
  }
  if (c == '"') {
    t.kind = PbrtToken::kString;
    ++pos_;
    while (true) {
      if (pos_ >= n || text_[pos_] == '\n' || text_[pos_] == '\r') {
        const std::string shown = t.text.size() > 40 ? t.text.substr(0, 40) + "..." : t.text;
        throw InputError({path_, t.line},
                         "unterminated string \"" + shown + "\" (a string must close on its line)");
      }
      const char s = text_[pos_++];
      if (s == '"') break;
      if (s != '\\') {
        t.text.push_back(s);
        continue;
      }
      const char e = pos_ < n ? text_[pos_++] : '\0';
      switch (e) {
        case 'b':
          t.text.push_back('\b');
          break;
        case 'f':
          t.text.push_back('\f');
          break;
        case 'n':
          t.text.push_back('\n');
          break;
        case 'r':
          t.text.push_back('\r');
          break;
        case 't':
          t.text.push_back('\t');
          break;
        case '\\':
          t.text.push_back('\\');
          break;
        case '\'':
          t.text.push_back('\'');
          break;
        case '"':
          t.text.push_back('"');
          break;
        default:
          throw InputError({path_, t.line},
                           std::string("unknown escape \"\\") + e + "\" in a string");
      }
    }
    return t;
  }
  t.kind = PbrtToken::kWord;
  const size_t start = pos_;
  while (pos_ < n) {
    const char w = text_[pos_];
    if (w == ' ' || w == '\n' || w == '\t' || w == '\r' || w == '"' || w == '[' || w == ']' ||
        w == '\f' || w == '\v')
      break;
    ++pos_;
  }
  t.text = text_.substr(start, pos_ - start);
  return t;
}

void PbrtInput::push(std::string text, const std::string& path, const SourceLoc& from) {
  if (stack_.size() >= 32)
    throw InputError(from,
                     "Include nested more than 32 deep (does \"" + path + "\" include itself?)");
  files_.push_back(std::make_unique<PbrtTokenizer>(std::move(text), path));
  // A token already peeked belongs to the including file: it is read after the included one.
  if (has_peek_ && !stack_.empty()) {
    stack_.back().pending = std::move(peek_);
    stack_.back().has_pending = true;
    has_peek_ = false;
  }
  stack_.push_back({files_.back().get(), false, PbrtToken()});
}

PbrtToken PbrtInput::next() {
  if (has_peek_) {
    has_peek_ = false;
    return std::move(peek_);
  }
  while (!stack_.empty()) {
    Level& level = stack_.back();
    if (level.has_pending) {
      level.has_pending = false;
      return std::move(level.pending);
    }
    PbrtToken t = level.tokens->next();
    if (t.kind != PbrtToken::kEnd) return t;
    if (stack_.size() == 1) return t;  // the main file's end, with its path and last line
    stack_.pop_back();
  }
  return PbrtToken();
}

const PbrtToken& PbrtInput::peek() {
  if (!has_peek_) {
    peek_ = next();
    has_peek_ = true;
  }
  return peek_;
}

double pbrt_number(const PbrtToken& t, const std::string& context) {
  const std::string& s = t.text;
  const bool looks_numeric =
      t.kind == PbrtToken::kWord && !s.empty() &&
      (std::isdigit(static_cast<unsigned char>(s[0])) || s[0] == '-' || s[0] == '+' || s[0] == '.');
  char* end = nullptr;
  const double v = looks_numeric ? std::strtod(s.c_str(), &end) : 0.0;
  if (!looks_numeric || end == s.c_str() || *end != '\0')
    throw InputError(t.loc(), "expected a number " + context + ", found " + t.describe());
  if (!std::isfinite(v) || std::fabs(v) > 3.4e38)
    throw InputError(t.loc(), "the number " + s + " " + context + " is outside the float range");
  return v;
}

}  // namespace tracer
