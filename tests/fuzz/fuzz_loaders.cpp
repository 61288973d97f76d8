// libFuzzer target for the scene loaders (run by scripts/fuzz.sh, not by ctest). FUZZ_FORMAT
// picks the parser: json (from memory), obj or gltf (through a temporary file, as users load
// them). Bad input must end in InputError; a scene that loads is compiled (BVH, lights) and a few
// paths are traced through it, so that magnitudes validation lets through must also render. A
// crash, hang, leak or sanitizer report is a bug.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "integrator/path.h"
#include "scene/compiled_scene.h"
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
    tracer::Scene scene;
    if (format == "json") {
      scene = tracer::load_scene_from_json(text, "fuzz.json");
    } else {
      static const std::string path =
          "/tmp/pathtracer_fuzz_" + std::to_string(getpid()) + "." + format;
      FILE* f = std::fopen(path.c_str(), "wb");
      if (!f) return 0;
      std::fwrite(data, 1, size, f);
      std::fclose(f);
      scene = tracer::load_scene(path);
    }
    // Four by four pixels, one sample each, at most four bounces: cheap, and enough to exercise
    // the BVH build, traversal, shading and light sampling on whatever the loader accepted.
    // Large meshes (the bunny seeds) are left out: their BVH build under the sanitizers takes
    // longer than the fuzzer's timeout, and size is not what the fuzzer explores.
    if (scene.mesh.indices.size() + scene.spheres.size() > 20000) return 0;
    const tracer::CompiledScene cs(scene, 4, 4);
    tracer::IntegratorSettings cfg;
    cfg.width = cfg.height = 4;
    cfg.max_depth = 4;
    for (uint32_t p = 0; p < 16; ++p) tracer::trace_path(cs.view(), cfg, p, 0);
  } catch (const tracer::InputError&) {
    // The expected outcome for broken input.
  }
  return 0;
}
