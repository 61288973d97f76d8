// The settings table (scene/settings.h): every setting round-trips through the scene format, the
// sidecar and --set with the same value; a bad value gets the same message from every entry point
// (scene file, flag, --set, workbench); unknown keys list the valid ones; the docs' tables are
// the table's.
#include "scene/settings.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "integrator/sidecar.h"
#include "materials/metals.h"
#include "scene/loader.h"
#include "test_util.h"
#include "ui/workbench.h"

namespace {

using nlohmann::json;
using tracer::Setting;
using tracer::SettingType;

const char* kObjects =
    R"("materials": {"m": {}}, "objects": [{"type": "sphere", "radius": 1, "material": "m"}])";

// A valid value of `s` that differs from its default, in the scene format. Vectors differ per
// key so that the camera stays valid (position, look_at and up not parallel).
json other_value(const Setting& s, int index) {
  const json def = s.get(tracer::Scene());
  switch (s.type) {
    case SettingType::kBool:
      return !def.get<bool>();
    case SettingType::kChoice:
      for (const std::string& c : s.choices)
        if (c != def.get<std::string>()) return c;
      return def;
    case SettingType::kInt: {
      const double v = def.get<double>() == s.lo ? s.lo + 1 : s.lo;
      return v;
    }
    case SettingType::kFloat: {
      const double hi = std::min(s.hi, s.lo + 10.0);
      double v = s.lo + 0.375 * (hi - s.lo);
      if (v == def.get<double>()) v = s.lo + 0.625 * (hi - s.lo);
      return v;
    }
    case SettingType::kVec3:
      return json::array({0.5, 1.25, 3.0 + index});
    case SettingType::kString:  // a file the load hook reads (absolute: scene files keep them so)
      return test::data_dir() + "/env/sky_16x8.pfm";
  }
  return def;
}

// The value as --set spells it.
std::string as_text(const Setting& s, const json& v) {
  switch (s.type) {
    case SettingType::kBool:
      return v.get<bool>() ? "on" : "off";
    case SettingType::kChoice:
    case SettingType::kString:
      return v.get<std::string>();
    case SettingType::kVec3: {
      std::ostringstream o;
      o << v[0].get<double>() << "," << v[1].get<double>() << "," << v[2].get<double>();
      return o.str();
    }
    default: {
      std::ostringstream o;
      o << v.get<double>();
      return o.str();
    }
  }
}

// The expected values: every setting at other_value(), as the scene format's sections.
json all_changed() {
  json sections = json::object();
  int i = 0;
  for (const Setting& s : tracer::settings_table())
    sections[s.section()][s.name()] = other_value(s, i++);
  return sections;
}

tracer::Scene load_sections(const json& sections) {
  std::string text = "{";
  for (auto it = sections.begin(); it != sections.end(); ++it)
    text += "\"" + it.key() + "\": " + it.value().dump() + ", ";
  text += std::string(kObjects) + "}";
  return tracer::load_scene_from_json(text, "settings_test.json");
}

// Compares two scenes setting by setting (floats as floats: the scene holds 32-bit values).
void expect_same_settings(const tracer::Scene& a, const json& expected, const std::string& via) {
  for (const Setting& s : tracer::settings_table()) {
    const json got = s.get(a), want = expected[s.section()][s.name()];
    if (s.type == SettingType::kFloat) {
      EXPECT_EQ(float(got.get<double>()), float(want.get<double>())) << s.key << " via " << via;
    } else if (s.type == SettingType::kVec3) {
      for (size_t i = 0; i < 3; ++i)
        EXPECT_EQ(float(got[i].get<double>()), float(want[i].get<double>()))
            << s.key << " via " << via;
    } else if (s.type == SettingType::kInt) {
      EXPECT_EQ(got.get<double>(), want.get<double>()) << s.key << " via " << via;
    } else {
      EXPECT_EQ(got, want) << s.key << " via " << via;
    }
  }
}

TEST(Settings, TableIsWellFormed) {
  std::vector<std::string> keys, flags;
  for (const Setting& s : tracer::settings_table()) {
    EXPECT_EQ(std::count(keys.begin(), keys.end(), s.key), 0) << "duplicate key " << s.key;
    keys.push_back(s.key);
    if (!s.flag.empty()) {
      EXPECT_EQ(std::count(flags.begin(), flags.end(), s.flag), 0) << "duplicate flag " << s.flag;
      EXPECT_EQ(s.flag.rfind("--", 0), 0u) << s.flag;
      flags.push_back(s.flag);
    }
    EXPECT_FALSE(s.help.empty()) << s.key;
    // The default is valid and prints in the --set language, which reads back.
    const json def = s.get(tracer::Scene());
    EXPECT_EQ(tracer::check_setting(s, def), "") << s.key;
    json parsed;
    EXPECT_EQ(tracer::parse_setting_text(s, tracer::setting_default_text(s), &parsed), "") << s.key;
    EXPECT_NE(other_value(s, 0), def) << s.key << ": the test needs a second valid value";
  }
  EXPECT_GE(keys.size(), 30u);
}

TEST(Settings, EverySettingRoundTripsSceneFileToSidecarToSceneFile) {
  const json expected = all_changed();
  const tracer::Scene loaded = load_sections(expected);
  expect_same_settings(loaded, expected, "scene file");
  // The sidecar's sections are scene-file sections: they load back to the same values.
  tracer::SidecarRun run;
  run.output = "x.png";
  const json side = tracer::make_sidecar(loaded, run);
  json sections = json::object();
  for (const char* sec : {"camera", "render", "gpu", "display", "environment"}) {
    ASSERT_TRUE(side.contains(sec)) << sec;
    sections[sec] = side[sec];
  }
  expect_same_settings(load_sections(sections), expected, "scene file -> sidecar -> scene file");
}

TEST(Settings, EverySettingRoundTripsSetToSidecar) {
  const json expected = all_changed();
  tracer::Scene scene = tracer::builtin_default_scene();
  for (const Setting& s : tracer::settings_table()) {
    const std::string a = s.key + "=" + as_text(s, expected[s.section()][s.name()]);
    EXPECT_EQ(tracer::set_setting_assignment(scene, a), "") << a;
  }
  expect_same_settings(scene, expected, "--set");
  tracer::SidecarRun run;
  const json side = tracer::make_sidecar(scene, run);
  json sections;
  for (const char* sec : {"camera", "render", "gpu", "display", "environment"})
    sections[sec] = side[sec];
  expect_same_settings(load_sections(sections), expected, "--set -> sidecar -> scene file");
}

// The same through the executable: every flag and --set of `render`, then its sidecar.
TEST(Settings, RenderCommandRecordsEverySettingItWasGiven) {
  json expected = all_changed();
  // What this run needs to be quick and to run here.
  expected["render"]["width"] = 8;
  expected["render"]["height"] = 6;
  expected["render"]["spp"] = 2;
  expected["render"]["time_limit_s"] = 0.0;
  expected["render"]["backend"] = "cpu";
  expected["render"]["threads"] = 1;
  expected["render"]["max_depth"] = 3;
  // These settings render a black image, a warning that --strict would make fatal (the flag
  // itself is tested in first_contact_test).
  expected["render"]["strict"] = false;
  const std::string out = testing::TempDir() + "/settings_cli.png";
  std::string cmd = test::pathtracer_exe() + " render -q --out " + out;
  bool use_flag = true;
  for (const Setting& s : tracer::settings_table()) {
    if (s.key == "render.samples_per_frame") continue;  // the workbench's only
    if (s.key == "render.time_limit_s") continue;       // --spp and --time exclude each other
    const std::string v = as_text(s, expected[s.section()][s.name()]);
    // Alternate between the flag and --set where a setting has both.
    if (s.bare_flag && v == "on" && use_flag)
      cmd += " " + s.flag;  // a flag without a value (--strict)
    else if (!s.flag.empty() && !s.bare_flag && use_flag)
      cmd += " " + s.flag + " '" + v + "'";
    else
      cmd += " --set '" + s.key + "=" + v + "'";
    use_flag = !use_flag;
  }
  std::string log;
  ASSERT_EQ(test::run_command(cmd, &log), 0) << cmd << "\n" << log;
  std::ifstream f(out + ".json");
  const json side = json::parse(f);
  expected["render"]["samples_per_frame"] = 0;  // not given: the default
  for (const char* sec : {"camera", "render", "gpu", "display", "environment"}) {
    for (auto it = expected[sec].begin(); it != expected[sec].end(); ++it) {
      const json got = side[sec][it.key()];
      if (it.value().is_number()) {
        EXPECT_FLOAT_EQ(float(got.get<double>()), float(it.value().get<double>()))
            << sec << "." << it.key();
      } else if (it.value().is_array()) {
        for (size_t i = 0; i < 3; ++i)
          EXPECT_FLOAT_EQ(float(got[i].get<double>()), float(it.value()[i].get<double>()))
              << sec << "." << it.key();
      } else {
        EXPECT_EQ(got, it.value()) << sec << "." << it.key();
      }
    }
  }
}

// Values each numeric setting refuses, as the user types them.
std::vector<std::string> bad_texts(const Setting& s) {
  std::vector<std::string> out = {"nan", "inf", "-inf"};
  auto text = [](double d) {
    std::ostringstream o;
    o.precision(12);
    o << d;
    return o.str();
  };
  if (s.hi < 1e30)
    out.push_back(text(s.hi + 1));
  else
    out.push_back("1e39");
  if (s.lo > -1e30) out.push_back(text(s.lo - 1));
  if (s.type == SettingType::kInt) out.push_back(text(s.lo + 0.5));
  return out;
}

std::string load_error(const std::string& text) {
  try {
    tracer::load_scene_from_json(text, "bad.json");
  } catch (const tracer::InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Settings, BadValuesGetTheSameMessageFromEveryEntryPoint) {
  tracer::Scene base = tracer::builtin_default_scene();
  ui::Workbench wb(base, tracer::BackendChoice::kCpu, 1);
  int checked = 0;
  for (const Setting& s : tracer::settings_table()) {
    if (s.type != SettingType::kInt && s.type != SettingType::kFloat) continue;
    for (const std::string& bad : bad_texts(s)) {
      SCOPED_TRACE(s.key + " = " + bad);
      // The table's own words for it.
      json ignored;
      const std::string msg = tracer::parse_setting_text(s, bad, &ignored);
      ASSERT_NE(msg, "");
      EXPECT_NE(msg.find("\"" + s.key + "\""), std::string::npos) << msg;
      // --set, on any command.
      tracer::Scene scene = base;
      EXPECT_EQ(tracer::set_setting_assignment(scene, s.key + "=" + bad), msg);
      // The workbench.
      std::string err;
      EXPECT_FALSE(wb.apply(s.key + "=" + bad, &err));
      EXPECT_NE(err.find(msg), std::string::npos) << err;
      // A scene file (JSON has no NaN or infinity: only the numbers).
      if (bad.find("inf") == std::string::npos && bad != "nan") {
        const std::string e = load_error("{\"" + s.section() + "\": {\"" + s.name() + "\": " + bad +
                                         "}, " + kObjects + "}");
        EXPECT_NE(e.find("bad.json:1: " + msg), std::string::npos) << e;
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 60);
}

TEST(Settings, FlagsGiveTheTablesMessage) {
  // One run per flag: the command refuses the value before rendering, with the table's words.
  for (const Setting& s : tracer::settings_table()) {
    if (s.flag.empty() || s.bare_flag) continue;  // a bare flag takes no value to refuse
    if (s.type == SettingType::kString) {         // any text parses; the load hook refuses the file
      std::string log;
      EXPECT_EQ(test::run_command(test::pathtracer_exe() + " render -q " + s.flag +
                                      " no_such_map.hdr --out " + testing::TempDir() + "/never.png",
                                  &log),
                2)
          << log;
      EXPECT_NE(log.find(s.flag + " no_such_map.hdr: no_such_map.hdr: no such file"),
                std::string::npos)
          << log;
      continue;
    }
    const std::string bad = s.type == SettingType::kBool     ? "maybe"
                            : s.type == SettingType::kChoice ? "bogus"
                            : s.hi < 1e30                    ? std::to_string(s.hi + 1)
                                                             : "nan";
    json ignored;
    const std::string msg = tracer::parse_setting_text(s, bad, &ignored);
    std::string log;
    EXPECT_EQ(test::run_command(test::pathtracer_exe() + " render -q " + s.flag + " " + bad +
                                    " --out " + testing::TempDir() + "/never.png",
                                &log),
              2)
        << s.flag << " " << bad << "\n"
        << log;
    EXPECT_NE(log.find(s.flag + " " + bad + ": " + msg), std::string::npos) << log;
  }
}

TEST(Settings, UnknownKeysListTheValidOnesAndGuess) {
  tracer::Scene scene = tracer::builtin_default_scene();
  const std::string m = tracer::set_setting_assignment(scene, "render.max_dpth=3");
  EXPECT_NE(m.find("did you mean \"render.max_depth\""), std::string::npos) << m;
  EXPECT_NE(m.find("gpu.kernel"), std::string::npos) << m;  // the valid keys are listed
  EXPECT_NE(m.find("materials.NAME.albedo"), std::string::npos) << m;
  const std::string e =
      load_error(std::string("{\"render\": {\n\"spp\": 4,\n\"max_dpth\": 3}, ") + kObjects + "}");
  EXPECT_NE(e.find("bad.json:3: unknown setting \"max_dpth\""), std::string::npos) << e;
  EXPECT_NE(e.find("did you mean \"max_depth\""), std::string::npos) << e;
  EXPECT_NE(e.find("rr_start_depth"), std::string::npos) << e;
  ui::Workbench wb(scene, tracer::BackendChoice::kCpu, 1);
  std::string err;
  EXPECT_FALSE(wb.apply("gpu.kernal=wavefront", &err));
  EXPECT_NE(err.find("did you mean \"gpu.kernel\""), std::string::npos) << err;
}

// The docs' tables of settings are generated from the table; TRACER_UPDATE_DOCS=1 rewrites them.
TEST(Settings, DocsTablesAreTheTable) {
  const std::string begin =
      "<!-- settings-table:begin (generated from tracer/scene/settings.cpp by "
      "tests/settings_test.cpp; TRACER_UPDATE_DOCS=1 rewrites it) -->\n";
  const std::string end = "<!-- settings-table:end -->";
  const std::string table = tracer::settings_markdown();
  for (const char* doc : {"docs/CLI.md", "docs/SCENE_FORMAT.md"}) {
    const std::string path = test::source_dir() + "/" + doc;
    std::ifstream f(path);
    ASSERT_TRUE(f.good()) << path;
    std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    const size_t a = text.find(begin), b = text.find(end);
    ASSERT_NE(a, std::string::npos) << doc << " has no generated settings table";
    ASSERT_NE(b, std::string::npos) << doc;
    const std::string current = text.substr(a + begin.size(), b - a - begin.size());
    if (current != table && std::getenv("TRACER_UPDATE_DOCS")) {
      text = text.substr(0, a + begin.size()) + table + text.substr(b);
      std::ofstream(path) << text;
      continue;
    }
    EXPECT_EQ(current, table) << doc << " is out of date: run TRACER_UPDATE_DOCS=1 "
                              << "build/tests/settings_test --gtest_filter=*Docs*";
  }
}

}  // namespace

// The material fields of issue 21's materials: --set (and so the workbench) edits them with the
// same checks as the scene format, and material_to_json (the sidecar, Save scene) writes what
// the scene format reads back to the same material.
TEST(Settings, NewMaterialFieldsSetAndRoundTrip) {
  using tracer::Material;
  using tracer::MaterialType;
  tracer::Scene scene = tracer::builtin_default_scene();
  auto set = [&](const std::string& a) { return tracer::set_material_assignment(scene, a); };
  auto white = [&]() -> Material& {
    return scene.materials[scene.find_material("white")].material;
  };
  EXPECT_EQ(set("materials.white.metal=Cu"), "");
  EXPECT_EQ(white().type, MaterialType::kConductor);
  EXPECT_TRUE(white().flags & tracer::kMaterialConductorIor);
  EXPECT_EQ(white().albedo, tracer::vec3(1.0f));  // the diffuse colour does not tint the metal
  EXPECT_EQ(white().eta, tracer::find_metal("Cu")->eta);
  EXPECT_EQ(set("materials.white.roughness=0.2,0.6"), "");
  EXPECT_TRUE(white().is_anisotropic());
  EXPECT_EQ(set("materials.white.k=3,2.5,2"), "");
  EXPECT_EQ(white().k, tracer::vec3(3.0f, 2.5f, 2.0f));
  EXPECT_NE(set("materials.white.eta=0,1,1").find("> 0"), std::string::npos);
  EXPECT_NE(set("materials.white.metal=Gld").find("unknown metal"), std::string::npos);
  EXPECT_NE(set("materials.white.metal=Auu").find("did you mean \"Au\""), std::string::npos);
  EXPECT_NE(set("materials.white.roughness=0.2,1.5").find("[0, 1]"), std::string::npos);
  const json metal = tracer::material_to_json(white());
  EXPECT_EQ(metal["roughness"], json::array({0.2, 0.6}));
  EXPECT_TRUE(metal.contains("eta") && metal.contains("k")) << metal.dump();

  EXPECT_EQ(set("materials.red.type=plastic"), "");
  EXPECT_EQ(set("materials.red.thickness=0.25"), "");
  EXPECT_EQ(set("materials.red.absorption=0.5,0,0"), "");
  EXPECT_EQ(set("materials.red.roughness=0.3"), "");
  EXPECT_NE(set("materials.red.roughness=0.3,0.4").find("only conductors"), std::string::npos);
  EXPECT_EQ(set("materials.green.type=diffuse_transmission"), "");
  EXPECT_EQ(set("materials.green.transmittance=0.4,0.5,0.6"), "");
  EXPECT_NE(set("materials.green.transmittance=2,0,0").find("<= 1"), std::string::npos);
  EXPECT_NE(set("materials.green.type=glas").find("coated_diffuse"), std::string::npos);
  EXPECT_NE(set("materials.green.thicknes=1").find("did you mean \"thickness\""),
            std::string::npos);

  // Written and read back: the same materials.
  json mats = json::object();
  for (const char* name : {"white", "red", "green"})
    mats[name] = tracer::material_to_json(scene.materials[scene.find_material(name)].material);
  const tracer::Scene back = tracer::load_scene_from_json(
      "{\"materials\": " + mats.dump() +
          ", \"objects\": [{\"type\": \"sphere\", \"radius\": 1, \"material\": \"white\"}]}",
      testing::TempDir() + "/materials.json");
  for (const char* name : {"white", "red", "green"}) {
    SCOPED_TRACE(name);
    const Material& a = scene.materials[scene.find_material(name)].material;
    const Material& b = back.materials[back.find_material(name)].material;
    EXPECT_EQ(a.type, b.type);
    EXPECT_EQ(a.flags, b.flags);
    EXPECT_EQ(a.albedo, b.albedo);
    EXPECT_EQ(a.roughness, b.roughness);
    EXPECT_EQ(a.type == MaterialType::kConductor ? a.roughness_v : -1.0f, b.roughness_v);
    if (a.flags & tracer::kMaterialConductorIor) {
      EXPECT_EQ(a.eta, b.eta);
      EXPECT_EQ(a.k, b.k);
    }
    if (a.type == MaterialType::kCoatedDiffuse) {
      EXPECT_EQ(a.ior, b.ior);
      EXPECT_EQ(a.absorption, b.absorption);
      EXPECT_EQ(a.thickness, b.thickness);
    }
    if (a.type == MaterialType::kDiffuseTransmission) EXPECT_EQ(a.transmittance, b.transmittance);
  }
}
