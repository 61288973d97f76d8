// `pathtracer compare`: error metrics of a test image against a reference (RMSE, relMSE as pbrt's
// MRSE, per-channel means, mean LDR-FLIP) and optionally a false-colour difference image and a
// FLIP error map.
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <iostream>

#include "commands.h"
#include "settings_cli.h"
#include "image/flip.h"
#include "image/image.h"

namespace app {
namespace {

struct CompareOptions {
  std::string test, ref, diff, flip_map;
  double ppd = tracer::kFlipDefaultPpd;
  float flip_exposure = 0.0f;
  bool json = false;
};

// JSON has no NaN/Inf (the mean of an empty image is NaN), so those are null.
std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

// compare_to_json's object with the FLIP figures added before its closing brace.
std::string with_flip(std::string json, const tracer::FlipResult& flip, const CompareOptions& o) {
  json.insert(json.rfind('}'), ",\"flip\":" + json_number(flip.mean) +
                                   ",\"flip_ppd\":" + json_number(o.ppd) +
                                   ",\"flip_exposure\":" + json_number(o.flip_exposure));
  return json;
}

int run_compare(const CompareOptions& o) {
  try {
    const tracer::ImageRGB test = tracer::read_image(o.test);
    const tracer::ImageRGB ref = tracer::read_image(o.ref);
    const tracer::CompareResult r = tracer::compare_images(test, ref);
    const tracer::FlipResult flip = tracer::ldr_flip(test, ref, o.ppd, o.flip_exposure);
    if (!o.diff.empty()) tracer::write_image(o.diff, tracer::false_color_difference(test, ref));
    if (!o.flip_map.empty()) tracer::write_image(o.flip_map, tracer::flip_error_map(flip));
    if (o.json) {
      std::cout << with_flip(tracer::compare_to_json(r), flip, o) << "\n";
    } else {
      std::cout << std::setprecision(6) << "size        " << r.width << "x" << r.height << "\n"
                << "rmse        " << r.rmse << "\n"
                << "relmse      " << r.relmse << "\n"
                << "flip        " << flip.mean << "  (LDR-FLIP, " << o.ppd << " ppd, exposure "
                << o.flip_exposure << ")\n"
                << "mean test   " << r.mean_test.x << " " << r.mean_test.y << " " << r.mean_test.z
                << "\n"
                << "mean ref    " << r.mean_ref.x << " " << r.mean_ref.y << " " << r.mean_ref.z
                << "\n";
      if (r.nonfinite_test) std::cout << "nonfinite   " << r.nonfinite_test << " values in TEST\n";
      if (!o.diff.empty()) std::cout << "diff        " << o.diff << "\n";
      if (!o.flip_map.empty()) std::cout << "flip map    " << o.flip_map << "\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInputError;
  }
  return 0;
}

}  // namespace

Runner add_compare_command(CLI::App& cmd) {
  auto o = std::make_shared<CompareOptions>();
  cmd.add_option("test", o->test, "Image to judge (.png, .exr)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd.add_option("ref", o->ref, "Reference image (.png, .exr)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd.add_flag("--json", o->json, "Print JSON");
  cmd.add_option("--diff", o->diff, "Write a false-colour relative-error image here (.png/.exr)");
  cmd.add_option(
      "--flip-map", o->flip_map,
      "Write the per-pixel LDR-FLIP error through the magma colour map here (.png/.exr)");
  cmd.add_option("--ppd", o->ppd,
                 "FLIP's pixels per degree of visual angle (default: a 0.7 m wide 4K monitor "
                 "seen from 0.7 m)")
      ->check(finite_number() & CLI::Range(0.1, 10000.0))
      ->capture_default_str();
  cmd.add_option("--flip-exposure", o->flip_exposure,
                 "Exposure in stops applied to both images before FLIP clamps them to [0, 1]")
      ->check(finite_number() & CLI::Range(-20.0, 20.0))
      ->capture_default_str();
  return [o] { return run_compare(*o); };
}

}  // namespace app
