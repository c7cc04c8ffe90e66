// One Embree user geometry over an object of ours: the CSG solids and the
// L-system objects attach themselves through this. A closest-hit query's
// context is a HitContext, through which a callback hands back more than
// Embree's hit record holds (an L-system object's GraphHit).
//
// The geometry has two primitives: primitive 0 is the object (its box),
// primitive 1 a sentinel, a point box at the object's lower corner whose
// callbacks return at once. With one primitive the geometry's BVH is a single
// leaf, and Embree tests no box before a leaf that is the root of its BVH: the
// callbacks ran for every ray of the scene (one L-system tree in the bake of
// docs/benchmarks/geometry.md: 2.33 M calls, 1.83 M of them for rays that miss the
// tree's box). With two, the root is an inner node whose box test culls them.
// The sentinel lives here alone: the object's callbacks never see it.
#pragma once

#include <embree3/rtcore.h>

#include <cmath>

namespace plm {

namespace lsystem {
struct GraphHit;
}

// Bounds [lo - pad, hi + pad] rounded outwards to float (V has double x, y,
// z); an empty box (lo > hi) becomes one Embree skips.
template <typename V>
void write_bounds(V lo, V hi, double pad, RTCBounds* b) {
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) {  // nothing there
    b->lower_x = b->lower_y = b->lower_z = INFINITY;
    b->upper_x = b->upper_y = b->upper_z = -INFINITY;
    return;
  }
  b->lower_x = std::nextafter(float(lo.x - pad), -INFINITY);
  b->lower_y = std::nextafter(float(lo.y - pad), -INFINITY);
  b->lower_z = std::nextafter(float(lo.z - pad), -INFINITY);
  b->upper_x = std::nextafter(float(hi.x + pad), INFINITY);
  b->upper_y = std::nextafter(float(hi.y + pad), INFINITY);
  b->upper_z = std::nextafter(float(hi.z + pad), INFINITY);
}

// The intersect context of every closest-hit query on a scene that may hold
// L-system objects (their callbacks read it); occlusion queries may use a
// plain RTCIntersectContext. Contexts that carry more (transport/rays/tracing.h)
// hold it as their first member.
struct HitContext {
  RTCIntersectContext context;  // first member: Embree hands back this pointer
  // Per ray, indexed by the ray's id: the GraphHit of the nearest L-system
  // hit so far (valid where the ray's final hit is an L-system object's);
  // null: the caller needs no more of an L-system hit than its kind.
  lsystem::GraphHit* graph_hits = nullptr;
  HitContext() { rtcInitIntersectContext(&context); }
};

namespace user_geometry_detail {

// The object's callbacks run for primitive 0 only; the sentinel's box is the
// point at the object's lower corner (an empty object leaves both empty).
template <RTCBoundsFunction Bounds>
void bounds(const RTCBoundsFunctionArguments* args) {
  Bounds(args);
  RTCBounds* b = args->bounds_o;
  if (args->primID != 0 && b->lower_x <= b->upper_x)
    b->upper_x = b->lower_x, b->upper_y = b->lower_y, b->upper_z = b->lower_z;
}
template <RTCIntersectFunctionN Intersect>
void intersect(const RTCIntersectFunctionNArguments* args) {
  if (args->primID == 0) Intersect(args);
}
template <RTCOccludedFunctionN Occluded>
void occluded(const RTCOccludedFunctionNArguments* args) {
  if (args->primID == 0) Occluded(args);
}

}  // namespace user_geometry_detail

// Attaches a user geometry (the object and its sentinel) whose callbacks
// receive `object` as their user pointer; returns its geometry id. The object
// is referenced, not copied.
template <RTCBoundsFunction Bounds, RTCIntersectFunctionN Intersect, RTCOccludedFunctionN Occluded>
unsigned attach_user_geometry(RTCDevice device, RTCScene scene, const void* object) {
  namespace d = user_geometry_detail;
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
  rtcSetGeometryUserPrimitiveCount(geom, 2);
  rtcSetGeometryUserData(geom, const_cast<void*>(object));
  rtcSetGeometryBoundsFunction(geom, d::bounds<Bounds>, nullptr);
  rtcSetGeometryIntersectFunction(geom, d::intersect<Intersect>);
  rtcSetGeometryOccludedFunction(geom, d::occluded<Occluded>);
  rtcCommitGeometry(geom);
  const unsigned id = rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  return id;
}

}  // namespace plm
