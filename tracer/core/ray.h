// A ray: origin, direction and the far end of the interval it is tested over. In core/ because
// the camera makes rays and the BVH traces them, and neither depends on the other.
#pragma once

#include "core/math.h"

namespace tracer {

struct Ray {
  vec3 o;
  float tmax;
  vec3 d;  // unit length
  float pad;
};

}  // namespace tracer
