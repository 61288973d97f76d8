// JSON parsing that remembers the line of every value and key, so that scene messages can say
// "scene.json:12: ...". nlohmann::json keeps no positions, so a SAX handler builds the DOM while
// the input iterator tells it which line the lexer has reached.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <unordered_map>

namespace tracer {

struct JsonDocument {
  nlohmann::json root;
  // JSON pointer (RFC 6901, "/objects/3/radius") -> 1-based line. A container's value line is
  // the line of its '{' or '['.
  std::unordered_map<std::string, int> value_lines;
  std::unordered_map<std::string, int> key_lines;  // pointer of an object member -> its key's line

  // Line of the value at `pointer`, or of the closest enclosing value that has one; 0 if none.
  int line_of(const std::string& pointer) const;
  // Line of the member's key, falling back to line_of.
  int key_line(const std::string& pointer) const;
};

// Parses `text`; a syntax error or a duplicate key throws InputError("path:line: ...").
JsonDocument parse_json_with_lines(const std::string& text, const std::string& path);

// `parent` + "/" + the escaped member name or array index.
std::string json_pointer_child(const std::string& parent, const std::string& key);
std::string json_pointer_child(const std::string& parent, size_t index);

}  // namespace tracer
