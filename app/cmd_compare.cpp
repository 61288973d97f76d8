// `pathtracer compare`: error metrics of a test image against a reference (RMSE, relMSE as pbrt's
// MRSE, per-channel means) and optionally a false-colour difference image.
#include <iomanip>
#include <iostream>

#include "commands.h"
#include "image/image.h"

namespace app {
namespace {

struct CompareOptions {
  std::string test, ref, diff;
  bool json = false;
};

int run_compare(const CompareOptions& o) {
  try {
    const tracer::ImageRGB test = tracer::read_image(o.test);
    const tracer::ImageRGB ref = tracer::read_image(o.ref);
    const tracer::CompareResult r = tracer::compare_images(test, ref);
    if (!o.diff.empty()) tracer::write_image(o.diff, tracer::false_color_difference(test, ref));
    if (o.json) {
      std::cout << tracer::compare_to_json(r) << "\n";
    } else {
      std::cout << std::setprecision(6) << "size        " << r.width << "x" << r.height << "\n"
                << "rmse        " << r.rmse << "\n"
                << "relmse      " << r.relmse << "\n"
                << "mean test   " << r.mean_test.x << " " << r.mean_test.y << " " << r.mean_test.z
                << "\n"
                << "mean ref    " << r.mean_ref.x << " " << r.mean_ref.y << " " << r.mean_ref.z
                << "\n";
      if (r.nonfinite_test) std::cout << "nonfinite   " << r.nonfinite_test << " values in TEST\n";
      if (!o.diff.empty()) std::cout << "diff        " << o.diff << "\n";
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
  cmd.add_option("test", o->test, "Image to judge (.png, .exr)")->required()->check(CLI::ExistingFile);
  cmd.add_option("ref", o->ref, "Reference image (.png, .exr)")->required()->check(CLI::ExistingFile);
  cmd.add_flag("--json", o->json, "Print JSON");
  cmd.add_option("--diff", o->diff, "Write a false-colour relative-error image here (.png/.exr)");
  return [o] { return run_compare(*o); };
}

}  // namespace app
