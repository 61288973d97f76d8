// `pathtracer compare`: error metrics of a test image against a reference (RMSE, relMSE as pbrt's
// MRSE, per-channel means, mean LDR-FLIP), optionally per region (a grid) with a test of whether
// each region differs by more than the images' noise, over the pixels a mask and rectangles keep;
// and a false-colour difference image and a FLIP error map.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "core/diagnostics.h"
#include "image/flip.h"
#include "image/image.h"
#include "image/region_stats.h"
#include "image/regions.h"
#include "settings_cli.h"

namespace app {
namespace {

struct CompareOptions {
  std::string test, ref, diff, flip_map;
  std::string test2, test_variance, ref2, ref_variance, grid, mask;
  std::vector<std::string> excludes;
  double ppd = tracer::kFlipDefaultPpd;
  float flip_exposure = 0.0f;
  double significance = 0.01;
  bool json = false, fail_on_difference = false;
};

// Everything a comparison reads, and how the test and reference images were made of it.
struct Inputs {
  tracer::NoisyImage test, ref;
  tracer::PixelMask mask;
  // NaN/Inf pixels of each file among the kept ones (the region statistics leave them out).
  std::vector<std::pair<std::string, long>> nonfinite;
};

long nonfinite_pixels(const tracer::ImageRGB& img, const tracer::PixelMask& m) {
  long n = 0;
  for (size_t i = 0; i < m.keep.size(); ++i) {
    const float* p = &img.pixels[3 * i];
    if (m.keep[i] && !(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) ++n;
  }
  return n;
}

Inputs read_inputs(const CompareOptions& o) {
  Inputs in;
  const tracer::ImageRGB test = tracer::read_image(o.test);
  const int w = test.width, h = test.height;
  in.mask = tracer::full_mask(w, h);
  if (!o.mask.empty()) tracer::apply_mask_image(&in.mask, tracer::read_image(o.mask), o.mask);
  for (const std::string& text : o.excludes) {
    tracer::PixelRect r;
    tracer::parse_rect(text, &r);  // checked by the option's validator
    tracer::apply_exclude_rect(&in.mask, r);
  }
  auto read = [&](const std::string& path) {
    tracer::ImageRGB img = tracer::read_image(path);
    tracer::require_same_size(img, path, w, h, o.test);
    in.nonfinite.emplace_back(path, nonfinite_pixels(img, in.mask));
    return img;
  };
  in.nonfinite.emplace_back(o.test, nonfinite_pixels(test, in.mask));
  if (!o.test2.empty()) {
    in.test = tracer::noisy_from_pair(test, read(o.test2), o.test, o.test2);
  } else if (!o.test_variance.empty()) {
    in.test = tracer::noisy_with_variance(test, read(o.test_variance), o.test, o.test_variance);
  } else {
    in.test = tracer::noisy_without_variance(test);
  }
  const tracer::ImageRGB ref = read(o.ref);
  if (!o.ref2.empty()) {
    in.ref = tracer::noisy_from_pair(ref, read(o.ref2), o.ref, o.ref2);
  } else if (!o.ref_variance.empty()) {
    in.ref = tracer::noisy_with_variance(ref, read(o.ref_variance), o.ref, o.ref_variance);
  } else {
    in.ref = tracer::noisy_without_variance(ref);
  }
  return in;
}

// The regions asked for: the grid, else the whole image when there is noise to test against;
// none (false) for a plain comparison. An object-ID image would be one more source here.
bool make_regions(const CompareOptions& o, const Inputs& in, tracer::RegionMap* map) {
  const int w = in.test.mean.width, h = in.test.mean.height;
  if (!o.grid.empty()) {
    int columns = 0, rows = 0;
    tracer::parse_grid(o.grid, &columns, &rows);  // checked by the option's validator
    *map = tracer::grid_regions(w, h, columns, rows);
    return true;
  }
  if (in.test.has_variance()) {
    *map = tracer::whole_image_region(w, h);
    return true;
  }
  return false;
}

// FLIP is a spatial filter over the whole image; only its mean is restricted to kept pixels.
double masked_flip_mean(const tracer::FlipResult& flip, const tracer::PixelMask& m) {
  double sum = 0.0;
  long n = 0;
  for (size_t i = 0; i < flip.per_pixel.size(); ++i) {
    if (!m.keep[i]) continue;
    sum += flip.per_pixel[i];
    ++n;
  }
  return n > 0 ? sum / n : std::nan("");
}

// Below this many degrees of freedom a region's test gets a note: in the measurements of
// tests/compare_test.cpp the false alarms then run up to twice the significance.
constexpr double kFewDof = 30.0;

std::string fmt(const char* f, double v) {
  if (std::isnan(v)) return "-";
  char buf[48];
  std::snprintf(buf, sizeof(buf), f, v);
  return buf;
}

// Three per-channel values, each right-aligned in `width` characters.
std::string triple(const tracer::ChannelStats* ch, double tracer::ChannelStats::*field,
                   const char* f, int width, double scale = 1.0, double offset = 0.0) {
  std::string out;
  for (int c = 0; c < 3; ++c) {
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%*s", width, fmt(f, (ch[c].*field + offset) * scale).c_str());
    out += buf;
  }
  return out;
}

void print_regions(const tracer::RegionMap& map, const tracer::RegionComparison& c) {
  std::printf("\nregions     %s, %zu regions\n", map.source.c_str(), map.regions.size());
  if (c.test_noise) {
    std::printf("noise       test: %s; reference: %s\n", c.test_noise_source.c_str(),
                c.ref_noise ? c.ref_noise_source.c_str() : "treated as exact");
    std::printf("significance %g over %d tests (regions x channels; Sidak: p < %.3g per test)\n",
                c.significance, c.tests, c.per_test);
    std::vector<double> rel;  // noise of each region mean relative to the reference mean
    for (const tracer::RegionStats& r : c.regions)
      for (const tracer::ChannelStats& ch : r.channel)
        if (r.pixels > 0 && ch.mean_ref > 0) rel.push_back(ch.sigma / ch.mean_ref);
    if (!rel.empty()) {
      std::sort(rel.begin(), rel.end());
      std::printf(
          "sigma       median %.3g%%, largest %.3g%% of the region's reference mean (standard "
          "error of the difference of the means)\n",
          100 * rel[rel.size() / 2], 100 * rel.back());
    }
  } else {
    std::printf("noise       unknown: --test2 or --test-variance gives each region a z-score\n");
  }
  std::printf("\n%-8s %-19s %7s %27s %27s %24s %21s %9s\n", "region", "box", "pixels",
              "test mean (r g b)", "ref mean (r g b)", "test/ref - 1, % (r g b)",
              c.test_noise ? "z (r g b)" : "", "relMSE");
  for (size_t k = 0; k < c.regions.size(); ++k) {
    const tracer::RegionStats& r = c.regions[k];
    const tracer::RegionMap::Region& reg = map.regions[k];
    const tracer::ChannelStats* ch = r.channel;
    std::printf("%-8s %-19s %7ld %s %s %s %s %9s%s\n", reg.name.c_str(), reg.box.str().c_str(),
                r.pixels, triple(ch, &tracer::ChannelStats::mean_test, "%.4g", 9).c_str(),
                triple(ch, &tracer::ChannelStats::mean_ref, "%.4g", 9).c_str(),
                triple(ch, &tracer::ChannelStats::ratio, "%+.2f", 8, 100.0, -1.0).c_str(),
                c.test_noise ? triple(ch, &tracer::ChannelStats::z, "%+.1f", 7).c_str()
                             : std::string(21, ' ').c_str(),
                fmt("%.3g", r.relmse).c_str(), r.differs ? "  DIFFERS" : "");
  }
  if (!c.test_noise) return;
  // Few degrees of freedom: the noise estimate rests on a few pixels (fireflies, or a small
  // region), and the test, approximate there, errs towards flagging (docs/CLI.md).
  std::string few;
  for (size_t k = 0; k < c.regions.size(); ++k) {
    double dof = INFINITY;
    for (const tracer::ChannelStats& ch : c.regions[k].channel)
      if (c.regions[k].pixels > 0) dof = std::min(dof, ch.dof);
    if (dof < kFewDof) few += (few.empty() ? "" : " ") + map.regions[k].name;
  }
  if (!few.empty())
    std::printf(
        "\nnote: the noise of regions %s rests on few pixels (under %.0f degrees of "
        "freedom: a few bright or noisy pixels carry it); their test is approximate\n",
        few.c_str(), kFewDof);
  std::printf("\n%d of %zu regions differ by more than the noise", c.differing, c.regions.size());
  if (c.differing == 0) {
    std::printf("\n");
    return;
  }
  std::printf(":");
  for (size_t k = 0; k < c.regions.size(); ++k)
    if (c.regions[k].differs) std::printf(" %s", map.regions[k].name.c_str());
  std::printf("\n");
}

int run_compare(const CompareOptions& o) {
  try {
    const Inputs in = read_inputs(o);
    const tracer::ImageRGB& test = in.test.mean;
    const tracer::ImageRGB& ref = in.ref.mean;
    const bool masked = !in.mask.exclusions.empty();
    const tracer::CompareResult r =
        tracer::compare_images(test, ref, masked ? &in.mask.keep : nullptr);
    const tracer::FlipResult flip = tracer::ldr_flip(test, ref, o.ppd, o.flip_exposure);
    const double flip_mean = masked ? masked_flip_mean(flip, in.mask) : flip.mean;
    tracer::RegionMap regions;
    const bool by_region = make_regions(o, in, &regions);
    tracer::RegionComparison rc;
    if (by_region) rc = tracer::compare_regions(in.test, in.ref, regions, &in.mask, o.significance);
    if (!o.diff.empty()) tracer::write_image(o.diff, tracer::false_color_difference(test, ref));
    if (!o.flip_map.empty()) tracer::write_image(o.flip_map, tracer::flip_error_map(flip));

    if (o.json) {
      nlohmann::json j = nlohmann::json::parse(tracer::compare_to_json(r));
      j["flip"] = std::isfinite(flip_mean) ? nlohmann::json(flip_mean) : nlohmann::json();
      j["flip_ppd"] = o.ppd;
      j["flip_exposure"] = o.flip_exposure;
      if (masked || by_region) {
        nlohmann::json ex = nlohmann::json::array();
        for (const auto& e : in.mask.exclusions)
          ex.push_back({{"what", e.what}, {"pixels", e.pixels}});
        nlohmann::json nf = nlohmann::json::object();
        for (const auto& [path, n] : in.nonfinite) nf[path] = n;
        j["pixels_kept"] = in.mask.kept();
        j["exclusions"] = ex;
        j["nonfinite_pixels"] = nf;
      }
      if (by_region)
        j["regions"] = nlohmann::json::parse(tracer::region_comparison_to_json(regions, rc));
      std::cout << j.dump() << "\n";
    } else {
      std::cout << std::setprecision(6) << "size        " << r.width << "x" << r.height << "\n";
      if (in.test.has_variance() && !o.test2.empty())
        std::cout << "test        mean of " << o.test << " and " << o.test2 << "\n";
      if (in.ref.has_variance() && !o.ref2.empty())
        std::cout << "reference   mean of " << o.ref << " and " << o.ref2 << "\n";
      if (masked) {
        std::cout << "pixels      " << in.mask.kept() << " of " << long(r.width) * r.height
                  << " kept; excluded:";
        const char* sep = " ";
        for (const auto& e : in.mask.exclusions) {
          std::cout << sep << e.what << " (" << e.pixels << ")";
          sep = ", ";
        }
        std::cout << "\n";
      }
      std::cout << "rmse        " << r.rmse << "\n"
                << "relmse      " << r.relmse << "\n"
                << "flip        " << flip_mean << "  (LDR-FLIP, " << o.ppd << " ppd, exposure "
                << o.flip_exposure << ")\n"
                << "mean test   " << r.mean_test.x << " " << r.mean_test.y << " " << r.mean_test.z
                << "\n"
                << "mean ref    " << r.mean_ref.x << " " << r.mean_ref.y << " " << r.mean_ref.z
                << "\n";
      if (r.nonfinite_test) std::cout << "nonfinite   " << r.nonfinite_test << " values in TEST\n";
      long nonfinite = 0;
      for (const auto& nf : in.nonfinite) nonfinite += nf.second;
      if (by_region && nonfinite > 0) {
        std::cout << "nonfinite   pixels left out of the regions:";
        for (const auto& [path, n] : in.nonfinite)
          if (n > 0) std::cout << " " << path << " " << n;
        std::cout << "\n";
      }
      if (!o.diff.empty()) std::cout << "diff        " << o.diff << "\n";
      if (!o.flip_map.empty()) std::cout << "flip map    " << o.flip_map << "\n";
      std::cout << std::flush;
      if (by_region) print_regions(regions, rc);
      std::fflush(stdout);
    }
    if (o.fail_on_difference && by_region && rc.differing > 0) {
      std::cerr << "compare: " << rc.differing
                << " region(s) differ by more than the noise (--fail-on-difference)\n";
      return kExitInputError;
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

  const CLI::Validator grid(
      [](std::string& s) {
        int c, r;
        return tracer::parse_grid(s, &c, &r) && c >= 1 && r >= 1
                   ? std::string()
                   : "expected COLUMNSxROWS, e.g. 4x4, not \"" + s + "\"";
      },
      "NxM");
  const CLI::Validator rect(
      [](std::string& s) {
        tracer::PixelRect r;
        return tracer::parse_rect(s, &r) ? std::string()
                                         : "expected x0,y0,x1,y1 with x0 < x1 and y0 < y1 (pixels, "
                                           "x1 and y1 excluded), not \"" +
                                               s + "\"";
      },
      "x0,y0,x1,y1");
  cmd.add_option("--grid", o->grid,
                 "Statistics per region of a COLUMNSxROWS grid (e.g. 4x4): means, their ratio, "
                 "relMSE and, with the test's noise, a z-score per channel")
      ->check(grid);
  auto* test2 = cmd.add_option("--test2", o->test2,
                               "A second render of the test's scene with another seed: the test "
                               "image becomes the mean of the two and their difference its noise")
                    ->check(CLI::ExistingFile);
  cmd.add_option("--test-variance", o->test_variance,
                 "The variance of TEST's mean per pixel (e.g. bench --error's NAME.variance.exr), "
                 "instead of --test2")
      ->check(CLI::ExistingFile)
      ->excludes(test2);
  auto* ref2 = cmd.add_option("--ref2", o->ref2,
                              "A second reference with another seed: the reference becomes the "
                              "mean of the two, with their noise (else it is treated as exact)")
                   ->check(CLI::ExistingFile);
  cmd.add_option("--ref-variance", o->ref_variance,
                 "The variance of REF's mean per pixel (bench --error writes NAME.variance.exr "
                 "beside its reference), instead of --ref2")
      ->check(CLI::ExistingFile)
      ->excludes(ref2);
  cmd.add_option("--mask", o->mask,
                 "Image of the same size; pixels where it is 0 (every channel) are left out of "
                 "every statistic")
      ->check(CLI::ExistingFile);
  cmd.add_option("--exclude", o->excludes,
                 "Leave out the pixels x0 <= x < x1, y0 <= y < y1 (row 0 at the top); repeatable")
      ->check(rect);
  cmd.add_option("--significance", o->significance,
                 "Chance of flagging any region when none truly differs (Sidak-corrected over "
                 "regions and channels)")
      ->check(finite_number() & CLI::Range(1e-12, 0.5))
      ->capture_default_str();
  cmd.add_flag("--fail-on-difference", o->fail_on_difference,
               "Exit 1 when a region differs by more than the noise (needs --test2 or "
               "--test-variance)");
  return [o] {
    if (o->fail_on_difference && o->test2.empty() && o->test_variance.empty()) {
      std::cerr << "error: --fail-on-difference needs the test's noise: give --test2 or "
                   "--test-variance\n";
      return kExitUsage;
    }
    return run_compare(*o);
  };
}

}  // namespace app
