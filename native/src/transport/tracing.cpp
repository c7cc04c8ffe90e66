#include "transport/tracing.h"

namespace plm {
namespace {

// A ray never hits the flat triangle it leaves: rejecting that one triangle
// removes self-intersection at any angle, so the origin offset can stay tiny.
// A shadow ray towards a point on an emitting triangle likewise ignores that
// triangle, which float rounding far from the origin could otherwise hit.
bool skipped(unsigned geom, unsigned prim, unsigned skip_g, unsigned skip_p, unsigned target_g, unsigned target_p) {
  return (geom == skip_g && prim == skip_p) || (geom == target_g && prim == target_p);
}

void skip_origin_triangle(const RTCFilterFunctionNArguments* args) {
  const auto* tc = reinterpret_cast<const TraceContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != 0 && skipped(RTCHitN_geomID(args->hit, args->N, i), RTCHitN_primID(args->hit, args->N, i),
                                       tc->skip_geom, tc->skip_prim, tc->target_geom, tc->target_prim))
      args->valid[i] = 0;
  }
}

// The same for a RayPacket: the ray's id is its lane.
void skip_lane_triangles(const RTCFilterFunctionNArguments* args) {
  const auto* pk = reinterpret_cast<const RayPacket*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    const unsigned lane = RTCRayN_id(args->ray, args->N, i) % RayPacket::kLanes;
    if (skipped(RTCHitN_geomID(args->hit, args->N, i), RTCHitN_primID(args->hit, args->N, i), pk->skip_geom[lane],
                pk->skip_prim[lane], pk->target_geom[lane], pk->target_prim[lane]))
      args->valid[i] = 0;
  }
}

}  // namespace

std::vector<Vec3> triangle_normals(const Mesh& mesh) {
  std::vector<Vec3> normals(mesh.triangle_count());
  for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3 p0 = mesh.vertex(t, 0), p1 = mesh.vertex(t, 1), p2 = mesh.vertex(t, 2);
    if (!degenerate_triangle(p0, p1, p2)) normals[t] = normalize(cross(p1 - p0, p2 - p0));
  }
  return normals;
}

TraceContext::TraceContext() {
  rtcInitIntersectContext(&context);
  context.filter = skip_origin_triangle;
}

RayPacket::RayPacket() {
  rtcInitIntersectContext(&context);
  context.filter = skip_lane_triangles;
}

void RayPacket::occluded(RTCScene scene) {
  alignas(32) int valid[kLanes];
  for (unsigned i = 0; i < kLanes; ++i) valid[i] = i < size ? -1 : 0;
  rtcOccluded8(valid, scene, &context, &rh.ray);
  size = 0;
}

void RayPacket::intersect(RTCScene scene) {
  alignas(32) int valid[kLanes];
  for (unsigned i = 0; i < kLanes; ++i) valid[i] = i < size ? -1 : 0;
  rtcIntersect8(valid, scene, &context, &rh);
  size = 0;
}

}  // namespace plm
