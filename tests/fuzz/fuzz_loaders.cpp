// libFuzzer target for the scene loaders (run by scripts/fuzz.sh, not by ctest). FUZZ_FORMAT
// picks the parser: json (from memory), obj or gltf (through a temporary file, as users load
// them). Bad input must end in InputError; a crash, hang, leak or sanitizer report is a bug.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "scene/loader.h"

namespace tracer {
// The fuzzer does not need the built-in scene; json_loader.cpp references it.
extern const char* const kBuiltinSceneJson;
const char* const kBuiltinSceneJson = "{}";
}  // namespace tracer

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string format = getenv("FUZZ_FORMAT") ? getenv("FUZZ_FORMAT") : "json";
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    if (format == "json") {
      tracer::load_scene_from_json(text, "fuzz.json");
    } else {
      static const std::string path =
          "/tmp/pathtracer_fuzz_" + std::to_string(getpid()) + "." + format;
      FILE* f = std::fopen(path.c_str(), "wb");
      if (!f) return 0;
      std::fwrite(data, 1, size, f);
      std::fclose(f);
      tracer::load_scene(path);
    }
  } catch (const tracer::InputError&) {
    // The expected outcome for broken input.
  }
  return 0;
}
