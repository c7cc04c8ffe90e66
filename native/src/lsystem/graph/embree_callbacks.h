// Embree user-geometry callbacks shared by a bare Graph (graph.cpp) and a
// placed LSystemObject (lsystem/lsystem_object.cpp): T provides first_hit(o, d,
// tnear, tfar, GraphHit*) and occluded(o, d, tnear, tfar). A closest-hit
// query's context is a HitContext (util/user_geometry.h): the full hit goes
// into the ray's record there, if it has one.
#pragma once

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>

#include "lsystem/graph/graph.h"
#include "util/user_geometry.h"

namespace plm::lsystem {

// A hit writes tfar, Ng = the OL normal (ol_normal) rounded to float, u =
// ShapeKind, v = 0, primID = the turtle material, and the GraphHit into the
// ray's record (HitContext::graph_hits[ray id]).
template <typename T>
void intersect_n(const RTCIntersectFunctionNArguments* args) {
  const T& obj = *static_cast<const T*>(args->geometryUserPtr);
  const HitContext& context = *reinterpret_cast<const HitContext*>(args->context);
  const unsigned N = args->N;
  RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, N);
  RTCHitN* hits = RTCRayHitN_HitN(args->rayhit, N);
  for (unsigned i = 0; i < N; ++i) {
    if (args->valid[i] == 0) continue;
    const Vec3d o{RTCRayN_org_x(rays, N, i), RTCRayN_org_y(rays, N, i), RTCRayN_org_z(rays, N, i)};
    const Vec3d d{RTCRayN_dir_x(rays, N, i), RTCRayN_dir_y(rays, N, i), RTCRayN_dir_z(rays, N, i)};
    const float tnear = RTCRayN_tnear(rays, N, i), tfar = RTCRayN_tfar(rays, N, i);
    GraphHit h;
    if (!obj.first_hit(o, d, tnear, tfar, &h)) continue;
    const float t = std::fmax(float(h.t), tnear);
    if (!(t <= tfar)) continue;
    RTCRayN_tfar(rays, N, i) = t;
    const Vec3d n = ol_normal(h.n);
    RTCHitN_Ng_x(hits, N, i) = float(n.x);
    RTCHitN_Ng_y(hits, N, i) = float(n.y);
    RTCHitN_Ng_z(hits, N, i) = float(n.z);
    RTCHitN_u(hits, N, i) = float(int(h.shape));
    RTCHitN_v(hits, N, i) = 0.0f;
    RTCHitN_primID(hits, N, i) = unsigned(std::max(h.material, 0));  // turtle materials are >= 0
    RTCHitN_geomID(hits, N, i) = args->geomID;
    RTCHitN_instID(hits, N, i, 0) = args->context->instID[0];
    if (context.graph_hits) context.graph_hits[RTCRayN_id(rays, N, i)] = h;
  }
}

template <typename T>
void occluded_n(const RTCOccludedFunctionNArguments* args) {
  const T& obj = *static_cast<const T*>(args->geometryUserPtr);
  const unsigned N = args->N;
  RTCRayN* rays = args->ray;
  for (unsigned i = 0; i < N; ++i) {
    if (args->valid[i] == 0) continue;
    const Vec3d o{RTCRayN_org_x(rays, N, i), RTCRayN_org_y(rays, N, i), RTCRayN_org_z(rays, N, i)};
    const Vec3d d{RTCRayN_dir_x(rays, N, i), RTCRayN_dir_y(rays, N, i), RTCRayN_dir_z(rays, N, i)};
    if (obj.occluded(o, d, RTCRayN_tnear(rays, N, i), RTCRayN_tfar(rays, N, i))) RTCRayN_tfar(rays, N, i) = -INFINITY;
  }
}

}  // namespace plm::lsystem
