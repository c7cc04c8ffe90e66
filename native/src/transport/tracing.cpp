#include "transport/tracing.h"

namespace plm {
namespace {

// A ray never hits the flat triangle it leaves: rejecting that one triangle
// removes self-intersection at any angle, so the origin offset can stay tiny.
// A shadow ray towards a point on an emitting triangle likewise ignores that
// triangle, which float rounding far from the origin could otherwise hit.
void skip_origin_triangle(const RTCFilterFunctionNArguments* args) {
  const auto* tc = reinterpret_cast<const TraceContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    const unsigned geom = RTCHitN_geomID(args->hit, args->N, i), prim = RTCHitN_primID(args->hit, args->N, i);
    if ((geom == tc->skip_geom && prim == tc->skip_prim) || (geom == tc->target_geom && prim == tc->target_prim))
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

}  // namespace plm
