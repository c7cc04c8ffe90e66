// What the photon pass and the direct pass share: the per-mesh view of the
// flat arrays, the ray context that skips the triangle a ray leaves, and the
// origin offset. A ray's hit is read as a SurfaceHit (accel/surface_hit.h).
#pragma once

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "accel/surface_hit.h"
#include "csg/csg_lightmap.h"
#include "scene/scene.h"
#include "util/math.h"

namespace plm {

// Read-only data the hot loops need, flattened at set-up.
struct MeshView {
  const Mesh* mesh;
  uint64_t texel_offset;     // into the global texel arrays
  const double* texel_area;  // world area per texel, null without lightmap
  const Vec3* normals;       // unit geometric normal per triangle; (0, 0, 0) if degenerate
  // Per texel: 1 where another surface may lie pressed against the mesh's
  // front there (contact_candidates); null where none does.
  const uint8_t* contact = nullptr;
  // Per triangle: its material's Burley roughness (the bake weighs arriving
  // light by bsdf::burley_receive), < 0 for Lambert; null where all are Lambert's.
  const float* burley = nullptr;
};

// A CSG solid as the passes see it (Embree geometry id = mesh count + index).
struct CsgView {
  const csg::CsgObject* object;
  const csg::CsgLightmap* lightmap;  // its texels on the primitives' faces; null without a carrier
  uint64_t texel_offset;             // of its sub-texels in the global texel arrays
};

// Unit normals of a mesh's triangles, (0, 0, 0) for degenerate ones.
std::vector<Vec3> triangle_normals(const Mesh& mesh);

// The scene's surfaces with the views' triangle normals.
SurfaceMap surface_map(const Scene& scene, const std::vector<MeshView>& views);

// The texel (row-major, of a width x height lightmap) that barycentric
// (bu, bv) of a triangle with corner UVs uv[0..5] lands in; -1 outside the
// map and for NaN. On [0, width) truncation is the floor (std::floor is a
// libm-like sequence without SSE4.1).
inline int64_t uv_texel(const float* uv, float bu, float bv, uint32_t width, uint32_t height) {
  const float bw = 1.0f - bu - bv;
  const float sx = (bw * uv[0] + bu * uv[2] + bv * uv[4]) * float(width);
  const float sy = (bw * uv[1] + bu * uv[3] + bv * uv[5]) * float(height);
  if (!(sx >= 0.0f && sy >= 0.0f && sx < float(width) && sy < float(height))) return -1;
  return int64_t(uint64_t(sy) * width + uint64_t(sx));
}

// The texel of a hit at barycentric (bu, bv) of a triangle (corner UVs uv),
// as uv_texel, where `area` (world area per texel) says the texel is covered.
// A hit on the triangle's edge where that edge lies on a texel boundary may
// round into the uncovered texel beyond it: then the texel of the point
// moved a little towards the triangle's centroid, which the triangle covers.
// -1 where no covered texel is found (a triangle without UV area).
inline int64_t covered_uv_texel(const float* uv, float bu, float bv, uint32_t width, uint32_t height,
                                const double* area) {
  int64_t t = uv_texel(uv, bu, bv, width, height);
  if (t >= 0 && area[t] > 0.0) return t;
  for (const float s : {1e-4f, 1e-3f, 1e-2f, 1e-1f, 1.0f}) {
    t = uv_texel(uv, bu + s * (1.0f / 3.0f - bu), bv + s * (1.0f / 3.0f - bv), width, height);
    if (t >= 0 && area[t] > 0.0) return t;
  }
  return -1;
}

// Geometry ids of the triangles to skip: SurfaceMap::mesh_geometry(mesh).
struct TraceContext {
  HitContext hits;  // first member: Embree hands back a pointer to its context
  unsigned skip_geom = RTC_INVALID_GEOMETRY_ID;  // the triangle the ray leaves
  unsigned skip_prim = RTC_INVALID_GEOMETRY_ID;
  unsigned target_geom = RTC_INVALID_GEOMETRY_ID;  // the emitting triangle a shadow ray aims at
  unsigned target_prim = RTC_INVALID_GEOMETRY_ID;
  TraceContext();
  RTCIntersectContext* context() { return &hits.context; }
};

// How far a ray origin leaves the surface at p: beyond the rounding of p's
// coordinates. (std::max, not max_abs_component's fmaxf call: p is finite,
// and a NaN gives NaN either way.)
inline float offset_distance(Vec3 p, float offset_scale) {
  const float m = std::max(std::fabs(p.x), std::max(std::fabs(p.y), std::fabs(p.z)));
  return offset_scale + 2.5e-7f * m;
}

// Ray origin just off the surface at p on the side of unit normal n.
inline Vec3 offset_origin(Vec3 p, Vec3 n, float offset_scale) { return p + n * offset_distance(p, offset_scale); }

// Whether point p of triangle prim of a mesh, unit geometric normal n, lies
// pressed against another surface, which its rays' origin offset would jump
// over: a surface facing p within twice the offset distance on either side of
// p, or one facing away from p (its back towards p) in front of p beyond the
// rounding of p's coordinates and within twice the offset. Such a point gets
// no light, as in Cycles, whose rays leave the surface itself and meet the
// other surface at once: the bottom of a box standing on the floor, the floor
// under it, the top of a column touching the ceiling. A box standing a little
// above the floor is not in contact, nor are two faces in one plane facing
// the same way (a duplicated object: both are lit).
bool in_contact(RTCScene scene, const SurfaceMap& surfaces, Vec3 p, Vec3 n, uint32_t mesh, uint32_t prim,
                float offset_scale);

// Per mesh, per lightmap texel: 1 where in_contact can be true (another
// mesh triangle nearly parallel to one of the texel's triangles lies within a
// few offset distances of its plane and overlaps it there), so that only those
// texels pay for the contact ray. CSG solids and L-system objects are not
// searched: a point a ray offset puts inside one meets its inside surface.
// Empty vectors for meshes without own texels (own_texels) or without such
// texels.
std::vector<std::vector<uint8_t>> contact_candidates(RTCScene scene, const Scene& s, const std::vector<MeshView>& views,
                                                     const SurfaceMap& surfaces, float offset_scale);

inline RTCRay make_ray(Vec3 org, Vec3 dir, float tfar) {
  RTCRay r;
  r.org_x = org.x;
  r.org_y = org.y;
  r.org_z = org.z;
  r.dir_x = dir.x;
  r.dir_y = dir.y;
  r.dir_z = dir.z;
  r.tnear = 0.0f;
  r.tfar = tfar;
  r.time = 0.0f;
  r.mask = 0xFFFFFFFFu;
  r.id = 0;
  r.flags = 0;
  return r;
}

// Rays traced eight at a time (rtcOccluded8 / rtcIntersect8). The direct
// pass's shadow rays and the final gather's rays leave one texel: shadow rays
// to one light cost ~1.8x less as a packet than one by one, gather rays a few
// per cent less (BM_TexelRaysOneByOneVersusPackets). Each lane skips its own
// origin and target triangles: the filter finds a lane's by the ray's id.
struct RayPacket {
  static constexpr unsigned kLanes = 8;
  HitContext hits;  // first member: Embree hands back a pointer to its context
  unsigned skip_geom[kLanes], skip_prim[kLanes], target_geom[kLanes], target_prim[kLanes];
  RTCRayHit8 rh;
  unsigned size = 0;  // lanes added since the last trace
  RayPacket();
  bool full() const { return size == kLanes; }
  // A ray from org towards dir up to tfar (may be infinite) in the next lane.
  void add(Vec3 org, Vec3 dir, float tfar, unsigned skip_g, unsigned skip_p,
           unsigned target_g = RTC_INVALID_GEOMETRY_ID, unsigned target_p = RTC_INVALID_GEOMETRY_ID) {
    const unsigned i = size++;
    RTCRay8& r = rh.ray;
    r.org_x[i] = org.x, r.org_y[i] = org.y, r.org_z[i] = org.z;
    r.dir_x[i] = dir.x, r.dir_y[i] = dir.y, r.dir_z[i] = dir.z;
    r.tnear[i] = 0.0f, r.tfar[i] = tfar, r.time[i] = 0.0f;
    r.mask[i] = 0xFFFFFFFFu, r.id[i] = i, r.flags[i] = 0;
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    skip_geom[i] = skip_g, skip_prim[i] = skip_p, target_geom[i] = target_g, target_prim[i] = target_p;
  }
  // Trace the lanes added, then empty the packet (their results stay until
  // the next add): lane i is occluded if blocked(i); hits are in rh
  // (SurfaceMap::hit(rh, i)).
  void occluded(RTCScene scene);
  // skip_lanes: bit i set leaves lane i untraced (its hit stays none).
  void intersect(RTCScene scene, uint32_t skip_lanes = 0);
  bool blocked(unsigned i) const { return rh.ray.tfar[i] < 0.0f; }
};

}  // namespace plm
