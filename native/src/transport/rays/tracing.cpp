#include "transport/rays/tracing.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>

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

// The contact ray of in_contact: it skips its own triangle, and a surface
// whose back faces the ray counts only from back_t_min on.
struct ContactContext {
  RTCIntersectContext context;  // first member: Embree hands back this pointer
  const SurfaceMap* surfaces;
  unsigned skip_geom, skip_prim;  // the triangle the ray leaves
  Vec3 dir;
  float back_t_min;
};

void contact_filter(const RTCFilterFunctionNArguments* args) {
  const auto* cc = reinterpret_cast<const ContactContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    if (skipped(RTCHitN_geomID(args->hit, args->N, i), RTCHitN_primID(args->hit, args->N, i), cc->skip_geom,
                cc->skip_prim, RTC_INVALID_GEOMETRY_ID, RTC_INVALID_GEOMETRY_ID)) {
      args->valid[i] = 0;
      continue;
    }
    const SurfaceHit h = cc->surfaces->candidate(args, i);
    if (dot(h.normal, cc->dir) >= 0.0f && h.t < cc->back_t_min) args->valid[i] = 0;
  }
}

// Whether 2D triangles a and b (x, y pairs) overlap by more than tol along
// every separating axis (their edges' normals): touching edges do not count.
bool triangles_overlap(const float a[6], const float b[6], float tol) {
  for (int k = 0; k < 6; ++k) {
    const float* t = k < 3 ? a : b;
    const int e = k % 3, f = (e + 1) % 3;
    float ax = t[2 * f + 1] - t[2 * e + 1], ay = t[2 * e] - t[2 * f];
    const float len = std::sqrt(ax * ax + ay * ay);
    if (!(len > 0.0f)) continue;
    ax /= len, ay /= len;
    float lo_a = INFINITY, hi_a = -INFINITY, lo_b = INFINITY, hi_b = -INFINITY;
    for (int c = 0; c < 3; ++c) {
      const float pa = a[2 * c] * ax + a[2 * c + 1] * ay, pb = b[2 * c] * ax + b[2 * c + 1] * ay;
      lo_a = std::min(lo_a, pa), hi_a = std::max(hi_a, pa), lo_b = std::min(lo_b, pb), hi_b = std::max(hi_b, pb);
    }
    if (std::min(hi_a, hi_b) - std::max(lo_a, lo_b) <= tol) return false;
  }
  return true;
}

// A rectangle of texels [x0, x1) x [y0, y1) of one mesh's lightmap.
struct TexelRect {
  int32_t x0, y0, x1, y1;
};

// One triangle's search for contact partners (contact_candidates): the
// texels of its lightmap that a partner may press against.
struct ContactQuery {
  const std::vector<MeshView>* views;
  const SurfaceMap* surfaces;
  const Mesh* mesh;  // the triangle's
  uint32_t mesh_index, prim;
  Vec3 origin, n, t, b;  // the triangle's vertex 0 and frame
  float tri2d[6];        // its corners in the frame
  float uv[6];           // its lightmap UVs, in texels
  TexelRect own;         // the texels its UVs reach
  float slab;            // how far from its plane a partner may lie
  float tol;             // overlap below this is touching
  std::vector<TexelRect>* rects;
};

// The texels of q's triangle under a partner whose corners are other[] in the
// triangle's frame: the box of the partner's corners mapped through the
// triangle's UVs, clipped to the triangle's own texels, one texel wider.
TexelRect partner_texels(const ContactQuery& q, const float other[6]) {
  const float* a = q.tri2d;
  const float e1x = a[2] - a[0], e1y = a[3] - a[1], e2x = a[4] - a[0], e2y = a[5] - a[1];
  const float det = e1x * e2y - e2x * e1y;
  if (!(std::fabs(det) > 0.0f)) return q.own;
  float lo_u = INFINITY, hi_u = -INFINITY, lo_v = INFINITY, hi_v = -INFINITY;
  for (int c = 0; c < 3; ++c) {
    const float dx = other[2 * c] - a[0], dy = other[2 * c + 1] - a[1];
    const float b1 = (dx * e2y - e2x * dy) / det, b2 = (e1x * dy - dx * e1y) / det, b0 = 1.0f - b1 - b2;
    const float u = b0 * q.uv[0] + b1 * q.uv[2] + b2 * q.uv[4], v = b0 * q.uv[1] + b1 * q.uv[3] + b2 * q.uv[5];
    lo_u = std::min(lo_u, u), hi_u = std::max(hi_u, u), lo_v = std::min(lo_v, v), hi_v = std::max(hi_v, v);
  }
  auto clampi = [](float x, int32_t lo, int32_t hi) {
    return x != x ? lo : int32_t(std::clamp(x, float(lo), float(hi)));
  };
  return {clampi(std::floor(lo_u) - 1.0f, q.own.x0, q.own.x1), clampi(std::floor(lo_v) - 1.0f, q.own.y0, q.own.y1),
          clampi(std::floor(hi_u) + 2.0f, q.own.x0, q.own.x1), clampi(std::floor(hi_v) + 2.0f, q.own.y0, q.own.y1)};
}

bool contact_query(RTCPointQueryFunctionArguments* args) {
  auto* q = static_cast<ContactQuery*>(args->userPtr);
  const SurfaceKind kind = q->surfaces->kind(args->geomID);
  // CSG solids and L-system objects: meshes press against meshes
  if (kind != SurfaceKind::Triangle) return false;
  const uint32_t mesh = q->surfaces->index(args->geomID, kind), prim = args->primID;
  if (mesh == q->mesh_index) {  // the triangle itself and its neighbours in the mesh cannot lie on it
    const uint32_t* a = &q->mesh->indices[3 * size_t(q->prim)];
    const uint32_t* b = &q->mesh->indices[3 * size_t(prim)];
    for (int i = 0; i < 3; ++i)
      if (a[i] == b[0] || a[i] == b[1] || a[i] == b[2]) return false;
  }
  const Vec3 n2 = (*q->views)[mesh].normals[prim];
  if (std::fabs(dot(n2, q->n)) < 0.99f) return false;  // not lying flat against it
  const Mesh& m = *(*q->views)[mesh].mesh;
  float other[6], lo = INFINITY, hi = -INFINITY;
  for (int c = 0; c < 3; ++c) {
    const Vec3 d = m.vertex(prim, c) - q->origin;
    const float h = dot(d, q->n);
    lo = std::min(lo, h), hi = std::max(hi, h);
    other[2 * c] = dot(d, q->t), other[2 * c + 1] = dot(d, q->b);
  }
  // Pressed flat: the whole partner within the slab. A partner that only
  // touches it (a sphere's pole fan on the ground, tilted away from the
  // touching point) is seen by the offset rays like any other surface.
  if (lo < -q->slab || hi > q->slab || !triangles_overlap(q->tri2d, other, q->tol)) return false;
  q->rects->push_back(partner_texels(*q, other));
  return false;
}

}  // namespace

bool in_contact(RTCScene scene, const SurfaceMap& surfaces, Vec3 p, Vec3 n, uint32_t mesh, uint32_t prim,
                float offset_scale) {
  const float d = offset_distance(p, offset_scale);
  ContactContext cc;
  rtcInitIntersectContext(&cc.context);
  cc.context.filter = contact_filter;
  cc.surfaces = &surfaces, cc.skip_geom = SurfaceMap::mesh_geometry(mesh), cc.skip_prim = prim, cc.dir = n;
  cc.back_t_min = 2.5f * d;  // half an offset in front of p
  RTCRay ray = make_ray(p - n * (2.0f * d), n, 4.0f * d);
  rtcOccluded1(scene, &cc.context, &ray);
  return ray.tfar < 0.0f;
}

std::vector<std::vector<uint8_t>> contact_candidates(RTCScene scene, const Scene& s, const std::vector<MeshView>& views,
                                                     const SurfaceMap& surfaces, float offset_scale) {
  std::vector<std::vector<uint8_t>> flags(views.size());
  for (size_t i = 0; i < views.size(); ++i) {
    const Mesh& mesh = *views[i].mesh;
    if (!s.own_texels(mesh)) continue;
    const int32_t w = int32_t(mesh.lightmap_width), h = int32_t(mesh.lightmap_height);
    tbb::enumerable_thread_specific<std::vector<TexelRect>> found;
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, mesh.triangle_count(), 256), [&](const auto& r) {
      std::vector<TexelRect>& rects = found.local();
      for (uint32_t tri = r.begin(); tri < r.end(); ++tri) {
        const Vec3 n = views[i].normals[tri];
        if (dot(n, n) == 0.0f) continue;
        ContactQuery q;
        q.views = &views, q.surfaces = &surfaces, q.mesh = &mesh, q.mesh_index = uint32_t(i), q.prim = tri, q.n = n;
        q.rects = &rects;
        make_frame(n, q.t, q.b);
        const Vec3 v[3] = {mesh.vertex(tri, 0), mesh.vertex(tri, 1), mesh.vertex(tri, 2)};
        q.origin = v[0];
        const Vec3 c = (v[0] + v[1] + v[2]) * (1.0f / 3.0f);
        float radius = 0.0f, d = 0.0f;
        float lo_u = INFINITY, hi_u = -INFINITY, lo_v = INFINITY, hi_v = -INFINITY;
        for (int k = 0; k < 3; ++k) {
          const Vec3 e = v[k] - v[0];
          q.tri2d[2 * k] = dot(e, q.t), q.tri2d[2 * k + 1] = dot(e, q.b);
          radius = std::max(radius, length(v[k] - c));
          d = std::max(d, offset_distance(v[k], offset_scale));
          q.uv[2 * k] = mesh.uv[6 * size_t(tri) + 2 * size_t(k)] * float(w);
          q.uv[2 * k + 1] = mesh.uv[6 * size_t(tri) + 2 * size_t(k) + 1] * float(h);
          lo_u = std::min(lo_u, q.uv[2 * k]), hi_u = std::max(hi_u, q.uv[2 * k]);
          lo_v = std::min(lo_v, q.uv[2 * k + 1]), hi_v = std::max(hi_v, q.uv[2 * k + 1]);
        }
        q.own = {std::clamp(int32_t(std::floor(lo_u)), 0, w), std::clamp(int32_t(std::floor(lo_v)), 0, h),
                 std::clamp(int32_t(std::floor(hi_u)) + 1, 0, w), std::clamp(int32_t(std::floor(hi_v)) + 1, 0, h)};
        if (q.own.x0 >= q.own.x1 || q.own.y0 >= q.own.y1) continue;  // outside the lightmap
        q.slab = 4.0f * d;
        q.tol = 1e-5f * radius;
        RTCPointQuery pq;
        pq.x = c.x, pq.y = c.y, pq.z = c.z, pq.time = 0.0f, pq.radius = radius + q.slab;
        RTCPointQueryContext pc;
        rtcInitPointQueryContext(&pc);
        rtcPointQuery(scene, &pq, &pc, contact_query, &q);
      }
    });
    for (const std::vector<TexelRect>& rects : found) {
      for (const TexelRect& r : rects) {
        if (flags[i].empty()) flags[i].assign(size_t(w) * size_t(h), 0);
        for (int32_t y = r.y0; y < r.y1; ++y)
          for (int32_t x = r.x0; x < r.x1; ++x) flags[i][size_t(y) * size_t(w) + size_t(x)] = 1;
      }
    }
  }
  return flags;
}

std::vector<Vec3> triangle_normals(const Mesh& mesh) {
  std::vector<Vec3> normals(mesh.triangle_count());
  for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3 p0 = mesh.vertex(t, 0), p1 = mesh.vertex(t, 1), p2 = mesh.vertex(t, 2);
    if (!degenerate_triangle(p0, p1, p2)) normals[t] = normalize(cross(p1 - p0, p2 - p0));
  }
  return normals;
}

SurfaceMap surface_map(const Scene& scene, const std::vector<MeshView>& views) {
  std::vector<const Vec3*> normals(views.size());
  for (size_t m = 0; m < views.size(); ++m) normals[m] = views[m].normals;
  return SurfaceMap(scene, normals);
}

TraceContext::TraceContext() { hits.context.filter = skip_origin_triangle; }

RayPacket::RayPacket() { hits.context.filter = skip_lane_triangles; }

void RayPacket::occluded(RTCScene scene) {
  alignas(32) int valid[kLanes];
  for (unsigned i = 0; i < kLanes; ++i) valid[i] = i < size ? -1 : 0;
  rtcOccluded8(valid, scene, &hits.context, &rh.ray);
  size = 0;
}

void RayPacket::intersect(RTCScene scene, uint32_t skip_lanes) {
  alignas(32) int valid[kLanes];
  for (unsigned i = 0; i < kLanes; ++i) valid[i] = i < size && !(skip_lanes >> i & 1u) ? -1 : 0;
  rtcIntersect8(valid, scene, &hits.context, &rh);
  size = 0;
}

}  // namespace plm
