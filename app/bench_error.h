// `pathtracer bench --error`: error against wall-clock time for a suite of configurations,
// measured against a reference image that carries its own per-pixel variance.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace app {

struct ErrorBenchOptions {
  bool enabled = false;
  std::string reference;   // EXR; rendered here when missing; "<stem>.variance.exr" beside it
  int reference_spp = 0;   // 0: 32768 on the GPU, 1024 on the CPU
  std::string configs;     // comma-separated; empty: the default suite for the backends present
  int max_spp = 0;         // 0: 4096 on the GPU, 256 on the CPU
  double time_limit = 30;  // seconds per configuration
  std::string out_dir = "bench-out";
  std::string flip = "on";
  int threads = 0;  // CPU backend threads (0: all cores)
};

// Returns the --error flag, so that speed-only options can exclude it.
CLI::Option* add_error_bench_options(CLI::App& cmd, ErrorBenchOptions* o);

// Settings shared with the speed bench; 0 means "the scene's own".
struct ErrorBenchScene {
  std::string scene;
  int width = 0, height = 0, max_depth = 0;
  std::string backend = "auto";
  std::vector<std::string> sets;  // --set KEY=VALUE, applied to the scene first (settings table)
};
int run_error_bench(const ErrorBenchScene& s, const ErrorBenchOptions& o);

}  // namespace app
