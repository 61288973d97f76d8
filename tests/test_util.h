// Helpers shared by the tests: paths to the source tree and test data.
#pragma once

#include <string>

namespace test {
inline std::string source_dir() { return TRACER_SOURCE_DIR; }
inline std::string data_dir() { return TRACER_TEST_DATA; }
inline std::string pathtracer_exe() { return PATHTRACER_EXE; }
// Runs a shell command, returns its exit status and fills `output` with stdout+stderr.
int run_command(const std::string& cmd, std::string* output = nullptr);
}  // namespace test
