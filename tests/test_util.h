// Helpers shared by the tests: paths to the source tree and test data.
#pragma once

#include <cstdlib>
#include <string>

namespace test {
// $TRACER_SOURCE_DIR overrides the checkout baked in at build time (binaries carried to a GPU
// machine run from another directory).
inline std::string source_dir() {
  const char* env = std::getenv("TRACER_SOURCE_DIR");
  return env && *env ? env : TRACER_SOURCE_DIR;
}
inline std::string data_dir() { return source_dir() + "/tests/data"; }
inline std::string pathtracer_exe() { return PATHTRACER_EXE; }
// Debian's blender-data world maps (CC0; 1024x512 DWA-compressed OpenEXR): city, courtyard,
// forest, interior, night, studio, sunrise, sunset. Tests that use them skip when absent.
constexpr const char* kBlenderWorlds = "/usr/share/blender/datafiles/studiolights/world";
// Runs a shell command, returns its exit status and fills `output` with stdout+stderr.
int run_command(const std::string& cmd, std::string* output = nullptr);
}  // namespace test
