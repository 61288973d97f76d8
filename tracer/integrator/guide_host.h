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
// The view for a sample, by the schedule: the distribution once `builds` > 0, the training
// arrays while the sample trains (guide_trains). Both backends' guides hand theirs out so.
GuideView guide_view_for(const GuideGrid& grid, const GuideArrays& arrays, uint32_t builds,
                         uint32_t sample);

// What a renderer's guide has done, for the Stats panel, the bench and the sidecar.
struct GuideStatus {
  bool on = false;
  uint32_t trained_samples = 0;  // samples that recorded (at most kGuideTrainSamples)
  uint32_t builds = 0;           // distributions built so far (the passes done)
  uint32_t learned_cells = 0, cells = 0;  // at the last build
  uint32_t guiding_cells = 0;  // learned cells whose share of the guide is not 0
  bool frozen() const { return trained_samples >= kGuideTrainSamples; }
  // The status of a guide on `grid` after `samples` samples, `builds` builds, `learned` cells
  // of which `guiding` guide.
  static GuideStatus of(const GuideGrid& grid, uint32_t samples, uint32_t builds,
                        uint32_t learned, uint32_t guiding);
  // e.g. "training: pass 4 of 8 (14 of 255 spp), 1,234 of 13,824 cells learned, 801 guide" or
  // "frozen after 255 spp, ...".
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
  // the training arrays while the schedule trains.
  GuideView view(uint32_t first_sample);
  // After sample `sample` (guide_builds_after): rebuilds every cell on `threads` threads.
  void build(int threads);
  GuideStatus status(uint32_t samples) const;

 private:
  GuideGrid grid_;
  std::vector<float> hist_, dist_;
  std::vector<uint32_t> counts_;
  std::vector<GuideRecord> records_;
  uint32_t builds_ = 0, learned_ = 0, guiding_ = 0;
};

}  // namespace tracer
