#include "transport/rays/passage.h"

#include <algorithm>
#include <limits>

namespace plm {
namespace {

// Passable hits a shadow ray may collect; more stop it (a conservative
// answer: the light is then carried by no one, never twice).
constexpr unsigned kMaxPassHits = 16;

struct PassHit {
  unsigned geom, prim;
  float t;
  Vec3 normal;
};

// The occlusion query's context: the packet's lanes skip their own triangles
// (as RayPacket's filter does), passable hits are collected per lane and
// rejected, so the query goes on; any other hit ends the lane.
struct PassContext {
  HitContext hits;  // first member: Embree hands back a pointer to its context
  const RayPacket* packet;
  const PassageTracer* tracer;
  unsigned count[RayPacket::kLanes];
  PassHit list[RayPacket::kLanes][kMaxPassHits];
};

void pass_filter(const RTCFilterFunctionNArguments* args) {
  auto* pc = reinterpret_cast<PassContext*>(args->context);
  const RayPacket& pk = *pc->packet;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    const unsigned lane = RTCRayN_id(args->ray, args->N, i) % RayPacket::kLanes;
    const unsigned geom = RTCHitN_geomID(args->hit, args->N, i), prim = RTCHitN_primID(args->hit, args->N, i);
    if ((geom == pk.skip_geom[lane] && prim == pk.skip_prim[lane]) ||
        (geom == pk.target_geom[lane] && prim == pk.target_prim[lane])) {
      args->valid[i] = 0;
      continue;
    }
    const SurfaceHit h = pc->tracer->surfaces().candidate(args, i);
    if (!pc->tracer->passable(h) || pc->count[lane] >= kMaxPassHits) continue;  // blocks the lane
    pc->list[lane][pc->count[lane]++] = {geom, prim, h.t, h.normal};
    args->valid[i] = 0;
  }
}

}  // namespace

PassageTracer::PassageTracer(const Scene& /*scene*/, const MaterialTable& table, const std::vector<MeshView>& views,
                             const SurfaceMap& surfaces, float scene_extent)
    : table_(table), views_(views), surfaces_(surfaces), offset_scale_(1e-6f * scene_extent) {}

float PassageTracer::pane_transmission(const MaterialLobes& m, Vec3 d, Vec3 n, bool front) {
  const float eta = front ? m.pane_ior : 1.0f / m.pane_ior;
  const float cos_i = std::fmin(std::fabs(dot(d, n)), 1.0f);
  float cos_t;
  const float F = bsdf::fresnel_dielectric(cos_i, eta, cos_t);
  if (cos_t == 0.0f) return 0.0f;  // total internal reflection
  return m.pane_fresnel ? 1.0f - F : 1.0f;
}

void PassageTracer::occluded(RayPacket& packet, RTCScene scene, Vec3 transmittance[RayPacket::kLanes]) const {
  PassContext pc;
  pc.hits.context.filter = pass_filter;
  pc.packet = &packet;
  pc.tracer = this;
  const unsigned lanes = packet.size;
  for (unsigned l = 0; l < RayPacket::kLanes; ++l) pc.count[l] = 0;
  alignas(32) int valid[RayPacket::kLanes];
  for (unsigned i = 0; i < RayPacket::kLanes; ++i) valid[i] = i < lanes ? -1 : 0;
  rtcOccluded8(valid, scene, &pc.hits.context, &packet.rh.ray);
  packet.size = 0;
  for (unsigned l = 0; l < lanes; ++l) {
    transmittance[l] = {0, 0, 0};
    if (packet.blocked(l)) continue;
    PassHit* hits = pc.list[l];
    const unsigned n = pc.count[l];
    // Along the ray; a triangle reported twice (Embree's spatial splits) counts once.
    std::sort(hits, hits + n, [](const PassHit& a, const PassHit& b) { return a.t < b.t; });
    const RTCRay8& r = packet.rh.ray;
    const Vec3 d = normalize(Vec3{r.dir_x[l], r.dir_y[l], r.dir_z[l]});
    Vec3 w{1, 1, 1};
    const PassHit* pending = nullptr;  // a pane entered, waiting for its partner
    unsigned last_geom = RTC_INVALID_GEOMETRY_ID, last_prim = RTC_INVALID_GEOMETRY_ID;
    for (unsigned k = 0; k < n && max_component(w) > 0.0f; ++k) {
      const PassHit& h = hits[k];
      if (h.geom == last_geom && h.prim == last_prim) continue;
      last_geom = h.geom, last_prim = h.prim;
      const MaterialLobes& m = table_.material(views_[h.geom].mesh->material_ids[h.prim]);
      const bool front = dot(d, h.normal) < 0.0f;
      if (pending) {
        const MaterialLobes& ma = table_.material(views_[pending->geom].mesh->material_ids[pending->prim]);
        const bool fa = dot(d, pending->normal) < 0.0f;
        if (m.passage != Passage::Pane || !pane_pair(pending->normal, fa, ma.pane_ior, h.normal, front, m.pane_ior)) {
          w = {0, 0, 0};
          break;
        }
        const float T = pane_transmission(ma, d, pending->normal, fa);
        w = w * ma.pass_tint * m.pass_tint * (T * T);
        pending = nullptr;
      } else if (m.passage == Passage::Transparent) {
        w = w * m.pass_tint;
      } else {
        pending = &h;
      }
    }
    if (!pending) transmittance[l] = w;
  }
}

SurfaceHit PassageTracer::continue_through(RTCScene scene, SurfaceHit h, Vec3 dir, Vec3& weight) const {
  TraceContext tc;
  SurfaceHit entry;  // a pane entered, waiting for its partner
  bool pending = false;
  for (int guard = 0; guard < 64; ++guard) {
    const MaterialLobes* m = passable(h);
    const bool front = dot(dir, h.normal) < 0.0f;
    if (pending) {
      const MaterialLobes& ma = *passable(entry);
      const bool fa = dot(dir, entry.normal) < 0.0f;
      if (!m || m->passage != Passage::Pane || !pane_pair(entry.normal, fa, ma.pane_ior, h.normal, front, m->pane_ior))
        return entry;  // the pane has no partner on this line: it is what the ray sees
      const float T = pane_transmission(ma, dir, entry.normal, fa);
      weight = weight * ma.pass_tint * m->pass_tint * (T * T);
      pending = false;
    } else if (!m) {
      return h;
    } else if (m->passage == Passage::Transparent) {
      weight = weight * m->pass_tint;
    } else {
      entry = h;
      pending = true;
    }
    // On along the line from the far side of h, skipping its triangle.
    const Vec3 far = front ? -h.normal : h.normal;
    RTCRayHit rh;
    rh.ray = make_ray(offset_origin(h.point, far, offset_scale_), dir, std::numeric_limits<float>::infinity());
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    tc.skip_geom = SurfaceMap::mesh_geometry(h.index);
    tc.skip_prim = h.prim;
    rtcIntersect1(scene, tc.context(), &rh);
    h = surfaces_.hit(rh);
    if (h.kind == SurfaceKind::None) return pending ? entry : h;
  }
  return h;
}

}  // namespace plm
