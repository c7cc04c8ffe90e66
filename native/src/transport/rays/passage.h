// Straight rays through passable surfaces (transport/materials/material_table.h:
// TRANSPARENT lobes, smooth panes): the direct pass's shadow rays and the final
// gather's rays go on through them with a weight, so the direct light through a
// window is computed per texel instead of carried by photons
// (docs/design/materials.md, "Direct light through glass: straight rays pass
// panes"). A pane passes a ray that enters one of its faces and leaves by the
// very next surface on the line, a face of a pane material of the same ior
// whose normal is opposite (a parallel face; a glass slab), crossing it the
// other way: the refracted ray leaves in its original direction, so the
// straight ray is exact up to the slab's lateral offset. Its weight is tint_in
// tint_out T^2, T = 1 - F(cos, eta) the exact Fresnel transmission at the entry
// angle (the same at the exit by reciprocity). Anything else stops the ray.
// Photons classify their paths by the same rule (transport/photons/photon_tracer.cpp),
// so no light is counted twice. CSG solids and L-system objects are opaque to
// these rays.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>
#include <vector>

#include "accel/surface_hit.h"
#include "scene/scene.h"
#include "transport/materials/material_table.h"
#include "transport/rays/tracing.h"

namespace plm {

// Two pane faces form a pair when their normals' cosine is below -kPaneParallel (0.8 degrees).
constexpr float kPaneParallel = 0.9999f;

class PassageTracer {
 public:
  PassageTracer(const Scene& scene, const MaterialTable& table, const std::vector<MeshView>& views,
                const SurfaceMap& surfaces, float scene_extent);

  // The passage of a hit's surface (Opaque for all but mesh triangles).
  const MaterialLobes* passable(const SurfaceHit& h) const {
    if (h.kind != SurfaceKind::Triangle) return nullptr;
    const MaterialLobes& m = table_.material(views_[h.index].mesh->material_ids[h.prim]);
    return m.passage == Passage::Opaque ? nullptr : &m;
  }
  // Whether two pane hits (a the entry, b the next surface on the line) form
  // a pair: opposite normals, crossed the other way, the same index.
  static bool pane_pair(Vec3 na, bool front_a, float ior_a, Vec3 nb, bool front_b, float ior_b) {
    return dot(na, nb) < -kPaneParallel && front_a != front_b && ior_a == ior_b;
  }
  // A pane face's transmission (without tint) for a ray of unit direction d
  // entering through the face of unit normal n from its front (eta = ior) or
  // back (eta = 1 / ior).
  static float pane_transmission(const MaterialLobes& m, Vec3 d, Vec3 n, bool front);

  // Traces the packet's lanes as shadow rays (like RayPacket::occluded) and
  // writes each lane's transmittance: 0 where something blocks it, else the
  // product of the passable surfaces' weights. Empties the packet.
  void occluded(RayPacket& packet, RTCScene scene, Vec3 transmittance[RayPacket::kLanes]) const;

  // Continues a ray that hit `first` (a passable surface; origin org,
  // unit direction dir) through passable surfaces: returns the first hit that
  // is not passed (kind None if the ray leaves the scene) and multiplies
  // `weight` by the passages. A pane whose partner is missing is the hit.
  SurfaceHit continue_through(RTCScene scene, SurfaceHit first, Vec3 dir, Vec3& weight) const;

  const SurfaceMap& surfaces() const { return surfaces_; }

 private:
  const MaterialTable& table_;
  const std::vector<MeshView>& views_;
  const SurfaceMap& surfaces_;
  float offset_scale_;
};

}  // namespace plm
