#include "accel/surface_hit.h"

#include "lsystem/lsystem_object.h"

namespace plm {

SurfaceMap::SurfaceMap(const Scene& scene, const std::vector<const Vec3*>& normals, size_t normal_stride)
    : mesh_count_(scene.meshes.size()), lsystem_base_(scene.meshes.size() + scene.csgs.size()),
      normal_stride_(normal_stride) {
  meshes_.reserve(scene.meshes.size());
  for (size_t m = 0; m < scene.meshes.size(); ++m)
    meshes_.push_back({scene.meshes[m].positions.data(), scene.meshes[m].indices.data(),
                       reinterpret_cast<const unsigned char*>(normals[m])});
  for (const CsgSolid& c : scene.csgs) csgs_.push_back(c.object.get());
  for (const auto& l : scene.lsystems) lsystems_.push_back(l.get());
}

SurfaceMap::LSystemDetail SurfaceMap::lsystem_detail(uint32_t object, const lsystem::GraphHit& graph) const {
  const lsystem::LSystemObject& obj = *lsystems_[object];
  return {lsystem::ol_normal(graph.n), obj.scene_material(graph.material), obj.stub_key(graph)};
}

}  // namespace plm
