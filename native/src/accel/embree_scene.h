// Owns the Embree device and scene built over the user's meshes. Vertex and
// index buffers are shared with the Scene, not copied; geometry id = mesh id,
// then one user geometry per CSG solid (id = mesh count + solid index), then
// one per L-system object (id = mesh count + solid count + object index);
// SurfaceMap (accel/surface_hit.h) turns a hit's id back into its surface.
#pragma once

#include <embree3/rtcore.h>

#include <cstddef>
#include <string>

#include "scene/scene.h"
#include "util/math.h"

namespace plm {

class EmbreeScene {
 public:
  // Scenes with at least this many mesh triangles get Embree's high-quality
  // build (spatial splits), smaller ones the medium one (embree_scene.cpp).
  static constexpr size_t kHighQualityTriangles = 100000;

  // thread_count 0 = all cores. Throws plm::Error if Embree fails.
  EmbreeScene(const Scene& scene, unsigned thread_count);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  RTCScene handle() const { return scene_; }
  Vec3 bounds_min() const { return lo_; }
  Vec3 bounds_max() const { return hi_; }

 private:
  void build(const Scene& scene, unsigned thread_count);
  void release();

  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  Vec3 lo_, hi_;
  std::string error_;  // first error reported by Embree's callback
};

}  // namespace plm
