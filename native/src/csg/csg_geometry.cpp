#include "csg/csg_geometry.h"

#include <cmath>

#include "accel/user_geometry.h"

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

void intersect(const RTCIntersectFunctionNArguments* args) {
  const CsgObject& obj = object(args->geometryUserPtr);
  const unsigned N = args->N;
  RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, N);
  RTCHitN* hits = RTCRayHitN_HitN(args->rayhit, N);
  const unsigned inst = args->context->instID[0];
  Crossing buffer[kMaxCrossings];
  for (unsigned i = 0; i < N; ++i) {
    if (args->valid[i] == 0) continue;
    const LaneRay r = read_ray(rays, N, i);
    const int n = obj.crossings(r.o, r.d, r.tnear, r.tfar, buffer);
    for (int k = 0; k < n; ++k) {
      const float t = float_t(buffer[k].t, r);
      if (t < 0) break;
      const CsgHit h = obj.make_hit(buffer[k], r.o, r.d);
      if (N > kMaxPacket) {  // never produced by Embree 3; no filters then
        RTCRayN_tfar(rays, N, i) = t;
        write_hit(hits, N, i, h, args->geomID, inst);
        break;
      }
      // A one-lane candidate packet of the ray's width for the filters.
      alignas(64) unsigned char storage[sizeof(RTCHit16)];
      RTCHitN* candidate = reinterpret_cast<RTCHitN*>(storage);
      int valid[kMaxPacket] = {};
      valid[i] = -1;
      write_hit(candidate, N, i, h, args->geomID, inst);
      RTCRayN_tfar(rays, N, i) = t;  // filters read the candidate's distance from the ray
      const RTCFilterFunctionNArguments f{valid, args->geometryUserPtr, args->context, rays, candidate, N};
      rtcFilterIntersection(args, &f);
      if (valid[i] != 0) {
        write_hit(hits, N, i, h, args->geomID, inst);
        break;
      }
      RTCRayN_tfar(rays, N, i) = r.tfar;
    }
  }
}

void occluded(const RTCOccludedFunctionNArguments* args) {
  const CsgObject& obj = object(args->geometryUserPtr);
  const unsigned N = args->N;
  RTCRayN* rays = args->ray;
  const unsigned inst = args->context->instID[0];
  Crossing buffer[kMaxCrossings];
  for (unsigned i = 0; i < N; ++i) {
    if (args->valid[i] == 0) continue;
    const LaneRay r = read_ray(rays, N, i);
    const int n = obj.crossings(r.o, r.d, r.tnear, r.tfar, buffer);
    for (int k = 0; k < n; ++k) {
      const float t = float_t(buffer[k].t, r);
      if (t < 0) break;
      bool accepted = true;
      if (N <= kMaxPacket) {
        alignas(64) unsigned char storage[sizeof(RTCHit16)];
        RTCHitN* candidate = reinterpret_cast<RTCHitN*>(storage);
        int valid[kMaxPacket] = {};
        valid[i] = -1;
        write_hit(candidate, N, i, obj.make_hit(buffer[k], r.o, r.d), args->geomID, inst);
        RTCRayN_tfar(rays, N, i) = t;
        const RTCFilterFunctionNArguments f{valid, args->geometryUserPtr, args->context, rays, candidate, N};
        rtcFilterOcclusion(args, &f);
        accepted = valid[i] != 0;
        RTCRayN_tfar(rays, N, i) = r.tfar;
      }
      if (accepted) {
        RTCRayN_tfar(rays, N, i) = -INFINITY;
        break;
      }
    }
  }
}

}  // namespace

unsigned attach_csg(RTCDevice device, RTCScene scene, const CsgObject& obj) {
  return attach_user_geometry<bounds, intersect, occluded>(device, scene, &obj);
}

}  // namespace plm::csg
