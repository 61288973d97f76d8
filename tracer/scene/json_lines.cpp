// Line-tracking JSON parser: a SAX handler that builds an nlohmann::json DOM and records the line
// of every key and value, fed by an iterator that counts newlines as the lexer reads.
#include "scene/json_lines.h"

#include <iterator>
#include <vector>

#include "core/diagnostics.h"

namespace tracer {

using nlohmann::json;

std::string json_pointer_child(const std::string& parent, const std::string& key) {
  std::string out = parent + "/";
  for (char c : key) {
    if (c == '~')
      out += "~0";
    else if (c == '/')
      out += "~1";
    else
      out += c;
  }
  return out;
}

std::string json_pointer_child(const std::string& parent, size_t index) {
  return parent + "/" + std::to_string(index);
}

int JsonDocument::line_of(const std::string& pointer) const {
  std::string p = pointer;
  for (;;) {
    auto it = value_lines.find(p);
    if (it != value_lines.end()) return it->second;
    auto k = key_lines.find(p);
    if (k != key_lines.end()) return k->second;
    if (p.empty()) return 0;
    p.erase(p.rfind('/'));
  }
}

int JsonDocument::key_line(const std::string& pointer) const {
  auto it = key_lines.find(pointer);
  return it != key_lines.end() ? it->second : line_of(pointer);
}

namespace {

struct LineTracker {
  int line = 1;             // line of the character the iterator points at
  int last_token_line = 1;  // line of the last non-whitespace character the lexer read
};

// The lexer dereferences each character once and then advances, so the tracker always knows the
// line of the last significant character; when a SAX event fires, that is the line of the token
// that completed it (a number's one-character lookahead is skipped when it is whitespace).
class TrackingIterator {
 public:
  using iterator_category = std::input_iterator_tag;
  using value_type = char;
  using difference_type = std::ptrdiff_t;
  using pointer = const char*;
  using reference = const char&;

  TrackingIterator(const char* p, LineTracker* t) : p_(p), t_(t) {}
  reference operator*() const {
    const char c = *p_;
    if (c != ' ' && c != '\t' && c != '\n' && c != '\r') t_->last_token_line = t_->line;
    return *p_;
  }
  TrackingIterator& operator++() {
    if (*p_ == '\n') ++t_->line;
    ++p_;
    return *this;
  }
  bool operator==(const TrackingIterator& o) const { return p_ == o.p_; }
  bool operator!=(const TrackingIterator& o) const { return p_ != o.p_; }

 private:
  const char* p_;
  LineTracker* t_;
};

class DomBuilder {
 public:
  DomBuilder(JsonDocument& doc, const LineTracker& tracker) : doc_(doc), tracker_(tracker) {}

  bool null() { return put(json(nullptr)); }
  bool boolean(bool v) { return put(json(v)); }
  bool number_integer(json::number_integer_t v) { return put(json(v)); }
  bool number_unsigned(json::number_unsigned_t v) { return put(json(v)); }
  bool number_float(json::number_float_t v, const json::string_t&) { return put(json(v)); }
  bool string(json::string_t& v) { return put(json(std::move(v))); }
  bool binary(json::binary_t& v) { return put(json::binary(std::move(v))); }
  bool start_object(std::size_t) { return open(json::object()); }
  bool start_array(std::size_t) { return open(json::array()); }
  bool end_object() { return close(); }
  bool end_array() { return close(); }
  bool key(json::string_t& k) {
    const json& parent = *stack_.back();
    const std::string ptr = json_pointer_child(pointers_.back(), k);
    if (parent.contains(k)) {
      error_line = tracker_.last_token_line;
      error =
          "duplicate key \"" + k + "\" (first on line " + std::to_string(doc_.key_line(ptr)) + ")";
      return false;
    }
    pending_key_ = k;
    doc_.key_lines[ptr] = tracker_.last_token_line;
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& ex) {
    // nlohmann's text is "[json.exception.parse_error.101] parse error at line L, column C: why";
    // keep only "why", the location is printed our way.
    // Numbers like 1e999 end up here too, as out_of_range.406 "number overflow parsing '1e999'".
    std::string what = ex.what();
    const size_t col = what.find("column ");
    if (col != std::string::npos && what.find(": ", col) != std::string::npos)
      what = what.substr(what.find(": ", col) + 2);
    else if (what.find("] ") != std::string::npos)
      what = what.substr(what.find("] ") + 2);
    error = (ex.id == 406 ? "number out of range: " : "JSON syntax error: ") + what;
    error_line = tracker_.last_token_line;
    return false;
  }

  std::string error;
  int error_line = 0;

 private:
  // Inserts v into the innermost open container (or as the root); returns where it now lives.
  json* insert(json&& v, std::string* ptr) {
    const int line = tracker_.last_token_line;
    json* at;
    if (stack_.empty()) {
      doc_.root = std::move(v);
      *ptr = "";
      at = &doc_.root;
    } else if (stack_.back()->is_array()) {
      json& arr = *stack_.back();
      *ptr = json_pointer_child(pointers_.back(), arr.size());
      arr.push_back(std::move(v));
      at = &arr.back();
    } else {
      json& obj = *stack_.back();
      *ptr = json_pointer_child(pointers_.back(), pending_key_);
      at = &(obj[pending_key_] = std::move(v));
    }
    doc_.value_lines[*ptr] = line;
    return at;
  }
  bool put(json&& v) {
    std::string ptr;
    insert(std::move(v), &ptr);
    return true;
  }
  bool open(json&& container) {
    std::string ptr;
    // Pointers into the DOM stay valid: only the innermost container grows, and std::map nodes
    // (objects) never move.
    stack_.push_back(insert(std::move(container), &ptr));
    pointers_.push_back(ptr);
    return true;
  }
  bool close() {
    stack_.pop_back();
    pointers_.pop_back();
    return true;
  }

  JsonDocument& doc_;
  const LineTracker& tracker_;
  std::vector<json*> stack_;
  std::vector<std::string> pointers_;
  std::string pending_key_;
};

}  // namespace

JsonDocument parse_json_with_lines(const std::string& text, const std::string& path) {
  JsonDocument doc;
  LineTracker tracker;
  DomBuilder builder(doc, tracker);
  const char* begin = text.data();
  const bool ok = json::sax_parse(TrackingIterator(begin, &tracker),
                                  TrackingIterator(begin + text.size(), &tracker), &builder);
  if (!ok) {
    throw InputError({path, builder.error_line > 0 ? builder.error_line : tracker.last_token_line},
                     builder.error.empty() ? "JSON syntax error" : builder.error);
  }
  return doc;
}

}  // namespace tracer
