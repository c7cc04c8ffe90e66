// What a ray met, as the passes read it: one record per hit (SurfaceHit),
// built in one place (SurfaceMap::hit) from Embree's answer, as Mitsuba 3's
// Embree wrapper maps a geometry id to its shape and fills the surface
// interaction there (pbrt-v4's SurfaceInteraction is the same idea). The
// passes switch on the record's kind; only this file knows how geometry ids
// are laid out (accel/embree_scene.h).
//
// L-system hits carry more than Embree's hit holds (the instance hit, for
// its OL stub): the object's intersect callback writes its GraphHit into the
// ray's record in the HitContext the ray is traced with (util/user_geometry.h),
// and SurfaceMap::hit reads it from there.
#pragma once

#include <embree3/rtcore.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "scene/scene.h"
#include "util/math.h"
#include "util/user_geometry.h"

namespace plm {

enum class SurfaceKind : uint8_t {
  None,      // the ray met nothing
  Triangle,  // a mesh triangle
  CsgFace,   // the exact surface of a CSG solid: a face of one of its primitives
  LSystem,   // a primitive of an L-system object
};

struct SurfaceHit {
  SurfaceKind kind = SurfaceKind::None;
  uint32_t index = 0;  // the mesh, CSG solid or L-system object
  uint32_t prim = 0;   // the triangle, or the CSG primitive whose face was crossed
  float u = 0, v = 0;  // a triangle's barycentrics of corners 1 and 2
  uint32_t face = 0;   // the CSG primitive's face
  float t = 0;         // the ray parameter of the hit
  Vec3 point;          // a triangle's corners interpolated at (u, v); otherwise origin + t direction
  // Unit geometric normal, not turned towards the ray: a triangle's from its
  // mesh's normal table ((0, 0, 0) if degenerate), a CSG solid's pointing
  // out of it, an L-system primitive's outward (not finite: no usable hit).
  Vec3 normal;
  // CSG solids, and L-system objects with the ray's GraphHit: the scene
  // material at the hit.
  uint32_t material = 0;
  // L-system objects, with the ray's GraphHit: the normal as OL bins take
  // it (lsystem::ol_normal, in double) and the stub key of the instance hit
  // (LSystemObject::stub_key).
  Vec3d ol_normal;
  uint64_t stub_key = 0;
};

// Embree geometry ids -> the scene's surfaces, and the one place hit
// records are made. Holds pointers into the Scene and the normal tables.
class SurfaceMap {
 public:
  SurfaceMap() = default;
  // normals[m]: mesh m's unit triangle normals, triangle t's at
  // normals[m] + t * normal_stride bytes (a table of Vec3, or a field of a
  // larger per-triangle record).
  SurfaceMap(const Scene& scene, const std::vector<const Vec3*>& normals, size_t normal_stride = sizeof(Vec3));

  // The kind of surface that geometry `geom` (a valid id) is, and its
  // mesh, solid or object: for ids met outside a hit (point queries).
  SurfaceKind kind(unsigned geom) const {
    return geom < mesh_count_ ? SurfaceKind::Triangle
           : geom < lsystem_base_ ? SurfaceKind::CsgFace : SurfaceKind::LSystem;
  }
  uint32_t index(unsigned geom, SurfaceKind k) const {
    return k == SurfaceKind::CsgFace ? uint32_t(geom - mesh_count_)
           : k == SurfaceKind::LSystem ? uint32_t(geom - lsystem_base_) : uint32_t(geom);
  }
  // Where a mesh is an Embree geometry (to skip its triangles in filters).
  static unsigned mesh_geometry(uint32_t mesh) { return mesh; }

  // The record of a closest hit (kind None for a miss). graph: the ray's
  // GraphHit (HitContext::graph_hits), or null where L-system detail is not
  // wanted. kMeshesOnly: the scene holds meshes only (no range tests).
  template <bool kMeshesOnly = false>
  SurfaceHit hit(const RTCRayHit& rh, const lsystem::GraphHit* graph = nullptr) const {
    return make<kMeshesOnly>(OneRay{rh}, graph);
  }
  // Lane `lane` of a packet's closest hits.
  SurfaceHit hit(const RTCRayHit8& rh, unsigned lane) const { return make<false>(PacketLane{rh, lane}, nullptr); }
  // Lane i of a filter function's candidate hit (its distance is the ray's tfar).
  SurfaceHit candidate(const RTCFilterFunctionNArguments* args, unsigned i) const {
    return make<false>(FilterLane{args->hit, args->ray, args->N, i}, nullptr);
  }

 private:
  struct MeshEntry {
    const Vec3* positions;
    const uint32_t* indices;
    const unsigned char* normals;  // triangle t's at normals + t * normal_stride_
  };
  // What an L-system hit adds from its GraphHit (out of line: a few calls into the object).
  struct LSystemDetail {
    Vec3d ol_normal;
    uint32_t material;
    uint64_t stub_key;
  };
  LSystemDetail lsystem_detail(uint32_t object, const lsystem::GraphHit& graph) const;

  // Embree's answer in its three layouts, read field by field where make
  // needs a field (a lane's field of a packet costs an index computation).
  struct OneRay {
    const RTCRayHit& rh;
    unsigned geom() const { return rh.hit.geomID; }
    unsigned prim() const { return rh.hit.primID; }
    float u() const { return rh.hit.u; }
    float v() const { return rh.hit.v; }
    Vec3 ng() const { return {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z}; }
    float t() const { return rh.ray.tfar; }
    Vec3 org() const { return {rh.ray.org_x, rh.ray.org_y, rh.ray.org_z}; }
    Vec3 dir() const { return {rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z}; }
  };
  struct PacketLane {
    const RTCRayHit8& rh;
    unsigned l;
    unsigned geom() const { return rh.hit.geomID[l]; }
    unsigned prim() const { return rh.hit.primID[l]; }
    float u() const { return rh.hit.u[l]; }
    float v() const { return rh.hit.v[l]; }
    Vec3 ng() const { return {rh.hit.Ng_x[l], rh.hit.Ng_y[l], rh.hit.Ng_z[l]}; }
    float t() const { return rh.ray.tfar[l]; }
    Vec3 org() const { return {rh.ray.org_x[l], rh.ray.org_y[l], rh.ray.org_z[l]}; }
    Vec3 dir() const { return {rh.ray.dir_x[l], rh.ray.dir_y[l], rh.ray.dir_z[l]}; }
  };
  struct FilterLane {
    RTCHitN* h;
    RTCRayN* r;
    unsigned n, i;
    unsigned geom() const { return RTCHitN_geomID(h, n, i); }
    unsigned prim() const { return RTCHitN_primID(h, n, i); }
    float u() const { return RTCHitN_u(h, n, i); }
    float v() const { return RTCHitN_v(h, n, i); }
    Vec3 ng() const { return {RTCHitN_Ng_x(h, n, i), RTCHitN_Ng_y(h, n, i), RTCHitN_Ng_z(h, n, i)}; }
    float t() const { return RTCRayN_tfar(r, n, i); }
    Vec3 org() const { return {RTCRayN_org_x(r, n, i), RTCRayN_org_y(r, n, i), RTCRayN_org_z(r, n, i)}; }
    Vec3 dir() const { return {RTCRayN_dir_x(r, n, i), RTCRayN_dir_y(r, n, i), RTCRayN_dir_z(r, n, i)}; }
  };

  // Inline: callers that read few fields let the compiler drop the rest.
  template <bool kMeshesOnly, typename Embree>
  SurfaceHit make(const Embree& e, const lsystem::GraphHit* graph) const {
    const unsigned geom = e.geom();
    if (geom == RTC_INVALID_GEOMETRY_ID) return SurfaceHit{};
    SurfaceHit s;
    s.prim = e.prim();
    s.t = e.t();
    if (kMeshesOnly || geom < mesh_count_) {
      s.kind = SurfaceKind::Triangle;
      s.index = geom;
      const MeshEntry& m = meshes_[geom];
      const float u = e.u(), v = e.v();
      s.u = u, s.v = v;
      const uint32_t* ix = m.indices + 3 * size_t(s.prim);
      s.point = m.positions[ix[0]] * (1.0f - u - v) + m.positions[ix[1]] * u + m.positions[ix[2]] * v;
      const Vec3& n = *reinterpret_cast<const Vec3*>(m.normals + size_t(s.prim) * normal_stride_);
      s.normal.x = n.x, s.normal.y = n.y, s.normal.z = n.z;
    } else if (geom < lsystem_base_) {  // u: the face id, an integer-valued float (csg/csg_geometry.h)
      s.kind = SurfaceKind::CsgFace;
      s.index = uint32_t(geom - mesh_count_);
      s.face = uint32_t(e.u());
      s.point = e.org() + e.dir() * s.t;
      s.normal = normalize(e.ng());
      s.material = csgs_[s.index]->material(s.prim);
    } else {  // Ng: the OL normal rounded to float (lsystem/graph/embree_callbacks.h)
      s.kind = SurfaceKind::LSystem;
      s.index = uint32_t(geom - lsystem_base_);
      s.point = e.org() + e.dir() * s.t;
      s.normal = e.ng();
      if (graph) {
        const LSystemDetail d = lsystem_detail(s.index, *graph);
        s.ol_normal = d.ol_normal;
        s.material = d.material;
        s.stub_key = d.stub_key;
      }
    }
    return s;
  }

  std::vector<MeshEntry> meshes_;  // per mesh: geometry id = mesh index
  size_t mesh_count_ = 0;
  std::vector<const csg::CsgObject*> csgs_;  // geometry id = mesh count + solid index
  std::vector<const lsystem::LSystemObject*> lsystems_;  // geometry id = lsystem_base_ + object index
  size_t lsystem_base_ = 0;
  size_t normal_stride_ = sizeof(Vec3);
};

}  // namespace plm
