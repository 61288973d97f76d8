// Backend-independent helpers of the Renderer interface: the integrator settings of a scene, the
// host display transform and the half-buffer noise estimate.
#include "integrator/renderer.h"

namespace tracer {

IntegratorSettings make_integrator_settings(const RenderSettings& rs) {
  IntegratorSettings cfg;
  cfg.width = uint32_t(rs.width);
  cfg.height = uint32_t(rs.height);
  cfg.max_depth = uint32_t(rs.max_depth);
  cfg.rr_start_depth = uint32_t(rs.rr_start_depth);
  cfg.seed = rs.seed;
  cfg.nee = rs.nee;
  cfg.mis = rs.mis;
  cfg.russian_roulette = rs.russian_roulette;
  cfg.jitter = rs.jitter;
  cfg.clamp = rs.clamp;
  cfg.sampler = rs.sampler;
  cfg.filter = rs.filter;
  cfg.light_sampler = rs.light_sampler;
  cfg.guiding = rs.guiding ? 1u : 0u;
  cfg.mnee = rs.mnee ? 1u : 0u;
  cfg.light_tracing = rs.light_tracing ? 1u : 0u;  // (light_tracing_runs: with jitter only)
  cfg.filter_radius = rs.filter_radius > 0.0f ? rs.filter_radius : default_filter_radius(rs.filter);
  return cfg;
}

void Renderer::display_rgba8(std::vector<uint32_t>& out, float exposure_scale, ToneMap op) const {
  const ImageRGB img = image();
  out.resize(size_t(img.width) * img.height);
  for (size_t i = 0; i < out.size(); ++i) {
    const vec3 c(img.pixels[3 * i], img.pixels[3 * i + 1], img.pixels[3 * i + 2]);
    out[i] = tracer::display_rgba8(c, exposure_scale, op);
  }
}

uint32_t wavefront_tail_bounce(const std::vector<uint32_t>& estimate, float fraction,
                               uint32_t pixels, uint32_t iterations) {
  if (!(fraction > 0.0f) || estimate.empty()) return 0;
  const double limit = double(fraction) * pixels;
  for (uint32_t b = 1; b < iterations; ++b)
    if (b >= estimate.size() || estimate[b] < limit) return b;
  return 0;
}

ImageRGB Renderer::denoised_image(DenoiseInfo* info) const {
  const AovImages a = aov_images();
  return denoise_image(image(), a.empty() ? nullptr : &a.albedo, a.empty() ? nullptr : &a.normal,
                       info);
}

void Renderer::half_sums(float* even, float* odd) const {
  ImageRGB halves[2];
  half_images(&halves[0], &halves[1]);
  float* outs[2] = {even, odd};
  for (int h = 0; h < 2; ++h) {
    const float n = float(half_samples(h));
    for (size_t i = 0; i < halves[h].pixels.size(); ++i) outs[h][i] = halves[h].pixels[i] * n;
  }
}

double half_images_relmse(const ImageRGB& a, const ImageRGB& b) {
  double sum = 0.0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    const double d = double(a.pixels[i]) - b.pixels[i];
    const double m = 0.5 * (double(a.pixels[i]) + b.pixels[i]) + 0.01;
    if (d == d) sum += d * d / (m * m);
  }
  return a.pixels.empty() ? -1.0 : sum / double(a.pixels.size());
}

double half_buffer_relmse(const Renderer& r) {
  if (r.samples_done() < 2) return -1.0;
  ImageRGB a, b;
  r.half_images(&a, &b);
  return half_images_relmse(a, b);
}

}  // namespace tracer
