// One Embree user geometry over an object of ours: the CSG solids and the
// L-system objects attach themselves through this.
//
// The geometry has two primitives: primitive 0 is the object (its box),
// primitive 1 a sentinel, a point box at the object's lower corner whose
// callbacks return at once. With one primitive the geometry's BVH is a single
// leaf, and Embree tests no box before a leaf that is the root of its BVH: the
// callbacks ran for every ray of the scene (one L-system tree in the bake of
// docs/benchmarks.md: 2.33 M calls, 1.83 M of them for rays that miss the
// tree's box). With two, the root is an inner node whose box test culls them.
#pragma once

#include <embree3/rtcore.h>

#include <cmath>

namespace plm {

constexpr unsigned kObjectPrimitive = 0;  // callbacks for any other primitive return at once

// Bounds of primitive args->primID: the object's [lo - pad, hi + pad]
// rounded outwards to float, or the sentinel's point at lo. An empty box
// (lo > hi) becomes one Embree skips, for both. V has double x, y, z.
template <typename V>
void write_user_bounds(const RTCBoundsFunctionArguments* args, V lo, V hi, double pad) {
  RTCBounds* b = args->bounds_o;
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) {  // nothing there
    b->lower_x = b->lower_y = b->lower_z = INFINITY;
    b->upper_x = b->upper_y = b->upper_z = -INFINITY;
    return;
  }
  if (args->primID != kObjectPrimitive) hi = lo, pad = 0.0;
  b->lower_x = std::nextafter(float(lo.x - pad), -INFINITY);
  b->lower_y = std::nextafter(float(lo.y - pad), -INFINITY);
  b->lower_z = std::nextafter(float(lo.z - pad), -INFINITY);
  b->upper_x = std::nextafter(float(hi.x + pad), INFINITY);
  b->upper_y = std::nextafter(float(hi.y + pad), INFINITY);
  b->upper_z = std::nextafter(float(hi.z + pad), INFINITY);
}

// Attaches a user geometry (the object and its sentinel) whose callbacks
// receive `object` as their user pointer; returns its geometry id. The object
// is referenced, not copied.
inline unsigned attach_user_geometry(RTCDevice device, RTCScene scene, const void* object, RTCBoundsFunction bounds,
                                     RTCIntersectFunctionN intersect, RTCOccludedFunctionN occluded) {
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
  rtcSetGeometryUserPrimitiveCount(geom, 2);
  rtcSetGeometryUserData(geom, const_cast<void*>(object));
  rtcSetGeometryBoundsFunction(geom, bounds, nullptr);
  rtcSetGeometryIntersectFunction(geom, intersect);
  rtcSetGeometryOccludedFunction(geom, occluded);
  rtcCommitGeometry(geom);
  const unsigned id = rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  return id;
}

}  // namespace plm
