// Flattens a host Scene into the plain arrays both backends trace (BVH, primitives, materials,
// lights) and keeps them alive; view() points into them.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "bvh/bvh8.h"
#include "scene/light_tree.h"
#include "scene/scene.h"
#include "scene/scene_view.h"

namespace tracer {

class CompiledScene {
 public:
  // Builds everything for an image of width x height. The scene must be validated.
  // `same_geometry`: a compiled scene of the same triangles and spheres (an edit of materials,
  // lights, camera or settings): its BVHs are shared instead of rebuilt, which keeps the
  // workbench's edits of a scene of millions of triangles interactive. Ignored when its
  // primitive counts differ.
  CompiledScene(const Scene& scene, int width, int height,
                const CompiledScene* same_geometry = nullptr);

  const SceneView& view() const { return view_; }
  const BvhBuildStats& bvh_stats() const { return bvh_->stats; }
  // True when the BVHs came from `same_geometry` (not rebuilt).
  bool shares_bvh() const { return shared_bvh_; }
  uint32_t features() const { return view_.features; }

  const std::vector<BvhNode>& nodes() const { return bvh_->nodes; }
  const CpuBvh& cpu_bvh() const { return *cpu_bvh_; }
  // The 8-wide compressed tree a bvh8 build's GPU walks; no nodes where it cannot hold the
  // scene's leaves (bvh8.h). view() leaves it out (the CPU walks its SSE tree); the GPU and the
  // tests set TraceView::nodes8 and prim_indices8 from it.
  const Bvh8& bvh8() const { return *bvh8_; }  // empty unless kBvh8Build
  const Bvh& bvh() const { return *bvh_; }
  // The flat primitive list (bvh/flat_list.h); enabled only for small scenes. view() points at
  // it but leaves use_flat off: the backends choose.
  const FlatList& flat_list() const { return flat_; }
  const std::vector<uint32_t>& prim_indices() const { return bvh_->prim_indices; }
  const std::vector<TriangleVerts>& tri_verts() const { return tri_verts_; }
  const std::vector<TriangleShading>& tri_shading() const { return tri_shading_; }
  const std::vector<Sphere>& spheres() const { return spheres_; }
  const std::vector<Material>& materials() const { return materials_; }
  const std::vector<Light>& lights() const { return lights_; }
  const std::vector<float>& light_cdf() const { return light_cdf_; }
  // The light tree (render.light_sampler bvh): nodes and each light's trail.
  const LightTree& light_tree() const { return light_tree_; }
  const std::vector<TriangleUv>& tri_uvs() const { return tri_uvs_; }
  // Instances (bvh/instance.h): the instances, their meshes' trees one after another, and the
  // meshes' triangles (TraceView::inst_*).
  const std::vector<Instance>& instances() const { return instances_; }
  const Bvh& instance_bvh() const { return *inst_bvh_; }
  const std::vector<TriangleVerts>& inst_tri_verts() const { return inst_tri_verts_; }
  const std::vector<TriangleShading>& inst_tri_shading() const { return inst_tri_shading_; }
  const std::vector<TriangleUv>& inst_tri_uvs() const { return inst_tri_uvs_; }
  const std::vector<TextureDesc>& textures() const { return textures_; }
  const std::vector<uint32_t>& texels() const { return texels_; }
  // The environment's and the distant lights' arrays (view().infinite points at its view when
  // the scene has any).
  const InfiniteLightsData& infinite() const { return *infinite_; }
  // The point and spot lights (view().point_lights points at them when there are any).
  const std::vector<PointLight>& point_lights() const { return point_lights_; }
  // The planes of flat smooth reflectors (view().reflector_planes points at them when there are
  // any).
  const std::vector<ReflectorPlane>& reflector_planes() const { return reflector_planes_; }
  // True when the scene's flat reflectors lie in more than kMaxReflectorPlanes planes (none
  // listed).
  bool too_many_reflector_planes() const { return too_many_reflectors_; }
  // The window planes of smooth glass (view().window_planes points at them; none where there
  // are more than kMaxWindowPlanes).
  const std::vector<WindowPlane>& window_planes() const { return window_planes_; }
  // Light tracing's targets (view().light_targets points at them when there are any).
  const std::vector<LightTarget>& light_targets() const { return light_targets_; }

 private:
  // Shared with the compiled scenes of later edits that keep the geometry.
  std::shared_ptr<const Bvh> bvh_;
  std::shared_ptr<const CpuBvh> cpu_bvh_;  // the CPU backend's SSE layout of bvh_ (bvh/cpu_bvh.h)
  std::shared_ptr<const Bvh8> bvh8_;
  std::shared_ptr<const Bvh> inst_bvh_;  // the instanced meshes' trees, one after another
  std::vector<uint32_t> mesh_roots_;     // each instanced mesh's root in inst_bvh_
  std::vector<Instance> instances_;
  std::vector<TriangleVerts> inst_tri_verts_;
  std::vector<TriangleShading> inst_tri_shading_;
  std::vector<TriangleUv> inst_tri_uvs_;
  bool shared_bvh_ = false;
  FlatList flat_;
  std::vector<TriangleVerts> tri_verts_;
  std::vector<TriangleShading> tri_shading_;
  std::vector<Sphere> spheres_;
  std::vector<Material> materials_;
  std::vector<Light> lights_;
  std::vector<float> light_cdf_;
  LightTree light_tree_;
  std::vector<TriangleUv> tri_uvs_;  // empty unless the scene has textures and uvs
  std::vector<TextureDesc> textures_;
  std::vector<uint32_t> texels_;  // RGBA8 packed little-endian (R in the low byte)
  std::unique_ptr<InfiniteLightsData> infinite_;  // on the heap: view_ keeps its address
  std::vector<PointLight> point_lights_;
  std::vector<ReflectorPlane> reflector_planes_;
  bool too_many_reflectors_ = false;
  std::vector<WindowPlane> window_planes_;
  std::vector<LightTarget> light_targets_;
  SceneView view_;
};

Camera make_camera(const CameraDesc& desc, int width, int height);

// "depth-of-field, dielectrics, ..." for messages and `pathtracer info`.
std::string describe_features(uint32_t features);

}  // namespace tracer
