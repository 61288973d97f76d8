// The noise measure of path guiding's calibration (integrator/guide_host.h, GuideCalibration):
// one pixel channel's squared deviation of a block's mean from the mean of the samples before
// the calibration, weighted as the bench's relMSE (image/convergence.h: (r + 0.01)^2). The CPU backend sums it on
// the host, the CUDA backend in a reduction kernel (cuda/film.cu).
#pragma once

#include "core/hd.h"

namespace tracer {

template <typename T>
TRACER_HD inline T guide_moment_term(T value, T mean) {
  const T d = (value - mean) / (mean + T(0.01));
  return d * d;
}

}  // namespace tracer
