// Host-side BVH builder: a binary binned-SAH tree (16 bins per axis over centroid bounds, leaves
// when splitting does not pay), then collapsed into the 4-wide tree that traversal uses. Both
// passes are iterative, so deep inputs cannot overflow the call stack, and run on all cores,
// building the same tree for any number of threads.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <type_traits>

#include "bvh/bvh.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace tracer {
namespace {

constexpr int kBins = 16;
constexpr float kTraversalCost = 1.0f;
constexpr float kIntersectCost = 1.0f;
// Leaves at this depth stop splitting, so traversal with a kBvhStackSize stack cannot overflow.
constexpr uint32_t kMaxDepth = kBvhStackSize - 4;
// Nodes of kBigNode primitives or more are split a tree level at a time, each pass over them
// spread over chunks of kChunk primitives whose partial results are merged in chunk order;
// below that, a node's whole subtree is one sequential task, and the tasks run side by side.
// Both are constants, never derived from the thread count: every machine builds the same tree,
// so that CPU and GPU renders of one seed agree everywhere.
constexpr uint32_t kBigNode = 1u << 16;
constexpr uint32_t kChunk = 1u << 13;

// Runs fn(i) for every i in [0, count) on a fixed set of threads, the caller's among them. Which
// thread takes which i varies from run to run, so fn(i) may write only what belongs to i.
class WorkerPool {
 public:
  explicit WorkerPool(int threads) {
    for (int i = 1; i < threads; ++i) {
      try {
        workers_.emplace_back([this] { work(); });
      } catch (const std::system_error&) {  // out of threads: fewer of them, the same tree
        break;
      }
    }
  }
  ~WorkerPool() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (std::thread& t : workers_) t.join();
  }
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  void run(size_t count, const std::function<void(size_t)>& fn) {
    if (workers_.empty() || count <= 1) {
      for (size_t i = 0; i < count; ++i) fn(i);
      return;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      fn_ = &fn;
      count_ = count;
      next_ = 0;
      busy_ = workers_.size();
      error_ = nullptr;
      ++generation_;
    }
    wake_.notify_all();
    drain();
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return busy_ == 0; });
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void drain() {
    try {
      for (size_t i; (i = next_.fetch_add(1)) < count_;) (*fn_)(i);
    } catch (...) {  // std::bad_alloc: hand out no more work; run() rethrows it
      std::lock_guard<std::mutex> lock(mutex_);
      if (!error_) error_ = std::current_exception();
      next_ = count_;
    }
  }
  void work() {
    uint64_t seen = 0;
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
        if (stop_) return;
        seen = generation_;
      }
      drain();
      std::lock_guard<std::mutex> lock(mutex_);
      if (--busy_ == 0) done_.notify_one();
    }
  }

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(size_t)>* fn_ = nullptr;
  size_t count_ = 0;
  std::atomic<size_t> next_{0};
  size_t busy_ = 0;
  uint64_t generation_ = 0;
  bool stop_ = false;
  std::exception_ptr error_;
};

// Surface area in double: a box of finite float bounds can have an area (or even an extent)
// beyond the float range, which made the SAH cost inf / inf = NaN. Infinite bounds (from callers
// that skip validate_scene) count as the float range, so the cost stays finite for any input.
double area_double(const Aabb& b) {
  if (b.empty()) return 0.0;
  const glm::dvec3 big(std::numeric_limits<float>::max());
  const glm::dvec3 e =
      glm::clamp(glm::dvec3(b.hi), -big, big) - glm::clamp(glm::dvec3(b.lo), -big, big);
  return 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
}

// Four floats: x, y, z and a lane whose value is never used. The per-primitive loops work on
// these. min4 and max4 are glm::min and glm::max lane by lane ((b < a) ? b : a and
// (a < b) ? b : a), and the SSE and portable versions compute the same bits, NaN and signed
// zeros included, so that every machine builds the same tree.
//
// bins_of gives the bins of centroid c in [lo, lo + kBins / scale] on each axis. A NaN position
// (an empty or non-finite primitive box from a caller that skipped validate_scene, or an extent
// whose scale underflowed to 0 next to an infinite distance) goes to bin 0 instead of through
// int(NaN), which is undefined and was an out-of-bounds index.
#if defined(__SSE2__)
struct F4 {
  __m128 v;
};
inline F4 load4(const void* p) {
  return {_mm_loadu_ps(static_cast<const float*>(p))};
}
inline F4 splat4(float f) {
  return {_mm_set1_ps(f)};
}
inline F4 min4(F4 a, F4 b) {
  return {_mm_min_ps(b.v, a.v)};
}
inline F4 max4(F4 a, F4 b) {
  return {_mm_max_ps(b.v, a.v)};
}
inline F4 centroid4(F4 lo, F4 hi) {  // Aabb::centroid
  const __m128 half = _mm_set1_ps(0.5f);
  return {_mm_add_ps(_mm_mul_ps(half, lo.v), _mm_mul_ps(half, hi.v))};
}
inline vec3 xyz(F4 a) {
  alignas(16) float f[4];
  _mm_store_ps(f, a.v);
  return vec3(f[0], f[1], f[2]);
}
// The box as two F4 without reading past it: hi comes from the four floats that end it.
inline void load_box(const Aabb& b, F4& lo, F4& hi) {
  static_assert(sizeof(Aabb) == 6 * sizeof(float), "Aabb is lo then hi, packed");
  const float* f = reinterpret_cast<const float*>(&b);
  lo.v = _mm_loadu_ps(f);
  hi.v = _mm_shuffle_ps(_mm_loadu_ps(f + 2), _mm_loadu_ps(f + 2), _MM_SHUFFLE(0, 3, 2, 1));
}
inline void bins_of(F4 c, F4 lo, F4 scale, int out[4]) {
  const __m128 f = _mm_mul_ps(_mm_sub_ps(c.v, lo.v), scale.v);
  const __m128i k = _mm_cvttps_epi32(_mm_min_ps(_mm_set1_ps(float(kBins - 1)), f));
  const __m128i in_range = _mm_castps_si128(_mm_cmpge_ps(f, _mm_setzero_ps()));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(out), _mm_and_si128(k, in_range));
}
#else
struct F4 {
  float v[4];
};
inline F4 load4(const void* p) {
  F4 r;
  std::memcpy(r.v, p, sizeof(r.v));
  return r;
}
inline F4 splat4(float f) {
  return {{f, f, f, f}};
}
inline F4 min4(F4 a, F4 b) {
  for (int i = 0; i < 4; ++i) a.v[i] = glm::min(a.v[i], b.v[i]);
  return a;
}
inline F4 max4(F4 a, F4 b) {
  for (int i = 0; i < 4; ++i) a.v[i] = glm::max(a.v[i], b.v[i]);
  return a;
}
inline F4 centroid4(F4 lo, F4 hi) {
  for (int i = 0; i < 4; ++i) lo.v[i] = 0.5f * lo.v[i] + 0.5f * hi.v[i];
  return lo;
}
inline vec3 xyz(F4 a) {
  return vec3(a.v[0], a.v[1], a.v[2]);
}
inline void load_box(const Aabb& b, F4& lo, F4& hi) {
  lo = {{b.lo.x, b.lo.y, b.lo.z, 0.0f}};
  hi = {{b.hi.x, b.hi.y, b.hi.z, 0.0f}};
}
inline void bins_of(F4 c, F4 lo, F4 scale, int out[4]) {
  for (int i = 0; i < 4; ++i) {
    const float f = (c.v[i] - lo.v[i]) * scale.v[i];
    out[i] = f >= 0.0f ? int(std::min(f, float(kBins - 1))) : 0;
  }
}
#endif

// An Aabb as two F4.
struct Box4 {
  F4 lo = splat4(kInfinity), hi = splat4(-kInfinity);
  void grow(F4 plo, F4 phi) {
    lo = min4(lo, plo);
    hi = max4(hi, phi);
  }
  Aabb aabb() const {
    Aabb b;
    b.lo = xyz(lo);
    b.hi = xyz(hi);
    return b;
  }
};

// The bounds of a node's primitives and of their centroids.
struct NodeBounds {
  Box4 box, cbox;
  void grow(F4 lo, F4 hi, F4 c) {
    box.grow(lo, hi);
    cbox.grow(c, c);
  }
  void grow(const NodeBounds& o) {
    box.grow(o.box.lo, o.box.hi);
    cbox.grow(o.cbox.lo, o.cbox.hi);
  }
};

// Where a node's centroids are binned. Axes without extent are not binned (nor split along),
// and a node that may not split (one primitive, or at the depth cap) bins none.
struct BinGrid {
  alignas(16) float lo[4], scale[4];
  bool active[3];
  BinGrid(const Aabb& cbox, bool may_split) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = cbox.lo[a];
      active[a] = may_split && cbox.hi[a] > cbox.lo[a];
      scale[a] = active[a] ? float(kBins) / (cbox.hi[a] - cbox.lo[a]) : 0.0f;
    }
    lo[3] = scale[3] = 0.0f;
  }
  void bins(F4 c, int out[4]) const { bins_of(c, load4(lo), load4(scale), out); }
};

// The boxes and counts of the primitives in each bin, per axis. A bin's box is written when its
// first primitive arrives, so an empty Bins costs its counts to clear, not 1.5 KB of boxes, and
// is read only while its count is non-zero. Merging partial bins is exact (minima, maxima and
// integer sums), and done in a fixed order all the same.
struct Bins {
  uint32_t count[3][kBins] = {};
  F4 lo[3][kBins], hi[3][kBins];

  void add(F4 c, F4 plo, F4 phi, const BinGrid& g) {
    int k[4];
    g.bins(c, k);
    for (int a = 0; a < 3; ++a)
      if (g.active[a]) grow(a, k[a], 1, plo, phi);
  }
  void add(const Bins& o, const BinGrid& g) {
    for (int a = 0; a < 3; ++a) {
      if (!g.active[a]) continue;
      for (int k = 0; k < kBins; ++k)
        if (o.count[a][k] > 0) grow(a, k, o.count[a][k], o.lo[a][k], o.hi[a][k]);
    }
  }
  Aabb box(int a, int k) const {
    Aabb b;
    b.lo = xyz(lo[a][k]);
    b.hi = xyz(hi[a][k]);
    return b;
  }

 private:
  void grow(int a, int k, uint32_t n, F4 plo, F4 phi) {
    if (count[a][k] == 0) {  // as growing an empty box, whatever the bounds (NaN too)
      lo[a][k] = splat4(kInfinity);
      hi[a][k] = splat4(-kInfinity);
    }
    count[a][k] += n;
    lo[a][k] = min4(lo[a][k], plo);
    hi[a][k] = max4(hi[a][k], phi);
  }
};

// How a node splits: before bin `bin` of `axis`, or (axis 3) at the middle of its range when
// no bin boundary separates its centroids; axis -1 makes it a leaf.
struct Split {
  int axis = -1, bin = 0;
  bool leaf() const { return axis < 0; }
  bool by_bin() const { return axis >= 0 && axis < 3; }
};

// The binned SAH decision (Wald 2007) with the builder's two overrides: nodes of more than four
// leaves' worth of primitives always split (so coincident centroids still make small leaves),
// and nothing splits at the depth cap. Only the boundaries just below occupied bins are costed:
// the boundaries in a run of empty bins all cost the same, and the sweep from the top keeps the
// first (highest) of equal costs, which is that one.
Split choose_split(const Aabb& box, const BinGrid& grid, const Bins& bins, uint32_t count,
                   uint32_t depth, int max_leaf_size) {
  const float leaf_cost = kIntersectCost * float(count);
  Split best;
  float best_cost = leaf_cost;
  const float inv_area = 1.0f / std::max(box.area(), 1e-30f);
  for (int axis = 0; axis < 3; ++axis) {
    if (!grid.active[axis]) continue;
    int occupied[kBins], m = 0;
    for (int i = 0; i < kBins; ++i)
      if (bins.count[axis][i] > 0) occupied[m++] = i;
    // What lies left of the boundary below occupied[q + 1]: the bins up to occupied[q].
    float left_area[kBins];
    uint32_t left_count[kBins];
    Aabb acc;
    uint32_t cnt = 0;
    for (int q = 0; q + 1 < m; ++q) {
      acc.grow(bins.box(axis, occupied[q]));
      cnt += bins.count[axis][occupied[q]];
      left_area[q] = acc.area();
      left_count[q] = cnt;
    }
    acc = Aabb();
    cnt = 0;
    for (int q = m - 1; q > 0; --q) {
      acc.grow(bins.box(axis, occupied[q]));
      cnt += bins.count[axis][occupied[q]];
      const float cost = kTraversalCost + kIntersectCost * inv_area *
                                              (left_area[q - 1] * float(left_count[q - 1]) +
                                               acc.area() * float(cnt));
      if (cost < best_cost) {
        best_cost = cost;
        best.axis = axis;
        best.bin = occupied[q];
      }
    }
  }
  const bool must_split = count > uint32_t(max_leaf_size) * 4 && depth < kMaxDepth;
  if (best.leaf() && must_split) best.axis = 3;
  if (best.leaf() || (count <= uint32_t(max_leaf_size) && best_cost >= leaf_cost)) return Split();
  return best;
}

// The binary tree being built. count == 0: inner node whose children are left_first and
// left_first + 1. count > 0: leaf holding prim_indices[left_first, left_first + count).
// Trivially constructible, so that the whole tree's array is allocated without being written
// and then filled in parallel.
struct BinaryNode {
  vec3 lo, hi;
  uint32_t left_first, count;
  bool is_leaf() const { return count > 0; }
  Aabb box() const {
    Aabb b;
    b.lo = lo;
    b.hi = hi;
    return b;
  }
};
static_assert(std::is_trivially_default_constructible<BinaryNode>::value,
              "the tree's array is allocated uninitialised");

// A node still to be split: its index among the binary nodes, its primitive range and the
// bounds of those primitives and of their centroids.
struct Pending {
  uint32_t node, first, count, depth;
  NodeBounds bounds;
};

// ---- Subtrees of small nodes, one thread each ----

// One primitive of a subtree, copied next to its neighbours, so that the subtree's passes read
// memory that stays in cache instead of gathering from the whole scene's arrays. Read as F4:
// lo's fourth lane holds the primitive's index.
struct alignas(16) PrimRef {
  float lo[3];
  uint32_t prim;
  float hi[4], c[4];
};

struct Subtree {
  std::vector<BinaryNode> nodes;  // [0] is the root; inner nodes index this vector
  double sah_sum = 0.0;
};

NodeBounds bounds_of(const PrimRef* first, const PrimRef* last) {
  NodeBounds nb;
  for (; first != last; ++first) nb.grow(load4(first->lo), load4(first->hi), load4(first->c));
  return nb;
}

// Moves the primitives that `goes_left` to the front of [first, last) and returns where the
// others begin, bounding both sides on the way. Hoare's partition (as std::partition): each
// primitive is tested once, and the order it leaves depends on the input's order alone.
template <class GoesLeft>
PrimRef* partition_bounded(PrimRef* first, PrimRef* last, const GoesLeft& goes_left,
                           NodeBounds& left, NodeBounds& right) {
  auto grow = [](NodeBounds& nb, const PrimRef& r) {
    nb.grow(load4(r.lo), load4(r.hi), load4(r.c));
  };
  for (;;) {
    while (first != last && goes_left(*first)) grow(left, *first++);
    while (first != last && !goes_left(last[-1])) grow(right, *--last);
    if (first == last) return first;
    std::swap(*first, last[-1]);  // *first went right and last[-1] left
    grow(left, *first++);
    grow(right, *--last);
  }
}

// The sequential build of the subtree over prims[0, count), depth first; the primitives are
// written back in leaf order. Leaves index from prims.
void build_subtree(const std::vector<Aabb>& bounds, uint32_t* prims, uint32_t count, uint32_t depth,
                   int max_leaf_size, Subtree& out) {
  std::vector<PrimRef> refs(count);
  for (uint32_t i = 0; i < count; ++i) {
    const Aabb& b = bounds[prims[i]];
    PrimRef& r = refs[i];
    const vec3 c = b.centroid();
    r = {{b.lo.x, b.lo.y, b.lo.z}, prims[i], {b.hi.x, b.hi.y, b.hi.z, 0.0f}, {c.x, c.y, c.z, 0.0f}};
  }
  std::vector<BinaryNode>& nodes = out.nodes;
  nodes.reserve(2 * size_t(count));
  nodes.push_back(BinaryNode{vec3(0.0f), vec3(0.0f), 0, count});
  std::vector<Pending> stack{{0, 0, count, depth, bounds_of(refs.data(), refs.data() + count)}};
  while (!stack.empty()) {
    const Pending task = stack.back();
    stack.pop_back();
    PrimRef* first = refs.data() + task.first;
    PrimRef* last = first + task.count;
    const Aabb box = task.bounds.box.aabb();
    nodes[task.node].lo = box.lo;
    nodes[task.node].hi = box.hi;
    const BinGrid grid(task.bounds.cbox.aabb(), task.count > 1 && task.depth < kMaxDepth);
    Bins bins;
    for (const PrimRef* r = first; r != last; ++r)
      bins.add(load4(r->c), load4(r->lo), load4(r->hi), grid);
    const Split split = choose_split(box, grid, bins, task.count, task.depth, max_leaf_size);
    if (split.leaf()) {
      out.sah_sum += area_double(box) * kIntersectCost * task.count;
      continue;
    }
    NodeBounds left_bounds, right_bounds;
    PrimRef* mid = first;
    if (split.by_bin()) {
      auto goes_left = [&](const PrimRef& r) {
        int k[4];
        grid.bins(load4(r.c), k);
        return k[split.axis] < split.bin;
      };
      mid = partition_bounded(first, last, goes_left, left_bounds, right_bounds);
    }
    if (mid == first || mid == last) {  // the middle (the bins never leave a side empty)
      mid = first + task.count / 2;
      left_bounds = bounds_of(first, mid);
      right_bounds = bounds_of(mid, last);
    }
    const uint32_t left_count = uint32_t(mid - first);
    const uint32_t child = uint32_t(nodes.size());
    out.sah_sum += area_double(box) * kTraversalCost;
    nodes[task.node].left_first = child;
    nodes[task.node].count = 0;
    const Pending left{child, task.first, left_count, task.depth + 1, left_bounds};
    const Pending right{child + 1, task.first + left_count, task.count - left_count, task.depth + 1,
                        right_bounds};
    for (const Pending* c : {&left, &right})
      nodes.push_back(BinaryNode{vec3(0.0f), vec3(0.0f), c->first, c->count});
    stack.push_back(right);
    stack.push_back(left);
  }
  for (uint32_t i = 0; i < count; ++i) prims[i] = refs[i].prim;
}

// ---- Big nodes, a level at a time ----

// The big nodes, one tree level at a time, each pass spread over all chunks of all the level's
// nodes, so that the many smaller nodes of the deeper levels keep every thread busy too. Per
// level, two passes gather the primitives' boxes: binning, then a stable partition of each chunk
// into `scratch` that also bounds both sides; a third moves each chunk's two sides to where
// prefix sums over the chunks, in chunk order, put them. Children of kBigNode primitives or more
// make the next level, smaller ones `tasks`. Nodes are numbered level by level, two children side
// by side after their parent.
class LevelBuilder {
 public:
  LevelBuilder(const std::vector<Aabb>& bounds, std::vector<uint32_t>& prims, int max_leaf_size,
               WorkerPool& pool)
      : bounds_(bounds),
        prims_(prims),
        max_leaf_size_(max_leaf_size),
        pool_(pool),
        scratch_(new uint32_t[prims.size()]) {}

  // Splits `level` and the levels below it into `nodes`; returns the SAH contributions of the
  // nodes it made, summed in node order.
  double build(std::vector<Pending> level, std::vector<BinaryNode>& nodes,
               std::vector<Pending>& tasks) {
    double sah_sum = 0.0;
    while (!level.empty()) {
      split_level(level);
      std::vector<Pending> next;
      for (size_t i = 0; i < level.size(); ++i) {
        const Pending& p = level[i];
        const Aabb box = p.bounds.box.aabb();
        BinaryNode& node = nodes[p.node];
        node.lo = box.lo;
        node.hi = box.hi;
        if (split_[i].leaf()) {  // at the depth cap
          node.left_first = p.first;
          node.count = p.count;
          sah_sum += area_double(box) * kIntersectCost * p.count;
          continue;
        }
        sah_sum += area_double(box) * kTraversalCost;
        const uint32_t child = uint32_t(nodes.size());
        node.left_first = child;
        node.count = 0;
        nodes.resize(nodes.size() + 2);  // invalidates `node`
        const uint32_t left = left_count_[i];
        const Pending kids[2] = {
            {child, p.first, left, p.depth + 1, child_bounds_[2 * i]},
            {child + 1, p.first + left, p.count - left, p.depth + 1, child_bounds_[2 * i + 1]}};
        for (const Pending& k : kids) (k.count >= kBigNode ? next : tasks).push_back(k);
      }
      level.swap(next);
    }
    return sah_sum;
  }

 private:
  struct Chunk {
    uint32_t node;        // index in the level
    uint32_t begin, end;  // positions in prims_
  };

  // Fills split_, left_count_ and child_bounds_ for every node of the level, and partitions
  // the primitives of the nodes split at a bin boundary.
  void split_level(const std::vector<Pending>& level) {
    const size_t n = level.size();
    std::vector<Chunk> chunks;
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t end = level[i].first + level[i].count;
      for (uint32_t b = level[i].first; b < end; b += kChunk)
        chunks.push_back({i, b, std::min(end, b + kChunk)});
    }
    std::vector<BinGrid> grids;
    for (const Pending& p : level)
      grids.emplace_back(p.bounds.cbox.aabb(), p.count > 1 && p.depth < kMaxDepth);
    std::vector<Bins> chunk_bins(chunks.size());
    pool_.run(chunks.size(), [&](size_t c) {
      const BinGrid& grid = grids[chunks[c].node];
      for (uint32_t i = chunks[c].begin; i < chunks[c].end; ++i) {
        F4 lo, hi;
        load_box(bounds_[prims_[i]], lo, hi);
        chunk_bins[c].add(centroid4(lo, hi), lo, hi, grid);
      }
    });
    std::vector<Bins> bins(n);
    for (size_t c = 0; c < chunks.size(); ++c)
      bins[chunks[c].node].add(chunk_bins[c], grids[chunks[c].node]);
    split_.resize(n);
    for (size_t i = 0; i < n; ++i) {
      split_[i] = choose_split(level[i].bounds.box.aabb(), grids[i], bins[i], level[i].count,
                               level[i].depth, max_leaf_size_);
    }

    // Each chunk: its left primitives, then its right ones (written from the end, then
    // reversed), in order, to its own range of scratch_, bounding both sides. A node split in
    // the middle moves nothing.
    std::vector<uint32_t> chunk_left(chunks.size(), 0);
    std::vector<NodeBounds> chunk_sides(2 * chunks.size());
    pool_.run(chunks.size(), [&](size_t c) {
      const Chunk& ch = chunks[c];
      const Split& s = split_[ch.node];
      if (s.leaf()) return;
      const BinGrid& grid = grids[ch.node];
      const uint32_t mid = level[ch.node].first + level[ch.node].count / 2;
      NodeBounds& left = chunk_sides[2 * c];
      NodeBounds& right = chunk_sides[2 * c + 1];
      uint32_t* out = scratch_.get();
      uint32_t l = ch.begin, r = ch.end;
      for (uint32_t i = ch.begin; i < ch.end; ++i) {
        const uint32_t p = prims_[i];
        F4 lo, hi;
        load_box(bounds_[p], lo, hi);
        const F4 centroid = centroid4(lo, hi);
        bool goes_left = i < mid;
        if (s.by_bin()) {
          int k[4];
          grid.bins(centroid, k);
          goes_left = k[s.axis] < s.bin;
        }
        (goes_left ? left : right).grow(lo, hi, centroid);
        if (goes_left)
          out[l++] = p;
        else
          out[--r] = p;
      }
      std::reverse(out + r, out + ch.end);
      chunk_left[c] = l - ch.begin;
    });

    // The children's bounds and the chunks' destinations, in chunk order.
    left_count_.assign(n, 0);
    for (size_t c = 0; c < chunks.size(); ++c) left_count_[chunks[c].node] += chunk_left[c];
    child_bounds_.assign(2 * n, NodeBounds());
    for (size_t c = 0; c < chunks.size(); ++c) {
      child_bounds_[2 * chunks[c].node].grow(chunk_sides[2 * c]);
      child_bounds_[2 * chunks[c].node + 1].grow(chunk_sides[2 * c + 1]);
    }
    for (size_t i = 0; i < n; ++i) {
      const Pending& p = level[i];
      if (split_[i].leaf() || (left_count_[i] > 0 && left_count_[i] < p.count)) continue;
      // A side left empty, which the bins never choose: the middle instead, as for coincident
      // centroids (the primitives have not moved).
      split_[i].axis = 3;
      left_count_[i] = p.count / 2;
      child_bounds_[2 * i] = child_bounds_[2 * i + 1] = NodeBounds();
      for (uint32_t k = p.first; k < p.first + p.count; ++k) {
        F4 lo, hi;
        load_box(bounds_[prims_[k]], lo, hi);
        child_bounds_[2 * i + (k - p.first < left_count_[i] ? 0 : 1)].grow(lo, hi,
                                                                           centroid4(lo, hi));
      }
    }
    std::vector<uint32_t> to_left(chunks.size()), to_right(chunks.size());
    std::vector<uint32_t> left_at(n), right_at(n);
    for (size_t i = 0; i < n; ++i) {
      left_at[i] = level[i].first;
      right_at[i] = level[i].first + left_count_[i];
    }
    for (size_t c = 0; c < chunks.size(); ++c) {
      const uint32_t i = chunks[c].node;
      to_left[c] = left_at[i];
      to_right[c] = right_at[i];
      left_at[i] += chunk_left[c];
      right_at[i] += chunks[c].end - chunks[c].begin - chunk_left[c];
    }
    pool_.run(chunks.size(), [&](size_t c) {
      const Chunk& ch = chunks[c];
      if (!split_[ch.node].by_bin()) return;
      const uint32_t* from = scratch_.get() + ch.begin;
      const uint32_t left = chunk_left[c];
      std::copy(from, from + left, prims_.data() + to_left[c]);
      std::copy(from + left, from + (ch.end - ch.begin), prims_.data() + to_right[c]);
    });
  }

  const std::vector<Aabb>& bounds_;
  std::vector<uint32_t>& prims_;
  const int max_leaf_size_;
  WorkerPool& pool_;
  std::unique_ptr<uint32_t[]> scratch_;  // uninitialised: each use writes before it reads
  // Per node of the level being split; child_bounds_ holds two per node.
  std::vector<Split> split_;
  std::vector<uint32_t> left_count_;
  std::vector<NodeBounds> child_bounds_;
};

// ---- The whole binary tree, and its collapse ----

// The binary tree in one array, with each node's height (0 for a leaf). The levels' nodes come
// first; the subtrees follow in task order, each root in its placeholder among the levels'
// nodes. Node 0 is the root, and children are side by side and after their parent.
struct BinaryTree {
  std::unique_ptr<BinaryNode[]> nodes;
  std::unique_ptr<uint32_t[]> height;
  uint32_t size = 0;
  uint32_t level_nodes = 0;        // nodes below this were made by the levels,
  std::vector<uint8_t> task_root;  // which of them are placeholders for a subtree's root
  double sah_sum = 0.0;
};

BinaryTree assemble_tree(std::vector<BinaryNode> level_nodes, double level_sah,
                         const std::vector<Pending>& tasks, std::vector<Subtree>& subtrees,
                         WorkerPool& pool) {
  BinaryTree tree;
  tree.level_nodes = uint32_t(level_nodes.size());
  tree.task_root.assign(level_nodes.size(), 0);
  tree.sah_sum = level_sah;
  std::vector<size_t> base(tasks.size());
  size_t total = level_nodes.size();
  for (size_t t = 0; t < tasks.size(); ++t) {
    base[t] = total - 1;  // the subtree's node j >= 1 goes to base + j
    total += subtrees[t].nodes.size() - 1;
    tree.sah_sum += subtrees[t].sah_sum;  // in task order: the same sum for any thread count
    tree.task_root[tasks[t].node] = 1;
  }
  tree.size = uint32_t(total);
  tree.nodes.reset(new BinaryNode[total]);
  tree.height.reset(new uint32_t[total]);
  std::copy(level_nodes.begin(), level_nodes.end(), tree.nodes.get());
  pool.run(tasks.size(), [&](size_t t) {
    const std::vector<BinaryNode>& local = subtrees[t].nodes;
    for (size_t j = local.size(); j-- > 0;) {  // children before parents, for the heights
      BinaryNode b = local[j];
      uint32_t h = 0;
      if (b.is_leaf()) {
        b.left_first += tasks[t].first;
      } else {
        b.left_first += uint32_t(base[t]);
        h = 1 + std::max(tree.height[b.left_first], tree.height[b.left_first + 1]);
      }
      const size_t at = j == 0 ? tasks[t].node : base[t] + j;
      tree.nodes[at] = b;
      tree.height[at] = h;
    }
    std::vector<BinaryNode>().swap(subtrees[t].nodes);
  });
  for (size_t i = level_nodes.size(); i-- > 0;) {
    const BinaryNode& b = tree.nodes[i];
    if (tree.task_root[i]) continue;
    tree.height[i] =
        b.is_leaf() ? 0 : 1 + std::max(tree.height[b.left_first], tree.height[b.left_first + 1]);
  }
  return tree;
}

struct CollapseWork {
  uint32_t bin_node, wide_node, stack, depth;
};

struct CollapseStats {
  uint32_t leaf_count = 0, max_depth = 0, max_stack = 0;
  void add(const CollapseStats& o) {
    leaf_count += o.leaf_count;
    max_depth = std::max(max_depth, o.max_depth);
    max_stack = std::max(max_stack, o.max_stack);
  }
};

// Collapses the binary subtree under `root` into 4-wide nodes, top down: a wide node starts
// with the two children of a binary inner node and repeatedly replaces the inner child of
// largest surface area by its two children until it holds four (Wald, Benthin & Boulos 2008).
// The traversal stack bound decides how far that may go: a node reached with at most `stack`
// entries below it pushes at most (children - 1), and a subtree of binary height h can always be
// collapsed so that it pushes at most h more (two children per node, as in the binary
// traversal). Opening stops where stack + children - 1 + height(child) could exceed
// kBvhStackSize for some child; the binary builder's depth cap keeps height(root) below
// kBvhStackSize, so two children always fit.
// The wide nodes go to `out`, whose node root.wide_node must exist; an inner child that
// `defer` names gets its wide node, left empty, and goes to `deferred` instead.
template <class Defer>
void collapse(const BinaryTree& tree, CollapseWork root, const Defer& defer,
              std::vector<BvhNode>& out, std::vector<CollapseWork>& deferred,
              uint32_t* prim_indices, CollapseStats& st) {
  const BinaryNode* bin = tree.nodes.get();
  const uint32_t* height = tree.height.get();
  BvhSlot empty{};
  empty.lo = vec3(kInfinity);
  empty.hi = vec3(-kInfinity);
  std::vector<CollapseWork> work{root};
  while (!work.empty()) {
    const CollapseWork w = work.back();
    work.pop_back();
    st.max_depth = std::max(st.max_depth, w.depth);
    uint32_t cand[kBvhWidth];
    float area[kBvhWidth];
    int k = 0;
    const BinaryNode& b = bin[w.bin_node];
    if (b.is_leaf()) {
      cand[k++] = w.bin_node;  // a single-leaf tree: the root holds that one leaf
    } else {
      cand[k++] = b.left_first;
      cand[k++] = b.left_first + 1;
    }
    for (int i = 0; i < k; ++i) area[i] = bin[cand[i]].box().area();
    while (k < kBvhWidth) {
      int best = -1;
      for (int i = 0; i < k; ++i)
        if (!bin[cand[i]].is_leaf() && (best < 0 || area[i] > area[best])) best = i;
      if (best < 0) break;
      // After opening: k + 1 children, the tallest of them max_height high.
      const uint32_t opened = cand[best];
      uint32_t max_height = height[opened] - 1;
      for (int i = 0; i < k; ++i)
        if (i != best) max_height = std::max(max_height, height[cand[i]]);
      if (w.stack + uint32_t(k) + max_height > uint32_t(kBvhStackSize)) break;
      cand[best] = bin[opened].left_first;
      cand[k] = bin[opened].left_first + 1;
      area[best] = bin[cand[best]].box().area();
      area[k] = bin[cand[k]].box().area();
      ++k;
    }
    const uint32_t child_stack = w.stack + uint32_t(k) - 1;
    st.max_stack = std::max(st.max_stack, child_stack);
    BvhNode node;
    for (int i = 0; i < kBvhWidth; ++i) node.child[i] = empty;
    for (int i = 0; i < k; ++i) {
      const BinaryNode& c = bin[cand[i]];
      BvhSlot& slot = node.child[i];
      slot.lo = c.lo;
      slot.hi = c.hi;
      slot.pad = 0;
      if (c.is_leaf()) {
        slot.ref = kBvhLeafBit | c.left_first;
        prim_indices[c.left_first + c.count - 1] |= kBvhLastPrimBit;
        st.leaf_count++;
      } else {
        slot.ref = uint32_t(out.size());
        out.push_back(BvhNode{});
        const CollapseWork next{cand[i], slot.ref, child_stack, w.depth + 1};
        (defer(cand[i]) ? deferred : work).push_back(next);
      }
    }
    out[w.wide_node] = node;
  }
}

// The nodes that the levels made are collapsed first; each inner subtree node that this reaches
// becomes a job, and the jobs run side by side, each into its own nodes, which are then
// appended in job order and renumbered.
void collapse_to_wide(const BinaryTree& tree, WorkerPool& pool, Bvh& bvh) {
  auto in_subtree = [&](uint32_t b) { return b >= tree.level_nodes || tree.task_root[b]; };
  std::vector<BvhNode> top{BvhNode{}};
  std::vector<CollapseWork> jobs;
  CollapseStats st;
  collapse(tree, {0, 0, 0, 0}, in_subtree, top, jobs, bvh.prim_indices.data(), st);

  std::vector<std::vector<BvhNode>> job_nodes(jobs.size());
  std::vector<CollapseStats> job_stats(jobs.size());
  pool.run(jobs.size(), [&](size_t j) {
    std::vector<CollapseWork> none;
    job_nodes[j].push_back(BvhNode{});
    collapse(
        tree, {jobs[j].bin_node, 0, jobs[j].stack, jobs[j].depth}, [](uint32_t) { return false; },
        job_nodes[j], none, bvh.prim_indices.data(), job_stats[j]);
  });
  std::vector<size_t> base(jobs.size());
  size_t total = top.size();
  for (size_t j = 0; j < jobs.size(); ++j) {
    base[j] = total - 1;  // the job's node i >= 1 goes to base + i
    total += job_nodes[j].size() - 1;
    st.add(job_stats[j]);
  }
  bvh.nodes.resize(total);
  std::copy(top.begin(), top.end(), bvh.nodes.begin());
  pool.run(jobs.size(), [&](size_t j) {
    std::vector<BvhNode>& local = job_nodes[j];
    for (size_t i = 0; i < local.size(); ++i) {
      BvhNode node = local[i];
      for (BvhSlot& slot : node.child)  // an unused slot's ref is 0, which no job node has
        if (!is_leaf_ref(slot.ref) && slot.ref != 0) slot.ref += uint32_t(base[j]);
      bvh.nodes[i == 0 ? jobs[j].wide_node : base[j] + i] = node;
    }
    std::vector<BvhNode>().swap(local);
  });
  bvh.stats.node_count = uint32_t(bvh.nodes.size());
  bvh.stats.leaf_count = st.leaf_count;
  bvh.stats.max_depth = st.max_depth;
  bvh.stats.max_stack = st.max_stack;
}

}  // namespace

Bvh build_bvh(const std::vector<Aabb>& bounds, int max_leaf_size, int threads) {
  const auto start = std::chrono::steady_clock::now();
  auto elapsed_ms = [&] {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
        .count();
  };
  Bvh bvh;
  const uint32_t n = uint32_t(bounds.size());
  if (bounds.size() >= kBvhLeafBit) {  // leaf references keep 31 bits for the first primitive
    throw std::length_error("build_bvh: " + std::to_string(bounds.size()) +
                            " primitives; at most " + std::to_string(kBvhLeafBit - 1) +
                            " fit in a leaf reference");
  }
  if (n == 0) {  // an empty scene has no nodes; traversal checks for that
    bvh.stats.build_ms = elapsed_ms();
    return bvh;
  }
  // A scene below kBigNode is one sequential task: no threads to start.
  if (threads <= 0) threads = int(std::max(1u, std::thread::hardware_concurrency()));
  WorkerPool pool(n >= kBigNode ? threads : 1);

  // The big nodes level by level, from the root's bounds (chunk by chunk, merged in chunk
  // order); then the small nodes' subtrees side by side, largest first.
  bvh.prim_indices.resize(n);
  std::vector<BinaryNode> level_nodes(1);
  std::vector<Pending> tasks;
  double level_sah = 0.0;
  if (n >= kBigNode) {
    std::vector<NodeBounds> chunk_bounds((n + kChunk - 1) / kChunk);
    pool.run(chunk_bounds.size(), [&](size_t c) {
      const uint32_t begin = uint32_t(c) * kChunk, end = std::min(n, begin + kChunk);
      for (uint32_t i = begin; i < end; ++i) {
        bvh.prim_indices[i] = i;
        F4 lo, hi;
        load_box(bounds[i], lo, hi);
        chunk_bounds[c].grow(lo, hi, centroid4(lo, hi));
      }
    });
    Pending root{0, 0, n, 0, NodeBounds()};
    for (const NodeBounds& b : chunk_bounds) root.bounds.grow(b);
    LevelBuilder levels(bounds, bvh.prim_indices, max_leaf_size, pool);
    level_sah = levels.build({root}, level_nodes, tasks);
  } else {
    for (uint32_t i = 0; i < n; ++i) bvh.prim_indices[i] = i;
    tasks.push_back({0, 0, n, 0, NodeBounds()});
  }
  std::vector<Subtree> subtrees(tasks.size());
  std::vector<uint32_t> order(tasks.size());
  for (uint32_t t = 0; t < order.size(); ++t) order[t] = t;
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return tasks[a].count > tasks[b].count; });
  pool.run(tasks.size(), [&](size_t k) {
    const Pending& t = tasks[order[k]];
    build_subtree(bounds, bvh.prim_indices.data() + t.first, t.count, t.depth, max_leaf_size,
                  subtrees[order[k]]);
  });

  const BinaryTree tree = assemble_tree(std::move(level_nodes), level_sah, tasks, subtrees, pool);
  bvh.stats.binary_node_count = tree.size;
  bvh.stats.sah_cost = float(tree.sah_sum / std::max(area_double(tree.nodes[0].box()), 1e-300));
  collapse_to_wide(tree, pool, bvh);
  bvh.stats.build_ms = elapsed_ms();
  return bvh;
}

}  // namespace tracer
