// Scene's material table.
#include "scene/scene.h"

namespace tracer {

uint32_t Scene::add_material(const std::string& name, const Material& m) {
  // Names stay unique so that find_material is unambiguous when a mesh file brings a material
  // whose name the scene already uses.
  std::string unique = name;
  for (int n = 2; find_material(unique) != kInvalid; ++n) unique = name + "#" + std::to_string(n);
  materials.push_back({unique, m});
  return uint32_t(materials.size() - 1);
}

uint32_t Scene::find_material(const std::string& name) const {
  for (size_t i = 0; i < materials.size(); ++i)
    if (materials[i].name == name) return uint32_t(i);
  return kInvalid;
}

uint64_t Scene::instanced_triangle_count() const {
  uint64_t n = 0;
  for (const MeshInstance& inst : instances)
    if (inst.mesh < instanced_meshes.size()) n += instanced_meshes[inst.mesh].mesh.indices.size();
  return n;
}

}  // namespace tracer
