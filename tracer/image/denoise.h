// Denoising a render with Intel Open Image Denoise (OIDN), loaded at run time: neither the build
// nor the tests depend on it, and without it every caller gets a clear reason instead. The
// library comes from the PyPI wheel `pyoidn` (libOpenImageDenoise 2.5.1 with its CPU and CUDA
// devices and weights, no headers), which scripts/setup.sh installs into .deps/oidn; the few C
// functions called here are declared in denoise.cpp from OIDN's documented C API.
#pragma once

#include <string>

#include "image/image.h"

namespace tracer {

// What one denoise did, for the sidecar and the Stats panel.
struct DenoiseInfo {
  std::string denoiser;  // e.g. "Open Image Denoise 2.5.1"
  std::string device;    // "CUDA", "CPU", ...
  std::string inputs;    // "color", "color+albedo", "color+albedo+normal"
  double ms = 0.0;       // wall time of the call, transfers included
};

// Whether the library could be loaded, and if not why (the places tried); loads it on first
// use. Thread-safe.
bool denoiser_available();
// "Open Image Denoise 2.5.1 (CUDA device), /path/libOpenImageDenoise.so.2", or why it is absent.
std::string denoiser_status();

// The denoised colour: OIDN's "RT" filter (HDR), guided by the albedo and normal images when
// given (the normal only together with the albedo, as OIDN requires), both as the renderers'
// AOVs make them (integrator/aov.h). All images must have the colour's size. Throws
// std::runtime_error with OIDN's message, or the reason it is absent; never returns a partial
// image.
ImageRGB denoise_image(const ImageRGB& color, const ImageRGB* albedo, const ImageRGB* normal,
                       DenoiseInfo* info = nullptr);

// The same on images in CUDA device memory (3 floats per pixel, rows top first; the CUDA
// renderer's buffers), read and written in place by OIDN's CUDA device: no copy through the
// host. The caller has finished writing them (its stream synchronised). Returns false, doing
// nothing, when the loaded device is not a CUDA device; throws as denoise_image does.
bool denoise_device_images(const float* color, const float* albedo, const float* normal,
                           float* out, int width, int height, DenoiseInfo* info = nullptr);

}  // namespace tracer
