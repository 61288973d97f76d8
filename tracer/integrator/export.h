// Exporting a render: the colour (raw, denoised or both, display.denoise), the AOV layers the
// user asked for (EXR layers, or PNG images beside the file) and the sidecar. One writer for
// `render` and the workbench's Export, so both write the same files under the same names.
#pragma once

#include <string>
#include <vector>

#include "integrator/renderer.h"
#include "integrator/sidecar.h"
#include "scene/scene.h"

namespace tracer {

// Which AOVs to write (`--aov albedo,normal,depth,id`), and whether as PNG images beside the
// file even when it is an EXR (`--aov-png`; a PNG export always writes them so).
struct AovRequest {
  bool albedo = false, normal = false, depth = false, id = false;
  bool png = false;
  bool any() const { return albedo || normal || depth || id; }
  std::vector<std::string> names() const;
};
// Parses a comma-separated list of albedo, normal, depth, id or all; false and a message naming
// the bad word otherwise.
bool parse_aov_list(const std::string& list, AovRequest* out, std::string* problem);

// "out/x.denoised.png" for "out/x.png": where display.denoise both puts the denoised image.
std::string denoised_path(const std::string& path);
// "out/x.albedo.png" for "out/x.exr" and "albedo".
std::string aov_png_path(const std::string& path, const std::string& aov);

// What export_render wrote.
struct ExportResult {
  std::vector<std::string> files;
  DenoiseInfo denoise;  // empty denoiser when display.denoise was off
};

// Writes `color` (the renderer's mean) to `path` and, per scene.display.denoise, the denoised
// image (guided by aovs' albedo and normal when given) in its place or beside it; the requested
// AOV layers from `aovs`; and the sidecar (run's output, aovs and denoise fields are filled
// here). Everything that can fail before a file is written (the denoiser absent, AOVs missing)
// fails first; each file is written atomically. Throws std::exception with the reason.
// `denoised`, when given (Renderer::denoised_image's, with `denoised_info`), is used instead of
// denoising here.
ExportResult export_render(const std::string& path, const ImageRGB& color, const AovImages* aovs,
                           const AovRequest& request, const Scene& scene, SidecarRun run,
                           const ImageRGB* denoised = nullptr,
                           const DenoiseInfo* denoised_info = nullptr);

// AOV images as a viewer shows them (display-referred, stored linear so that a PNG shows the
// encoded values): albedo as is, normals as n * 0.5 + 0.5, depth as grey from near (white) to
// far (black) over its range, ids as a colour per value.
ImageRGB aov_preview(const AovImages& a, const std::string& which);

}  // namespace tracer
