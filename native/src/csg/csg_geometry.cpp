#include "csg/csg_geometry.h"

#include <cmath>

#include "util/user_geometry.h"

namespace plm::csg {
namespace {

// Embree hands packets of at most 16 rays to user geometry callbacks.
constexpr unsigned kMaxPacket = 16;

const CsgObject& object(void* user) { return *static_cast<const CsgObject*>(user); }

void bounds(const RTCBoundsFunctionArguments* args) {
  const CsgObject& obj = object(args->geometryUserPtr);
  write_bounds(obj.bounds_lo(), obj.bounds_hi(), 0.0, args->bounds_o);  // float bounds must contain the double ones
}

struct LaneRay {
  Vec3d o, d;
  float tnear, tfar;
};

LaneRay read_ray(RTCRayN* rays, unsigned N, unsigned i) {
  return {{RTCRayN_org_x(rays, N, i), RTCRayN_org_y(rays, N, i), RTCRayN_org_z(rays, N, i)},
          {RTCRayN_dir_x(rays, N, i), RTCRayN_dir_y(rays, N, i), RTCRayN_dir_z(rays, N, i)},
          RTCRayN_tnear(rays, N, i),
          RTCRayN_tfar(rays, N, i)};
}

void write_hit(RTCHitN* hits, unsigned N, unsigned i, const CsgHit& h, unsigned geom, unsigned inst) {
  RTCHitN_Ng_x(hits, N, i) = float(h.n.x);
  RTCHitN_Ng_y(hits, N, i) = float(h.n.y);
  RTCHitN_Ng_z(hits, N, i) = float(h.n.z);
  RTCHitN_u(hits, N, i) = float(h.face);
  RTCHitN_v(hits, N, i) = h.flipped ? 1.0f : 0.0f;
  RTCHitN_primID(hits, N, i) = h.prim;
  RTCHitN_geomID(hits, N, i) = geom;
  RTCHitN_instID(hits, N, i, 0) = inst;
}

// The ray's t as a float inside [tnear, tfar], or -1 if rounding pushed it out.
float float_t(double t, const LaneRay& r) {
  const float f = std::fmax(float(t), r.tnear);
  return f <= r.tfar ? f : -1.0f;
}

// Calls visit(i, r, crossing, t) for the crossings of each valid lane in ray
// order, t the crossing's float distance, until visit returns true (the lane
// is done) or rounding pushes t out of the ray's [tnear, tfar].
template <typename Visit>
void for_each_crossing(const CsgObject& obj, RTCRayN* rays, const int* valid, unsigned N, Visit&& visit) {
  Crossing buffer[kMaxCrossings];
  for (unsigned i = 0; i < N; ++i) {
    if (valid[i] == 0) continue;
    const LaneRay r = read_ray(rays, N, i);
    const int n = obj.crossings(r.o, r.d, r.tnear, r.tfar, buffer);
    for (int k = 0; k < n; ++k) {
      const float t = float_t(buffer[k].t, r);
      if (t < 0 || visit(i, r, buffer[k], t)) break;
    }
  }
}

// Offers hit h at distance t of lane i to the geometry's filter functions
// (rtcFilterIntersection or rtcFilterOcclusion) as a one-lane candidate packet
// of the ray's width; true if they keep it. Leaves the ray's tfar at t, where
// the filters read the candidate's distance.
template <typename Args>
bool filters_keep(const Args* args, void (*filter)(const Args*, const RTCFilterFunctionNArguments*), RTCRayN* rays,
                  unsigned N, unsigned i, float t, const CsgHit& h) {
  alignas(64) unsigned char storage[sizeof(RTCHit16)];
  RTCHitN* candidate = reinterpret_cast<RTCHitN*>(storage);
  int valid[kMaxPacket] = {};
  valid[i] = -1;
  write_hit(candidate, N, i, h, args->geomID, args->context->instID[0]);
  RTCRayN_tfar(rays, N, i) = t;
  const RTCFilterFunctionNArguments f{valid, args->geometryUserPtr, args->context, rays, candidate, N};
  filter(args, &f);
  return valid[i] != 0;
}

void intersect(const RTCIntersectFunctionNArguments* args) {
  const CsgObject& obj = object(args->geometryUserPtr);
  const unsigned N = args->N;
  RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, N);
  RTCHitN* hits = RTCRayHitN_HitN(args->rayhit, N);
  const unsigned inst = args->context->instID[0];
  for_each_crossing(obj, rays, args->valid, N, [&](unsigned i, const LaneRay& r, const Crossing& c, float t) {
    const CsgHit h = obj.make_hit(c, r.o, r.d);
    if (N > kMaxPacket) {  // never produced by Embree 3; no filters then
      RTCRayN_tfar(rays, N, i) = t;
      write_hit(hits, N, i, h, args->geomID, inst);
      return true;
    }
    if (filters_keep(args, rtcFilterIntersection, rays, N, i, t, h)) {
      write_hit(hits, N, i, h, args->geomID, inst);
      return true;
    }
    RTCRayN_tfar(rays, N, i) = r.tfar;
    return false;
  });
}

void occluded(const RTCOccludedFunctionNArguments* args) {
  const CsgObject& obj = object(args->geometryUserPtr);
  const unsigned N = args->N;
  RTCRayN* rays = args->ray;
  for_each_crossing(obj, rays, args->valid, N, [&](unsigned i, const LaneRay& r, const Crossing& c, float t) {
    bool accepted = true;
    if (N <= kMaxPacket) {  // Embree 3 never gives more; no filters then
      accepted = filters_keep(args, rtcFilterOcclusion, rays, N, i, t, obj.make_hit(c, r.o, r.d));
      RTCRayN_tfar(rays, N, i) = r.tfar;
    }
    if (accepted) RTCRayN_tfar(rays, N, i) = -INFINITY;
    return accepted;
  });
}

}  // namespace

unsigned attach_csg(RTCDevice device, RTCScene scene, const CsgObject& obj) {
  return attach_user_geometry<bounds, intersect, occluded>(device, scene, &obj);
}

}  // namespace plm::csg
