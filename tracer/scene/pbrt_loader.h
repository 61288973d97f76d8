// pbrt-v4 text scenes (.pbrt): the camera, film, sampler and integrator settings, transforms and
// attribute blocks, shapes (triangle meshes, PLY meshes, quadrics, bilinear patches), instances,
// materials, textures and area lights, mapped onto this renderer with one warning per kind of
// construct it substitutes or skips (docs/SCENE_FORMAT.md, "pbrt-v4 scenes").
#pragma once

#include <string>

#include "scene/scene.h"

namespace tracer {

// Loads a .pbrt file (and the files it includes), then validates the scene. Throws InputError
// "path:line: what; nothing was rendered".
Scene load_pbrt_scene(const std::string& path);
// The same from text; `path` names it in messages and its folder resolves relative file names.
Scene load_pbrt_string(const std::string& text, const std::string& path);

// pbrt's camera space is left-handed (x right, y up, z forward) and ours right-handed, so a
// pbrt world seen through our camera would be mirrored. When the camera transform keeps
// handedness, our world is pbrt's with x negated; when it already swaps it (a "Scale -1 1 1"
// before LookAt, as exporters write), our world is pbrt's as it is.
mat4 pbrt_world_to_ours(const mat4& camera_from_world);

}  // namespace tracer
