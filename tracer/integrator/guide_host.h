// Path guiding on the host (integrator/guide.h holds the shared core): the grid a scene gets, the
// training schedule's progress as the workbench and the bench report it, and the CPU backend's
// guide (its buffers; the CUDA backend keeps the same arrays in device memory).
#pragma once

#include <string>
#include <vector>

#include "integrator/guide.h"

namespace tracer {

class CompiledScene;

// The grid over a scene's bounds: cubic cells, `side` (at most kGuideMaxSide) along the longest
// axis (fewer along the others), the bounds grown by a little so that surfaces on them fall inside.
// A scene's grid has as many cells along its longest axis as the image's training can fill:
// a cell's histogram of 256 bins needs thousands of records before it is smooth enough to guide
// (PPG splits its cells at 12,000), and training records about 2 x 255 vertices per pixel, so the
// side is the cube root of pixels / 8 (7 cells at 48 x 48, the full 24 from 384 x 384 up).
struct GuideGrid {
  vec3 lo = vec3(0.0f), inv_cell = vec3(1.0f);
  uint32_t nx = 1, ny = 1, nz = 1;
  uint32_t cells() const { return nx * ny * nz; }
};
GuideGrid guide_grid(vec3 lo, vec3 hi, uint32_t side = kGuideMaxSide);
uint32_t guide_grid_side(uint32_t pixels);
GuideGrid guide_grid(const CompiledScene& scene, uint32_t pixels);
// A guide's arrays, wherever they live (host or device memory).
struct GuideArrays {
  float* dist = nullptr;
  float* hist = nullptr;
  uint32_t* counts = nullptr;
  GuideRecord* records = nullptr;
};
// After training, the guide earns its keep or retires. Two blocks of kGuideCalibrationBlock
// samples follow the last training pass, from sample kGuideCalibrationStart: unguided, then
// guided. Both backends time each sample and measure each block's noise as the relMSE of its mean
// against the mean of the samples before the first block (the bench's relMSE weighting,
// guide_calibration.h): the noise of a block's mean, not of one sample, because the Sobol
// sampler's points make a mean of consecutive samples converge faster than 1/N, and the guided
// vertices must show how much of that they keep. Each sample is a valid estimate of the image,
// so the choice keeps the render unbiased. The guide stays when its variance times its time per
// sample is at least 10% below the unguided one's; otherwise the render goes on unguided (on the
// GPU with the unguided kernels: the specialised shade kernels and the tail).
constexpr uint32_t kGuideCalibrationStart = 256;  // a multiple of the block: Sobol's strata
constexpr uint32_t kGuideCalibrationBlock = 8;
constexpr uint32_t kGuideCalibrationSamples = 2 * kGuideCalibrationBlock;
static_assert(kGuideCalibrationStart >= kGuideTrainSamples, "calibrates the frozen guide");
inline bool guide_calibrates(uint32_t sample) {
  return sample >= kGuideCalibrationStart &&
         sample - kGuideCalibrationStart < kGuideCalibrationSamples;
}
inline bool guide_calibration_guided(uint32_t sample) {
  return sample >= kGuideCalibrationStart + kGuideCalibrationBlock;
}
// Whether `sample` begins a block (the films are kept before it) or ends one (its noise measured).
inline bool guide_calibration_block_starts(uint32_t sample) {
  return guide_calibrates(sample) &&
         (sample - kGuideCalibrationStart) % kGuideCalibrationBlock == 0;
}
inline bool guide_calibration_block_ends(uint32_t sample) {
  return guide_calibrates(sample) &&
         (sample + 1 - kGuideCalibrationStart) % kGuideCalibrationBlock == 0;
}
struct GuideCalibration {
  static constexpr uint32_t kEach = kGuideCalibrationBlock;
  double seconds[2][kEach] = {};  // [unguided, guided]: each sample's time
  double noise[2] = {-1.0, -1.0};  // each block's guide_block_noise (< 0: not yet measured)
  uint32_t samples[2] = {0, 0};
  void add_time(bool guided, double sample_seconds);
  bool done() const { return samples[0] == kEach && samples[1] == kEach && noise[1] >= 0.0; }
  // Guided over unguided, per sample (1 until both are measured): the ratio of the median
  // times (a kernel's first launch loads its code: one slow sample must not decide) and of the
  // blocks' noise.
  double time_ratio() const;
  double variance_ratio() const;
  // The decision, once done(): the guide's relMSE at equal time is at least kGuideKeepGain below
  // the BSDF's alone. The margin: the estimate rests on two blocks of 8 samples, and in a tie
  // the cheaper estimator wins (the unguided kernels are the specialised ones, with the tail).
  static constexpr double kGuideKeepGain = 0.1;
  bool keeps() const { return variance_ratio() * time_ratio() <= 1.0 - kGuideKeepGain; }
  bool retires() const { return done() && !keeps(); }
};
// The view for a sample, by the schedule: the distribution once `builds` > 0, the training
// arrays while the sample trains (guide_trains); none for the calibration's unguided block or
// once the guide has retired. Both backends' guides hand theirs out so.
GuideView guide_view_for(const GuideGrid& grid, const GuideArrays& arrays, uint32_t builds,
                         uint32_t sample, const GuideCalibration& calibration);

// A block's noise: over pixels and channels, guide_moment_term (guide_calibration.h) of the
// block's mean, (now - then) * inv_block, against the earlier mean base * inv_base; the arrays
// hold each pixel's rgb sums over all samples so far (both halves).
double guide_block_noise(const double* now, const double* then, const double* base,
                         double inv_block, double inv_base, size_t floats);

// What a renderer's guide has done, for the Stats panel, the bench and the sidecar.
struct GuideStatus {
  bool on = false;
  uint32_t trained_samples = 0;  // samples that recorded (at most kGuideTrainSamples)
  uint32_t builds = 0;           // distributions built so far (the passes done)
  uint32_t learned_cells = 0, cells = 0;  // at the last build
  uint32_t guiding_cells = 0;  // learned cells whose share of the guide is not 0
  GuideCalibration calibration;  // kept or retired, once calibration.done()
  bool frozen() const { return trained_samples >= kGuideTrainSamples; }
  bool retired() const { return calibration.retires(); }
  // The status of a guide on `grid` after `samples` samples, `builds` builds, `learned` cells
  // of which `guiding` guide.
  static GuideStatus of(const GuideGrid& grid, uint32_t samples, uint32_t builds,
                        uint32_t learned, uint32_t guiding, const GuideCalibration& calibration);
  // e.g. "training: pass 4 of 8 (14 of 255 spp), 1,234 of 13,824 cells learned, 801 guide",
  // "frozen after 255 spp, ...; calibrating (5 of 16 spp)" or "...; kept: 0.52x the variance
  // for 1.36x the time per sample" (or "retired: ...": unguided from then on).
  std::string describe() const;
};

// The number of builds the schedule has made once `samples` samples are done.
uint32_t guide_builds_done(uint32_t samples);
// The last sample of the pass that holds `sample` (kGuideTrainSamples - 1 or beyond: none).
uint32_t guide_pass_end(uint32_t sample);

// The CPU backend's guide: the arrays of GuideView in host memory.
class HostGuide {
 public:
  // Sizes the arrays for the grid and `pixels` paths and clears them.
  void setup(const GuideGrid& grid, uint32_t pixels);
  void clear();  // forgets everything learned (a new render)
  bool ready() const { return !dist_.empty(); }
  // The view for samples from `first_sample` on (within one pass): the distribution once built,
  // the training arrays while the schedule trains; none for an unguided calibration sample or
  // once the guide has retired.
  GuideView view(uint32_t first_sample);
  GuideCalibration& calibration() { return calibration_; }
  // After sample `sample` (guide_builds_after): rebuilds every cell on `threads` threads.
  void build(int threads);
  GuideStatus status(uint32_t samples) const;

 private:
  GuideGrid grid_;
  std::vector<float> hist_, dist_;
  std::vector<uint32_t> counts_;
  std::vector<GuideRecord> records_;
  uint32_t builds_ = 0, learned_ = 0, guiding_ = 0;
  GuideCalibration calibration_;
};

}  // namespace tracer
