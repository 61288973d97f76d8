// Distributed rendering without the transport: how the samples of one image are handed out in
// batches to ranks of different speeds, the accumulators those ranks add up, and the frame
// patterns of a sequence. app/mpi_render.cpp moves these over MPI; everything here is plain
// data, so the tests check it without MPI.
//
// A sample's number alone seeds its paths (Renderer::set_next_sample), so ranks that render
// disjoint ranges of numbers add up to the image that one process renders with all of them, up to
// the order of the float sums.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "integrator/renderer.h"

namespace tracer {

// Samples first, first + 1, ... first + count - 1 (count 0: no more work).
struct SampleRange {
  uint32_t first = 0, count = 0;
};

// Hands out the sample numbers of one image in batches, in order, to ranks that ask when they
// are free ("self-scheduling"), so fast and slow ranks finish together:
// - a batch lasts about `batch_s` at the asking rank's measured speed (its first batch, before
//   it has one, is a single sample);
// - with a sample count, no batch is more than half the asking rank's share of what remains
//   (shares by measured speed), so the last batches shrink and every rank ends within about one
//   small batch of the others;
// - with a time limit instead, batches are handed out until `time_limit_s` has passed (by the
//   clock the caller passes), each no longer than the time left.
class BatchScheduler {
 public:
  // spp > 0: exactly spp samples; spp == 0: until time_limit_s (> 0).
  BatchScheduler(uint32_t spp, double time_limit_s, int ranks, double batch_s = 0.5);
  // The next batch for `rank`, whose last batch took ms_per_spp milliseconds per sample (<= 0:
  // not measured yet), asked now_s seconds after the render began. Empty when the work is
  // all handed out.
  SampleRange next(int rank, double ms_per_spp, double now_s);
  // Ends the handing out (a rank failed): every later next() is empty.
  void stop() { stopped_ = true; }
  uint32_t handed_out() const { return next_; }
  // Per rank: batches and samples handed out.
  uint32_t batches(int rank) const { return batches_[size_t(rank)]; }
  uint32_t samples(int rank) const { return samples_[size_t(rank)]; }
  int ranks() const { return int(batches_.size()); }

 private:
  uint32_t spp_;
  double time_limit_s_, batch_s_;
  uint32_t next_ = 0;
  bool stopped_ = false;
  std::vector<double> rate_;  // samples per ms, per rank (0: not measured)
  std::vector<uint32_t> batches_, samples_;
};

// A render's accumulators as plain sums: what the ranks of a distributed render add together
// (element by element) and rank 0 turns into images.
struct Accumulation {
  int width = 0, height = 0;
  // Radiance summed over the samples of even (0) and of odd (1) numbers, 3 per pixel.
  std::vector<float> sum[2];
  uint32_t count[2] = {0, 0};
  // The feature buffers (empty while off): albedo rgb, normal xyz and depth summed over the AOV
  // samples (7 per pixel), and the material and primitive of a pixel's first AOV sample (2 per
  // pixel).
  std::vector<float> aov_sum;
  uint32_t aov_count = 0;
  std::vector<uint32_t> aov_ids;
  // Counters over the samples.
  RayCounts rays;
  uint64_t nonfinite = 0, clamped = 0;
  double clamped_luminance = 0.0;

  uint32_t samples() const { return count[0] + count[1]; }
  // Adds another's sums and counters (same size); ids are kept, or taken when this has none.
  void add(const Accumulation& o);
  ImageRGB image() const;                          // the mean
  void half_images(ImageRGB* even, ImageRGB* odd) const;  // the halves' means
  AovImages aov_images() const;                    // empty when there are none
  double half_relmse() const;                      // half_buffer_relmse() of these halves
};

// A renderer's accumulators (Renderer::half_sums; floats, as the GPU keeps them) for an image of
// width x height. The counters are the caller's (Renderer keeps no totals of rays): `rays` etc.
// are left zero.
Accumulation accumulation_of(const Renderer& r, int width, int height);
// Its AOV part alone (aov_sum, aov_count, aov_ids; empty while the AOVs are off or have none).
Accumulation accumulation_of_aovs(const Renderer& r, int width, int height);

// Where one rank of a distributed render runs, from its place among the ranks of its host:
// with --backend auto, node-local rank i takes CUDA device i while there are devices and the
// others run on the CPU, sharing the host's cores (render.threads 0: hw_threads divided among
// the host's CPU ranks); --backend cuda shares the devices round robin (several ranks per GPU);
// --backend cpu divides the cores among all the host's ranks.
struct RankPlacement {
  BackendChoice backend = BackendChoice::kAuto;
  int device = 0;   // the CUDA device (when backend is not kCpu)
  int threads = 0;  // CPU threads (when it runs on the CPU)
  std::string note;  // how it was placed, when that is worth saying
};
RankPlacement place_rank(BackendChoice asked, int threads_asked, int local_rank, int local_size,
                         int gpus, int hw_threads);

// What one rank did, for rank 0's report and the sidecar.
struct RankShare {
  int rank = 0;
  std::string host, backend, device;
  uint32_t samples = 0, batches = 0;
  double render_s = 0.0;    // time spent in its batches
  double ms_per_spp = 0.0;  // its speed over them
  double idle_s = 0.0;      // from its last batch's end until every rank had ended
};

// A hash of everything that decides a rank's samples: the camera, the render settings that shape
// the image (not threads, backend, spp, time limit or strictness), the environment, materials,
// lights and the geometry's data (meshes, spheres, instances, textures). Ranks that would sum
// different images (another version of the scene file on one host, another --seed) differ here.
uint64_t scene_fingerprint(const Scene& scene);

// --- frame sequences -----------------------------------------------------------------------

// Parses "A..B" (A <= B, both >= 0) or a single "A"; false with a message otherwise.
bool parse_frame_range(const std::string& text, int* first, int* last, std::string* problem);
// Whether `pattern` holds a run of '#' (the frame number's place).
bool has_frame_field(const std::string& pattern);
// `pattern` with its first run of '#' replaced by `frame`, zero-padded to the run's length
// ("shot_####.json", 7 -> "shot_0007.json").
std::string frame_path(const std::string& pattern, int frame);

}  // namespace tracer
