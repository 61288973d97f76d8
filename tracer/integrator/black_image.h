// Why a finished render came out black: the likely reason, in words a user can act on.
#pragma once

#include <string>

#include "scene/compiled_scene.h"

namespace tracer {

// The most likely reason that `scene` renders to an entirely black image, found by casting a few
// rays: the scene has no light, the camera is inside a closed object, every light faces away
// from everything, or (when none of those holds) no light reaches the camera.
std::string explain_black_image(const Scene& scene, const CompiledScene& compiled);

}  // namespace tracer
