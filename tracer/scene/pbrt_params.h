// pbrt-v4 parameter lists ("float radius" [ 1 ]): parsing with the declared types checked, typed
// lookups that report a parameter declared with the wrong type, unused parameters with a
// did-you-mean, and the one-warning-per-kind-per-file collector of a pbrt load.
#pragma once

#include <initializer_list>
#include <map>
#include <string>
#include <vector>

#include "scene/pbrt_tokenizer.h"

namespace tracer {

// Warnings and notes of a pbrt load, kept once per (file, kind): the first occurrence's location
// and text, and how many more there were. flush() hands them to the scene's diagnostics.
class PbrtWarnings {
 public:
  void warn(const SourceLoc& loc, const std::string& kind, const std::string& problem,
            const std::string& action);
  void note(const SourceLoc& loc, const std::string& kind, const std::string& text);
  void flush(Diagnostics& d);

 private:
  struct Entry {
    SourceLoc loc;
    std::string problem, action;
    bool is_note = false;
    int count = 0;
  };
  std::vector<Entry> entries_;
  std::map<std::pair<std::string, std::string>, size_t> index_;
};

struct PbrtParam {
  // Canonical type: integer, float, point2, vector2, point3, vector3, normal, bool, string,
  // texture, rgb, spectrum, blackbody (pbrt's aliases point, vector, normal3, color map to these).
  std::string type, name;
  std::vector<double> numbers;       // numeric types, and a spectrum's (lambda, value) pairs
  std::vector<std::string> strings;  // string, texture, a named spectrum
  std::vector<bool> bools;
  SourceLoc loc;
  bool used = false;
  std::string decl() const { return "\"" + type + " " + name + "\""; }
};

class PbrtParams {
 public:
  PbrtParams() = default;
  PbrtParams(std::vector<PbrtParam> list, std::string owner)
      : list_(std::move(list)), owner_(std::move(owner)) {}

  const std::string& owner() const { return owner_; }  // e.g. Shape "sphere", for messages
  // The parameter called `name`, or nullptr. It must be declared with one of `types`, else
  // InputError; a found parameter counts as used.
  const PbrtParam* find(const std::string& name, std::initializer_list<const char*> types);
  float get_float(const std::string& name, float def);
  int get_int(const std::string& name, int def);
  bool get_bool(const std::string& name, bool def);
  std::string get_string(const std::string& name, const std::string& def);
  // An array parameter of `type` ("integer", "float", "point3", "normal", "point2"), or nullptr.
  const std::vector<double>* get_numbers(const std::string& name, const char* type);
  // Parameters that pbrt knows and that change nothing here (a film's file name, a filter).
  void ignore(std::initializer_list<const char*> names);
  bool has(const std::string& name) const;
  // One warning for each parameter nobody looked up, with the closest name that was looked up.
  void report_unused(PbrtWarnings& warnings);

 private:
  PbrtParam* lookup(const std::string& name);
  std::vector<PbrtParam> list_;
  std::string owner_;
  std::vector<std::string> known_;
};

// Reads the parameter list after a directive's fixed arguments: "type name" value pairs for as
// long as the next token is a string. Unknown types, values of the wrong kind, bad counts (an
// rgb needs 3 numbers) and unterminated brackets throw InputError at their line.
PbrtParams parse_pbrt_params(PbrtInput& in, const std::string& owner);

}  // namespace tracer
