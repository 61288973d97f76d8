// Parameter lists of pbrt-v4 directives and the per-kind warning collector.
#include "scene/pbrt_params.h"

#include <cmath>

namespace tracer {

void PbrtWarnings::warn(const SourceLoc& loc, const std::string& kind, const std::string& problem,
                        const std::string& action) {
  auto [it, added] = index_.emplace(std::make_pair(loc.path, kind), entries_.size());
  if (added) entries_.push_back({loc, problem, action, false, 0});
  entries_[it->second].count++;
}

void PbrtWarnings::note(const SourceLoc& loc, const std::string& kind, const std::string& text) {
  auto [it, added] = index_.emplace(std::make_pair(loc.path, "note: " + kind), entries_.size());
  if (added) entries_.push_back({loc, text, "", true, 0});
  entries_[it->second].count++;
}

void PbrtWarnings::flush(Diagnostics& d) {
  for (const Entry& e : entries_) {
    const std::string more =
        e.count > 1 ? " (and " + std::to_string(e.count - 1) + " more like it in this file)" : "";
    if (e.is_note)
      d.note(e.loc, e.problem + more);
    else
      d.warn(e.loc, e.problem, e.action + more);
  }
  entries_.clear();
  index_.clear();
}

PbrtParam* PbrtParams::lookup(const std::string& name) {
  known_.push_back(name);
  for (PbrtParam& p : list_)
    if (p.name == name) return &p;
  return nullptr;
}

const PbrtParam* PbrtParams::find(const std::string& name,
                                  std::initializer_list<const char*> types) {
  PbrtParam* p = lookup(name);
  if (!p) return nullptr;
  std::string expected;
  for (const char* t : types) {
    if (p->type == t) {
      p->used = true;
      return p;
    }
    expected += std::string(expected.empty() ? "" : " or ") + "\"" + t + "\"";
  }
  throw InputError(p->loc, owner_ + ": parameter " + p->decl() + " has the wrong type; \"" + name +
                               "\" takes " + expected);
}

namespace {

double one_number(const PbrtParam& p, const std::string& owner) {
  if (p.numbers.size() != 1)
    throw InputError(p.loc, owner + ": " + p.decl() + " takes one value, not " +
                                std::to_string(p.numbers.size()));
  return p.numbers[0];
}

}  // namespace

float PbrtParams::get_float(const std::string& name, float def) {
  const PbrtParam* p = find(name, {"float"});
  return p ? float(one_number(*p, owner_)) : def;
}

int PbrtParams::get_int(const std::string& name, int def) {
  const PbrtParam* p = find(name, {"integer"});
  return p ? int(one_number(*p, owner_)) : def;
}

bool PbrtParams::get_bool(const std::string& name, bool def) {
  const PbrtParam* p = find(name, {"bool"});
  if (!p) return def;
  if (p->bools.size() != 1)
    throw InputError(p->loc, owner_ + ": " + p->decl() + " takes one value");
  return p->bools[0];
}

std::string PbrtParams::get_string(const std::string& name, const std::string& def) {
  const PbrtParam* p = find(name, {"string"});
  if (!p) return def;
  if (p->strings.size() != 1)
    throw InputError(p->loc, owner_ + ": " + p->decl() + " takes one string");
  return p->strings[0];
}

const std::vector<double>* PbrtParams::get_numbers(const std::string& name, const char* type) {
  const PbrtParam* p = find(name, {type});
  return p ? &p->numbers : nullptr;
}

void PbrtParams::ignore(std::initializer_list<const char*> names) {
  for (const char* n : names) {
    known_.push_back(n);
    for (PbrtParam& p : list_)
      if (p.name == n) p.used = true;
  }
}

bool PbrtParams::has(const std::string& name) const {
  for (const PbrtParam& p : list_)
    if (p.name == name) return true;
  return false;
}

void PbrtParams::report_unused(PbrtWarnings& warnings) {
  for (PbrtParam& p : list_) {
    if (p.used) continue;
    p.used = true;
    const std::string guess = did_you_mean(p.name, known_);
    warnings.warn(p.loc, "unused " + owner_ + " " + p.name,
                  owner_ + " has no parameter " + p.decl() +
                      (guess.empty() ? "" : " (did you mean \"" + guess + "\"?)"),
                  "ignored it");
  }
}

namespace {

const std::vector<std::string>& numeric_types() {
  static const std::vector<std::string> t = {"integer", "float",  "point2", "vector2",  "point3",
                                             "vector3", "normal", "rgb",    "blackbody"};
  return t;
}

std::string canonical_type(const std::string& t) {
  if (t == "point") return "point3";
  if (t == "vector") return "vector3";
  if (t == "normal3") return "normal";
  if (t == "color") return "rgb";
  return t;
}

bool is_numeric(const std::string& t) {
  for (const std::string& n : numeric_types())
    if (n == t) return true;
  return false;
}

// Checks a parsed parameter's values against its type.
void check_values(const PbrtParam& p, const std::string& owner) {
  const std::string what = owner + ": " + p.decl();
  const size_t n = p.numbers.size() + p.strings.size() + p.bools.size();
  if (n == 0) throw InputError(p.loc, what + " has no value");
  auto kind_of_values = [&]() {
    return !p.strings.empty() ? "a string" : !p.bools.empty() ? "true/false" : "numbers";
  };
  if (is_numeric(p.type)) {
    if (p.numbers.size() != n)
      throw InputError(p.loc, what + " takes numbers, but its value holds " + kind_of_values());
    size_t group = 1;
    if (p.type == "point2" || p.type == "vector2") group = 2;
    if (p.type == "point3" || p.type == "vector3" || p.type == "normal" || p.type == "rgb")
      group = 3;
    if (n % group != 0)
      throw InputError(p.loc, what + " takes numbers in groups of " + std::to_string(group) +
                                  ", but has " + std::to_string(n));
    if (p.type == "blackbody" && n != 1)
      throw InputError(p.loc, what + " takes one temperature in kelvin");
    if (p.type == "integer") {
      for (double v : p.numbers) {
        if (v != std::floor(v) || std::fabs(v) > 2147483647.0)
          throw InputError(p.loc, what + " takes integers, but has " + std::to_string(v));
      }
    }
  } else if (p.type == "bool") {
    if (p.bools.size() != n)
      throw InputError(p.loc,
                       what + " takes true or false, but its value holds " + kind_of_values());
  } else if (p.type == "string" || p.type == "texture") {
    if (p.strings.size() != n)
      throw InputError(p.loc,
                       what + " takes quoted strings, but its value holds " + kind_of_values());
  } else if (p.type == "spectrum") {
    if (!p.bools.empty() || (!p.strings.empty() && n != 1))
      throw InputError(p.loc, what + " takes (wavelength, value) pairs or one named spectrum");
    if (p.strings.empty() && n % 2 != 0)
      throw InputError(p.loc, what + " takes (wavelength, value) pairs, but has " +
                                  std::to_string(n) + " numbers");
  }
}

void add_value(PbrtParam& p, const PbrtToken& t, const std::string& owner) {
  if (t.kind == PbrtToken::kString) {
    if (p.type == "bool" && (t.text == "true" || t.text == "false"))
      p.bools.push_back(t.text == "true");
    else
      p.strings.push_back(t.text);
  } else if (t.text == "true" || t.text == "false") {
    p.bools.push_back(t.text == "true");
  } else {
    p.numbers.push_back(pbrt_number(t, "in " + owner + " " + p.decl()));
  }
}

}  // namespace

PbrtParams parse_pbrt_params(PbrtInput& in, const std::string& owner) {
  static const std::vector<std::string> kTypes = {
      "integer", "float", "point2",   "vector2",   "point3", "vector3", "normal",  "bool", "string",
      "texture", "rgb",   "spectrum", "blackbody", "point",  "vector",  "normal3", "color"};
  std::vector<PbrtParam> list;
  while (in.peek().kind == PbrtToken::kString) {
    const PbrtToken decl = in.next();
    PbrtParam p;
    p.loc = decl.loc();
    std::vector<std::string> words;
    size_t i = 0;
    while (i < decl.text.size()) {
      while (i < decl.text.size() && (decl.text[i] == ' ' || decl.text[i] == '\t')) ++i;
      const size_t start = i;
      while (i < decl.text.size() && decl.text[i] != ' ' && decl.text[i] != '\t') ++i;
      if (i > start) words.push_back(decl.text.substr(start, i - start));
    }
    if (words.size() != 2)
      throw InputError(p.loc, owner + ": expected a parameter declaration \"type name\", found \"" +
                                  decl.text + "\"");
    bool known = false;
    for (const std::string& t : kTypes) known |= t == words[0];
    if (!known) {
      const std::string guess = did_you_mean(words[0], kTypes);
      throw InputError(p.loc, owner + ": unknown parameter type \"" + words[0] + "\" in \"" +
                                  decl.text + "\"" +
                                  (guess.empty() ? "" : " (did you mean \"" + guess + "\"?)"));
    }
    p.type = canonical_type(words[0]);
    p.name = words[1];
    for (const PbrtParam& q : list)
      if (q.name == p.name)
        throw InputError(p.loc, owner + ": parameter \"" + p.name + "\" is given twice");
    const PbrtToken v = in.next();
    if (v.kind == PbrtToken::kOpen) {
      while (true) {
        const PbrtToken t = in.next();
        if (t.kind == PbrtToken::kClose) break;
        const bool directive = t.kind == PbrtToken::kWord && !t.text.empty() &&
                               std::isalpha(static_cast<unsigned char>(t.text[0])) &&
                               t.text != "true" && t.text != "false";
        if (t.kind == PbrtToken::kEnd || t.kind == PbrtToken::kOpen || directive)
          throw InputError(
              v.loc(), owner + ": unterminated '[' of " + p.decl() + " (found " + t.describe() +
                           (t.kind == PbrtToken::kEnd ? "" : " at line " + std::to_string(t.line)) +
                           " before its ']')");
        add_value(p, t, owner);
      }
    } else if (v.kind == PbrtToken::kWord || v.kind == PbrtToken::kString) {
      add_value(p, v, owner);
    } else {
      throw InputError(v.loc(),
                       owner + ": " + p.decl() + " has no value (found " + v.describe() + ")");
    }
    check_values(p, owner);
    list.push_back(std::move(p));
  }
  return PbrtParams(std::move(list), owner);
}

}  // namespace tracer
