#include "transport/lights/emitters.h"

#include <algorithm>
#include <limits>
#include <memory>

#include "csg/csg.h"
#include "lsystem/lsystem_object.h"
#include "scene/environment.h"
#include "scene/texture.h"

namespace plm {

float spot_attenuation(float c, float cos_half, float spot_smooth, bool cosine) {
  if (c <= cos_half) return 0.0f;
  const float t = c - cos_half;
  const float k = cosine ? c : 1.0f;
  if (spot_smooth > 0.0f && t < spot_smooth) {
    const float x = t / spot_smooth;
    return k * x * x * (3.0f - 2.0f * x);
  }
  return k;
}

namespace {

// Integral of spot_attenuation over the sphere of directions (midpoint rule in cos).
double spot_solid_angle_integral(float cos_half, float spot_smooth, bool cosine) {
  const int n = 4096;
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double c = cos_half + (1.0 - cos_half) * (i + 0.5) / n;
    sum += spot_attenuation(float(c), cos_half, spot_smooth, cosine);
  }
  return 2.0 * kPiD * sum * (1.0 - cos_half) / n;
}

// conventions: plm_conventions (docs/design/cycles-versions.md).
Emitter light_emitter(const Light& light, int32_t conventions) {
  const bool cycles4 = conventions == PLM_CONVENTIONS_CYCLES_4;
  const plm_light& l = light.desc;
  const Affine3f m = Affine3f::from_array(l.matrix);
  const Vec3 color{l.color[0], l.color[1], l.color[2]};
  Emitter e{};
  e.origin = m.point({0, 0, 0});
  switch (l.type) {
    case PLM_LIGHT_POINT:
      // Cycles: radiant intensity P / (4 pi) in every direction.
      e.kind = EmitterKind::Point;
      e.radius = l.radius;
      e.flux = color * l.power;
      e.scale = e.flux;
      e.radiance = color * (l.power / (4.0f * kPi));
      break;
    case PLM_LIGHT_SPOT: {
      e.kind = EmitterKind::Spot;
      e.radius = l.radius;
      e.normal = normalize(m.vector({0, 0, -1}));
      e.cos_half = std::cos(0.5f * l.spot_size);
      e.spot_smooth = (1.0f - e.cos_half) * l.spot_blend;
      e.spot_cosine = !cycles4;
      const Vec3 intensity = color * (l.power / (4.0f * kPi));
      e.radiance = intensity;
      // Directions are drawn uniformly inside the cone and weighted by the falloff.
      e.scale = intensity * (2.0f * kPi * (1.0f - e.cos_half));
      e.flux = intensity * float(spot_solid_angle_integral(e.cos_half, e.spot_smooth, e.spot_cosine));
      break;
    }
    case PLM_LIGHT_AREA_RECT:
    case PLM_LIGHT_AREA_DISK: {
      e.kind = l.type == PLM_LIGHT_AREA_RECT ? EmitterKind::AreaRect : EmitterKind::AreaDisk;
      e.axis_u = m.vector({0.5f * l.size_x, 0, 0});
      e.axis_v = m.vector({0, 0.5f * l.size_y, 0});
      e.normal = -normalize(cross(e.axis_u, e.axis_v));
      // Cycles 3.4: radiance P / (4 A), one-sided, so the flux pi L A = pi P / 4
      // whatever the size; Cycles 4: radiance P / (pi A), the flux P.
      e.flux = cycles4 ? color * l.power : color * (kPi * l.power / 4.0f);
      e.scale = e.flux;
      e.area = length(cross(e.axis_u, e.axis_v)) * (e.kind == EmitterKind::AreaRect ? 4.0f : kPi);
      e.radiance = e.flux / (kPi * e.area);
      break;
    }
    case PLM_LIGHT_SUN:
      e.kind = EmitterKind::Sun;
      e.normal = normalize(m.vector({0, 0, -1}));
      e.cos_half = std::cos(0.5f * l.angle);
      break;
  }
  return e;
}

}  // namespace

EmitterTable::EmitterTable(const std::vector<Emitter>& emitters, const std::vector<uint8_t>& skip) {
  auto pick = [&](size_t k) { return skip.empty() || !skip[k] ? double(emitters[k].pick) : 0.0; };
  double total = 0.0;
  for (size_t k = 0; k < emitters.size(); ++k) total += pick(k);
  double running = 0.0;
  for (size_t k = 0; k < emitters.size(); ++k) {
    running += pick(k);
    cdf_.push_back(total > 0.0 ? running / total : 1.0);
    pick_.push_back(total > 0.0 ? float(pick(k) / total) : 0.0f);
  }
  if (!cdf_.empty()) cdf_.back() = 1.0;
}

namespace {

constexpr float kPortalPhotonShare = 0.9f;  // sun and world photons sent through portals
// Sun and world photons aimed at the box around what records photons (the
// rest cover the scene's box), unless that box has this share of the scene
// box's surface or more.
constexpr float kFootprintAim = 0.75f, kFootprintWholeScene = 0.9f;
constexpr float kPortalDirectShare = 0.75f;  // the sky's direct samples aimed at portals

std::vector<Portal> scene_portals(const Scene& scene) {
  std::vector<Portal> out;
  for (const Light& light : scene.lights) {
    if (light.desc.type != PLM_LIGHT_PORTAL) continue;
    const Affine3f m = Affine3f::from_array(light.desc.matrix);
    Portal p;
    p.center = m.point({0, 0, 0});
    p.half_u = m.vector({0.5f * light.desc.size_x, 0, 0});
    p.half_v = m.vector({0, 0.5f * light.desc.size_y, 0});
    const Vec3 n = cross(p.half_u, p.half_v);
    p.area = 4.0f * length(n);
    p.inward = -normalize(n);  // the side a Blender area light shines to
    if (p.area > 0.0f && is_finite(p.inward)) out.push_back(p);
  }
  return out;
}

// Where the line o + t d meets portal p's plane inside the parallelogram,
// travelling along `side` * inward (+1: into the interior, -1: out of it).
bool portal_crossing(const Portal& p, Vec3 o, Vec3 d, float side, float& t, float& cos_p) {
  cos_p = dot(d, p.inward) * side;
  if (!(cos_p > 0.0f)) return false;
  t = dot(p.center - o, p.inward) / dot(d, p.inward);
  const Vec3 q = o + d * t - p.center;
  const float uu = dot(p.half_u, p.half_u), uv = dot(p.half_u, p.half_v), vv = dot(p.half_v, p.half_v);
  const float qu = dot(q, p.half_u), qv = dot(q, p.half_v), det = uu * vv - uv * uv;
  const float a = (qu * vv - qv * uv) / det, b = (qv * uu - qu * uv) / det;
  return std::fabs(a) <= 1.0f && std::fabs(b) <= 1.0f;
}

// Density of the sun or world photon line (o, d) over (direction, position
// across the direction), per unit of the direction density the two sampling
// strategies share: the footprint (1 - share) and the portals.
float photon_line_density(const Emitter& e, Vec3 o, Vec3 d) {
  const float across = footprint_density(*e.footprint, o, d);
  float density = (1.0f - e.portal_share) * (e.kind == EmitterKind::World ? across / (4.0f * kPi) : across);
  for (size_t j = 0; j < e.portals.size(); ++j) {
    float t, cos_p;
    if (e.portal_pick[j] <= 0.0f || !portal_crossing(e.portals[j], o, d, 1.0f, t, cos_p)) continue;
    // World: cosine directions (cos / pi) over the portal's area, per area across d: 1 / (pi A).
    // Sun: the portal's area seen along d: 1 / (A cos).
    const float a = e.portals[j].area;
    density += e.portal_share * e.portal_pick[j] / (e.kind == EmitterKind::World ? kPi * a : a * cos_p);
  }
  return density;
}

// Gives a sun or world emitter the scene's portals: photons are picked by the
// flux they are expected to bring in (mostly what enters through the portals).
void attach_portals(Emitter& e, const std::vector<Portal>& portals) {
  std::vector<float> weight;
  float total = 0.0f, entering = 0.0f;
  for (const Portal& p : portals) {
    float w = e.kind == EmitterKind::World ? p.area : p.area * std::fmax(0.0f, dot(e.normal, p.inward));
    // An environment map: the flux through the opening, A x the irradiance on its outer face.
    if (e.map) w = p.area * average(e.map->irradiance(e.map_part, -p.inward));
    weight.push_back(w);
    total += w;
  }
  if (!(total > 0.0f)) return;  // the sun shines away from every portal
  for (float& w : weight) w /= total;
  e.portals = portals;
  e.portal_pick = weight;
  e.portal_share = kPortalPhotonShare;
  // Flux through the portals: world pi L sum A, sun S sum A cos, a map sum A E(outward).
  entering = e.map ? total : average(e.radiance) * (e.kind == EmitterKind::World ? kPi * total : total);
  e.pick = kPortalPhotonShare * entering + (1.0f - kPortalPhotonShare) * average(e.flux);
}

}  // namespace

namespace {

// Pads box [lo, hi] so that no side is empty (a flat ground still has a
// projected area seen edge-on, and a line along it crosses it).
void pad_box(Vec3& lo, Vec3& hi) {
  const float pad = 1e-4f * length(hi - lo) + 2.5e-7f * std::fmax(max_abs_component(lo), max_abs_component(hi)) + 1e-20f;
  lo = lo - Vec3{pad, pad, pad};
  hi = hi + Vec3{pad, pad, pad};
}

float surface_area(Vec3 lo, Vec3 hi) {
  const Vec3 e = hi - lo;
  return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
}

void grow(Vec3& lo, Vec3& hi, Vec3 p) {
  lo = {std::fmin(lo.x, p.x), std::fmin(lo.y, p.y), std::fmin(lo.z, p.z)};
  hi = {std::fmax(hi.x, p.x), std::fmax(hi.y, p.y), std::fmax(hi.z, p.z)};
}

}  // namespace

Footprint photon_footprint(const Scene& scene, Vec3 lo, Vec3 hi) {
  Footprint f;
  f.scene_lo = lo;
  f.scene_hi = hi;
  const Vec3 center = (lo + hi) * 0.5f;
  f.radius = 0.5f * length(hi - lo) * 1.01f + 1e-6f * max_abs_component(center) + 1e-30f;
  constexpr float inf = std::numeric_limits<float>::infinity();
  Vec3 rlo{inf, inf, inf}, rhi{-inf, -inf, -inf};
  for (const Mesh& mesh : scene.meshes) {
    if (!(mesh.has_lightmap() || mesh.ol_group >= 0) || mesh.csg_carrier >= 0) continue;
    for (uint32_t k = 0; k < mesh.vertex_count; ++k)
      if (is_finite(mesh.positions[k])) grow(rlo, rhi, mesh.positions[k]);
  }
  for (const CsgSolid& c : scene.csgs) {
    grow(rlo, rhi, to_float(c.object->bounds_lo()));
    grow(rlo, rhi, to_float(c.object->bounds_hi()));
  }
  for (const auto& ls : scene.lsystems) {
    grow(rlo, rhi, to_float(ls->bounds_lo()));
    grow(rlo, rhi, to_float(ls->bounds_hi()));
  }
  // Within the scene's box (the bounds of what is traced).
  f.lo = {std::fmax(rlo.x, lo.x), std::fmax(rlo.y, lo.y), std::fmax(rlo.z, lo.z)};
  f.hi = {std::fmin(rhi.x, hi.x), std::fmin(rhi.y, hi.y), std::fmin(rhi.z, hi.z)};
  if (!(f.lo.x <= f.hi.x && f.lo.y <= f.hi.y && f.lo.z <= f.hi.z)) {  // nothing records: the scene's box
    f.lo = lo;
    f.hi = hi;
  }
  return f;
}

std::vector<Emitter> build_emitters(const Scene& scene, Vec3 center, float radius, const TextureSet* textures) {
  Footprint f;
  f.lo = f.scene_lo = center - Vec3{radius, radius, radius};
  f.hi = f.scene_hi = center + Vec3{radius, radius, radius};
  f.radius = radius;
  return build_emitters(scene, f, textures);
}

std::vector<Emitter> build_emitters(const Scene& scene, Footprint fp, const TextureSet* textures) {
  std::vector<Emitter> out;
  const std::vector<Portal> portals = scene_portals(scene);
  // Sun and world power (by which photons and direct samples are shared between lights): the flux
  // through the disk of the sphere around the scene and the portals.
  const Vec3 center = (fp.scene_lo + fp.scene_hi) * 0.5f;
  float radius = fp.radius;
  for (const Portal& p : portals)  // sun and world photons' scene box holds the portals too
    for (float a : {-1.0f, 1.0f})
      for (float b : {-1.0f, 1.0f}) {
        const Vec3 corner = p.center + p.half_u * a + p.half_v * b;
        grow(fp.scene_lo, fp.scene_hi, corner);
        radius = std::fmax(radius, 1.01f * length(corner - center));
      }
  const float disk_area = kPi * radius * radius;
  pad_box(fp.lo, fp.hi);
  pad_box(fp.scene_lo, fp.scene_hi);
  // A recording box nearly as large as the scene's is the scene's: all photons aim at it.
  const float scene_surface = surface_area(fp.scene_lo, fp.scene_hi);
  fp.aim = surface_area(fp.lo, fp.hi) >= kFootprintWholeScene * scene_surface ? 1.0f : kFootprintAim;
  if (fp.aim >= 1.0f) {
    fp.lo = fp.scene_lo;
    fp.hi = fp.scene_hi;
  }
  fp.reach = 1.01f * length(fp.scene_hi - fp.scene_lo);
  const auto shared = std::make_shared<const Footprint>(fp);
  for (const Light& light : scene.lights) {
    Emitter e = light_emitter(light, scene.conventions);
    e.group = light.light_group;
    if (e.kind == EmitterKind::Sun) {
      // Irradiance S on a surface facing the sun: flux S through the disk.
      e.footprint = shared;
      make_frame(e.normal, e.axis_u, e.axis_v);
      const Vec3 color{light.desc.color[0], light.desc.color[1], light.desc.color[2]};
      e.flux = color * (light.desc.power * disk_area);
      e.scale = e.flux;
      e.radiance = color * light.desc.power;
    }
    if (average(e.flux) > 0.0f) out.push_back(e);
  }
  for (uint32_t mesh_id = 0; mesh_id < scene.meshes.size(); ++mesh_id) {
    const Mesh& mesh = scene.meshes[mesh_id];
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      const uint32_t material = mesh.material_ids.empty() ? 0u : mesh.material_ids[t];
      Vec3 emission = scene.materials.empty() ? Vec3{} : scene.materials[material].emission;
      if (max_component(emission) <= 0.0f) continue;
      if (textures) emission = textures->triangle_emission(mesh, material, t);
      if (max_component(emission) <= 0.0f) continue;
      if (degenerate_triangle(mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2))) continue;
      Emitter e{};
      e.kind = EmitterKind::Triangle;
      e.origin = mesh.vertex(t, 0);
      e.axis_u = mesh.vertex(t, 1) - e.origin;
      e.axis_v = mesh.vertex(t, 2) - e.origin;
      const Vec3 n = cross(e.axis_u, e.axis_v);
      const float area = 0.5f * length(n);
      if (!(area > 0.0f)) continue;
      e.normal = n / (2.0f * area);
      // Both sides emit radiance L: flux 2 pi L A.
      e.flux = emission * (2.0f * kPi * area);
      e.scale = e.flux;
      e.radiance = emission;
      e.area = area;
      e.mesh = mesh_id;
      e.triangle = t;
      e.material = material;
      e.textured = textures && textures->emission_varies(mesh, material);
      e.group = mesh.light_group;
      if (average(e.flux) > 0.0f) out.push_back(e);  // denormal emission can underflow to 0
    }
  }
  if (max_component(scene.world) > 0.0f) {
    // Uniform radiance from every direction: flux L * 4 pi * (disk area).
    Emitter e{};
    e.kind = EmitterKind::World;
    e.footprint = shared;
    e.flux = scene.world * (4.0f * kPi * disk_area);
    e.scale = e.flux;
    e.radiance = scene.world;
    e.group = scene.world_light_group;
    if (average(e.flux) > 0.0f) out.push_back(e);
  }
  if (scene.world_map) {
    // The map's flux through the disk: (integral of L over the sphere) x (disk area); a map
    // with a sun as two lights, the sun's cells and the rest.
    const EnvironmentMap& map = *scene.world_map;
    for (int part = map.split() ? 1 : 0; part <= (map.split() ? 2 : 0); ++part) {
      Emitter e{};
      e.kind = EmitterKind::World;
      e.map = &map;
      e.map_part = part;
      e.footprint = shared;
      e.flux = map.integral(part) * disk_area;
      e.scale = e.flux;
      e.radiance = map.integral(part) * (1.0f / (4.0f * kPi));
      e.group = scene.world_light_group;
      if (average(e.flux) > 0.0f) out.push_back(e);
    }
  }
  for (Emitter& e : out) {
    e.pick = average(e.flux);
    if (e.kind == EmitterKind::Spot || e.kind == EmitterKind::AreaRect || e.kind == EmitterKind::AreaDisk ||
        e.kind == EmitterKind::Triangle)
      make_frame(e.normal, e.frame_t, e.frame_b);
    if (!portals.empty() && (e.kind == EmitterKind::Sun || e.kind == EmitterKind::World)) attach_portals(e, portals);
  }
  return out;
}

namespace {

// Direction uniform in the cone of half-angle acos(cos_half) around unit
// axis, whose frame t, b, axis is given. (Inlined: called per shadow ray of
// the sun, it cost 2x its arithmetic as a call.)
inline __attribute__((always_inline)) Vec3 cone_direction(Vec3 axis, Vec3 t, Vec3 b, float cos_half, float u0, float u1) {
  const float c = 1.0f - u0 * (1.0f - cos_half);
  const float sn = std::sqrt(std::fmax(0.0f, 1.0f - c * c));
  float sp, cp;
  sincos_2pi(u1, sp, cp);
  return t * (sn * cp) + b * (sn * sp) + axis * c;
}

// Share of a map's portal photons whose direction is cosine-distributed into
// the room; the others take the map's distribution (they find a sun in it).
// A sun's part takes its own distribution only: cosine directions miss it.
inline float map_portal_cosine_share(const Emitter& e) { return e.map_part == 1 ? 0.0f : 0.5f; }

// Density of the map world's photon line (o, d) over (direction, position
// across d), pm the map's density of the direction looked towards (-d): the
// disk (1 - share) and, for each portal the line enters through, the portal's
// mixture of cosine (1 / (pi A)) and map directions (pm / (A cos)).
float map_line_density(const Emitter& e, Vec3 o, Vec3 d, float pm) {
  const float b = map_portal_cosine_share(e);
  float density = (1.0f - e.portal_share) * pm * footprint_density(*e.footprint, o, d);
  for (size_t j = 0; j < e.portals.size(); ++j) {
    float t, cos_p;
    if (e.portal_pick[j] <= 0.0f || !portal_crossing(e.portals[j], o, d, 1.0f, t, cos_p)) continue;
    const float a = e.portals[j].area;
    density += e.portal_share * e.portal_pick[j] * (b / (kPi * a) + (1.0f - b) * pm / (a * cos_p));
  }
  return density;
}

// With portals, u0 first chooses the strategy (a portal, and which, or the
// disk) and is then rescaled for reuse as the first direction number.
// Returns whether the photon goes through portal j.
inline bool pick_portal(const Emitter& e, float& u0, size_t& j) {
  const bool through_portal = u0 < e.portal_share;
  if (e.portal_share > 0.0f) {
    u0 = through_portal ? u0 / e.portal_share : (u0 - e.portal_share) / (1.0f - e.portal_share);
    if (through_portal) {
      while (j + 1 < e.portals.size() && u0 >= e.portal_pick[j]) u0 -= e.portal_pick[j++];
      u0 = std::fmin(u0 / e.portal_pick[j], 0.99999994f);
    }
  }
  return through_portal;
}

// A direction cosine-distributed into the interior through a portal.
inline Vec3 into_portal(const Portal& p, float u0, float u1) {
  const Vec3 local = cosine_hemisphere(u0, u1);
  Vec3 t, b;
  make_frame(p.inward, t, b);
  return t * local.x + b * local.y + p.inward * local.z;
}

// Where a sun or world photon travelling along d starts: on portal j, or on
// the footprint seen along d, both far enough back to be outside the scene.
inline Vec3 line_origin(const Emitter& e, bool through_portal, size_t j, Vec3 d, const float u[4]) {
  if (through_portal) {
    const Portal& p = e.portals[j];
    const Vec3 q = p.center + p.half_u * (2.0f * u[2] - 1.0f) + p.half_v * (2.0f * u[3] - 1.0f);
    return q - d * e.footprint->reach;
  }
  return footprint_origin(*e.footprint, d, u[2], u[3]);
}

// World photons from an environment map: the direction looked towards is
// drawn from the map (or, through a portal, cosine-distributed half the
// time), the photon travels the other way; flux = L / (density of its line).
__attribute__((noinline)) void sample_map_sky(const Emitter& e, const float u[4], EmitterSample& s) {
  const EnvironmentMap& map = *e.map;
  float u0 = u[0];
  size_t j = 0;
  const bool through_portal = pick_portal(e, u0, j);
  bool cosine = false;
  if (through_portal) {
    const float share = map_portal_cosine_share(e);
    cosine = u0 < share;
    u0 = cosine ? u0 / share : (u0 - share) / (1.0f - share);
    u0 = std::fmin(u0, 0.99999994f);
  }
  Vec3 d;
  float pm = 0.0f;
  if (cosine) {
    d = into_portal(e.portals[j], u0, u[1]);
    pm = map.pdf(e.map_part, -d);
  } else {
    d = -map.sample(e.map_part, u0, u[1], pm);
  }
  s.origin = line_origin(e, through_portal, j, d, u);
  s.direction = d;
  const Vec3 L = map.radiance(e.map_part, -d);
  float tc, cos_p;
  if (e.portal_share <= 0.0f) {
    const float density = pm * footprint_density(*e.footprint, s.origin, d);
    s.weight = density > 0.0f ? L * (1.0f / density) : Vec3{0, 0, 0};
  } else if (through_portal && !portal_crossing(e.portals[j], s.origin, d, 1.0f, tc, cos_p)) {
    s.weight = {0, 0, 0};  // a map direction leaving through the portal, or rounding at its rim
  } else {
    const float density = map_line_density(e, s.origin, d, pm);
    s.weight = density > 0.0f ? L * (1.0f / density) : Vec3{0, 0, 0};
  }
}

// Sun and world photons (sample_emitter): out of line, so that the common
// lights' path keeps its registers and a small frame (they are drawn once
// per photon, before its first ray).
__attribute__((noinline)) void sample_sky(const Emitter& e, const float u[4], EmitterSample& s) {
  if (e.map) {
    sample_map_sky(e, u, s);
    return;
  }
  float u0 = u[0];
  size_t j = 0;
  const bool through_portal = pick_portal(e, u0, j);
  Vec3 d = e.normal;
  if (e.kind == EmitterKind::World) {
    d = through_portal ? into_portal(e.portals[j], u0, u[1]) : uniform_sphere(u0, u[1]);
  } else if (e.cos_half < 1.0f) {
    d = cone_direction(e.normal, e.axis_u, e.axis_v, e.cos_half, u0, u[1]);  // over the sun's disk of directions
  }
  s.origin = line_origin(e, through_portal, j, d, u);
  s.direction = d;
  float tc, cos_p;
  if (through_portal && !portal_crossing(e.portals[j], s.origin, d, 1.0f, tc, cos_p)) {
    s.weight = {0, 0, 0};  // the sun's cone grazing the portal, or rounding at its rim
  } else {
    // Radiance over the line's density; the world's directions are uniform (1 / 4 pi).
    const float density = photon_line_density(e, s.origin, d);
    s.weight = density > 0.0f ? e.radiance * (1.0f / density) : Vec3{0, 0, 0};
  }
}

}  // namespace

EmitterSample sample_emitter(const Emitter& e, const float u[4]) {
  EmitterSample s;
  s.weight = e.scale;
  switch (e.kind) {
    case EmitterKind::Point:
    case EmitterKind::Spot: {
      if (e.kind == EmitterKind::Point) {
        s.direction = uniform_sphere(u[0], u[1]);
      } else {
        s.direction = cone_direction(e.normal, e.frame_t, e.frame_b, e.cos_half, u[0], u[1]);
        s.weight = e.scale * spot_attenuation(1.0f - u[0] * (1.0f - e.cos_half), e.cos_half, e.spot_smooth, e.spot_cosine);
      }
      // Start on the disk of the light's radius across the direction (soft
      // shadows); the distance falloff of the disk is applied at the first hit.
      s.origin = e.origin;
      s.center = e.origin;
      s.radius2 = e.radius * e.radius;
      if (e.radius > 0.0f) {
        float dx, dy;
        concentric_disk(u[2], u[3], dx, dy);
        Vec3 t, b;
        make_frame(s.direction, t, b);
        s.origin += (t * dx + b * dy) * e.radius;
      }
      break;
    }
    case EmitterKind::AreaRect:
    case EmitterKind::AreaDisk: {
      float x = 2.0f * u[0] - 1.0f, y = 2.0f * u[1] - 1.0f;
      if (e.kind == EmitterKind::AreaDisk) concentric_disk(u[0], u[1], x, y);
      s.origin = e.origin + e.axis_u * x + e.axis_v * y;
      const Vec3 local = cosine_hemisphere(u[2], u[3]);
      s.direction = e.frame_t * local.x + e.frame_b * local.y + e.normal * local.z;
      break;
    }
    case EmitterKind::Triangle: {
      float a = u[0], b = u[1];
      if (a + b > 1.0f) {
        a = 1.0f - a;
        b = 1.0f - b;
      }
      s.origin = e.origin + e.axis_u * a + e.axis_v * b;
      s.bu = a;
      s.bv = b;
      // Pick a side with u[2], reuse the remainder of it for the direction.
      const bool back = u[2] >= 0.5f;
      const float u2 = back ? 2.0f * u[2] - 1.0f : 2.0f * u[2];
      const Vec3 n = back ? -e.normal : e.normal;
      const Vec3 bt = back ? -e.frame_b : e.frame_b;  // bit for bit make_frame(n)'s second axis
      const Vec3 local = cosine_hemisphere(u2, u[3]);
      s.direction = e.frame_t * local.x + bt * local.y + n * local.z;
      break;
    }
    case EmitterKind::Sun:
    case EmitterKind::World:
      sample_sky(e, u, s);
      break;
  }
  return s;
}

namespace {

// Irradiance from a point q on an emitting surface of radiance L and area A
// (density 1/A), with emitter normal nl (two_sided: either side emits).
DirectSample from_surface_point(Vec3 q, Vec3 nl, bool two_sided, Vec3 L, float A, Vec3 p, Vec3 n) {
  DirectSample s{{0, 0, 0}, {0, 0, 1}, 0.0f, 0.0f, 0.0f, 0.0f};
  const Vec3 v = q - p;
  const float d2 = dot(v, v);
  if (!(d2 > 0.0f)) return s;
  const float d = std::sqrt(d2);
  s.dir = v / d;
  s.distance = d;
  float cos_l = -dot(nl, s.dir);
  if (two_sided) cos_l = std::fabs(cos_l);
  const float cos_s = dot(n, s.dir);
  if (cos_l > 0.0f && cos_s > 0.0f) {
    s.geometry = cos_l * cos_s * A / d2;
    s.irradiance = L * s.geometry;
  }
  return s;
}

// Adds to density the density in solid angle with which the portals'
// share of the sky samples at p reaches direction dir (points on the portals,
// chosen by portal_pick), for every portal dir leaves through.
inline void add_portal_density(const Emitter& e, Vec3 p, Vec3 dir, float share, float& density) {
  for (size_t j = 0; j < e.portals.size(); ++j) {
    float t, cos_p;  // leaving the interior through portal j
    if (!portal_crossing(e.portals[j], p, dir, -1.0f, t, cos_p) || !(t > 0.0f)) continue;
    density += share * e.portal_pick[j] * t * t / (e.portals[j].area * cos_p);
  }
}

// A map's sky samples at a point: without portals half are drawn from the
// map and half are cosine directions; with portals kPortalDirectShare (as for
// the uniform world) aim at points on the portals (they find the sky through
// the opening, the job the cosine directions do without portals) and the rest
// come from the map. A sun's part (map_part 1) is drawn from its own
// distribution only: its direct light is then sampled like a sun lamp's,
// whatever the portals. One sample, one shadow ray: the balance heuristic of
// the strategies, i.e. the mixture's density [Veach97 ch. 9].
constexpr float kMapDirectShare = 0.5f;

// A direct sample aimed at a point on a portal (chosen by area with u[2] /
// share, the point by u[0], u[1]): the unit direction from p, false if p lies on it.
inline bool toward_portal(const Emitter& e, Vec3 p, const float u[3], float share, Vec3& dir) {
  float v = u[2] / share;
  size_t j = 0;
  while (j + 1 < e.portals.size() && v >= e.portal_pick[j]) v -= e.portal_pick[j++];
  const Portal& q = e.portals[j];
  const Vec3 to = q.center + q.half_u * (2.0f * u[0] - 1.0f) + q.half_v * (2.0f * u[1] - 1.0f) - p;
  const float d = length(to);
  if (!(d > 0.0f)) return false;
  dir = to / d;
  return true;
}

// A cosine-distributed direction about n.
inline Vec3 cosine_about(Vec3 n, float u0, float u1) {
  const Vec3 local = cosine_hemisphere(u0, u1);
  Vec3 t, b;
  make_frame(n, t, b);
  return t * local.x + b * local.y + n * local.z;
}

// The sky's direct light at p from an environment map: directions from the
// map and cosine directions (and with portals, points on them) mixed, each
// sample weighted by the mixture's density.
__attribute__((noinline)) DirectSample map_sky_direct(const Emitter& e, Vec3 p, Vec3 n, const float u[3]) {
  DirectSample s{{0, 0, 0}, {0, 0, 1}, std::numeric_limits<float>::infinity(), 0.0f, 0.0f, 0.0f};
  const EnvironmentMap& map = *e.map;
  const bool sun = e.map_part == 1;
  const float share = e.portals.empty() || sun ? 0.0f : kPortalDirectShare;
  const float map_share = e.portals.empty() && !sun ? kMapDirectShare : 1.0f;  // of the samples not aimed at portals
  float pm = -1.0f;  // the map's density of s.dir, once known
  if (u[2] < share) {
    if (!toward_portal(e, p, u, share, s.dir)) return s;
  } else if ((u[2] - share) < map_share * (1.0f - share)) {
    s.dir = map.sample(e.map_part, u[0], u[1], pm);
  } else {
    s.dir = cosine_about(n, u[0], u[1]);
  }
  const float cos_s = dot(n, s.dir);
  if (!(cos_s > 0.0f)) return s;
  if (pm < 0.0f) pm = map.pdf(e.map_part, s.dir);
  float density = (1.0f - share) * (map_share * pm + (1.0f - map_share) * cos_s / kPi);
  if (share > 0.0f) add_portal_density(e, p, s.dir, share, density);
  if (density > 0.0f && std::isfinite(density)) s.irradiance = map.radiance(e.map_part, s.dir) * (cos_s / density);
  return s;
}

// The sky's direct light at p with portals: a mixture of cosine directions
// and points on the portals (chosen by area), weighted by the mixture's
// density in solid angle, so texels the portals do not see stay unbiased.
DirectSample sky_through_portals(const Emitter& e, Vec3 p, Vec3 n, const float u[3]) {
  DirectSample s{{0, 0, 0}, {0, 0, 1}, std::numeric_limits<float>::infinity(), 0.0f, 0.0f, 0.0f};
  const float share = kPortalDirectShare;
  if (u[2] < share) {
    if (!toward_portal(e, p, u, share, s.dir)) return s;
  } else {
    s.dir = cosine_about(n, u[0], u[1]);
  }
  const float cos_s = dot(n, s.dir);
  if (!(cos_s > 0.0f)) return s;
  float density = (1.0f - share) * cos_s / kPi;
  add_portal_density(e, p, s.dir, share, density);
  if (density > 0.0f && std::isfinite(density)) s.irradiance = e.radiance * (cos_s / density);
  return s;
}

}  // namespace

DirectSample sample_direct(const Emitter& e, Vec3 p, Vec3 n, const float u[3]) {
  DirectSample s{{0, 0, 0}, {0, 0, 1}, std::numeric_limits<float>::infinity(), 0.0f, 0.0f, 0.0f};
  switch (e.kind) {
    case EmitterKind::Point:
    case EmitterKind::Spot: {
      // Cycles 3.4: a disk of radius r facing p: I cos / (d^2 + r^2), soft shadows from the disk.
      const Vec3 v = e.origin - p;
      const float d2 = dot(v, v);
      if (!(d2 > 0.0f)) return s;
      const Vec3 w = v / std::sqrt(d2);
      const float cos_s = dot(n, w);
      if (cos_s <= 0.0f) return s;
      Vec3 target = e.origin;
      if (e.radius > 0.0f) {
        float dx, dy;
        concentric_disk(u[0], u[1], dx, dy);
        Vec3 t, b;
        make_frame(w, t, b);
        target += (t * dx + b * dy) * e.radius;
      }
      const Vec3 to = target - p;
      s.distance = length(to);
      s.dir = to / s.distance;
      // As Cycles, the spot cone is taken from the sampled point of the disk.
      float att = 1.0f;
      if (e.kind == EmitterKind::Spot) att = spot_attenuation(-dot(s.dir, e.normal), e.cos_half, e.spot_smooth, e.spot_cosine);
      if (att <= 0.0f) return s;
      s.irradiance = e.radiance * (att * cos_s / (d2 + e.radius * e.radius));
      return s;
    }
    case EmitterKind::Sun: {
      const Vec3 travel = e.cos_half < 1.0f ? cone_direction(e.normal, e.axis_u, e.axis_v, e.cos_half, u[0], u[1]) : e.normal;
      s.dir = -travel;
      const float cos_s = dot(n, s.dir);
      if (cos_s > 0.0f) s.irradiance = e.radiance * cos_s;
      return s;
    }
    case EmitterKind::World: {
      if (e.map) return map_sky_direct(e, p, n, u);
      if (e.portals.empty()) {
        const Vec3 local = cosine_hemisphere(u[0], u[1]);
        Vec3 t, b;
        make_frame(n, t, b);
        s.dir = t * local.x + b * local.y + n * local.z;
        s.irradiance = e.radiance * kPi;  // cosine-weighted: L cos / (cos / pi)
        return s;
      }
      return sky_through_portals(e, p, n, u);
    }
    case EmitterKind::AreaRect:
    case EmitterKind::AreaDisk: {
      float x = 2.0f * u[0] - 1.0f, y = 2.0f * u[1] - 1.0f;
      if (e.kind == EmitterKind::AreaDisk) concentric_disk(u[0], u[1], x, y);
      return from_surface_point(e.origin + e.axis_u * x + e.axis_v * y, e.normal, false, e.radiance, e.area, p, n);
    }
    case EmitterKind::Triangle: {
      float a = u[0], b = u[1];
      if (a + b > 1.0f) {
        a = 1.0f - a;
        b = 1.0f - b;
      }
      DirectSample s2 = from_surface_point(e.origin + e.axis_u * a + e.axis_v * b, e.normal, true, e.radiance, e.area, p, n);
      s2.bu = a;
      s2.bv = b;
      return s2;
    }
  }
  return s;
}

float unoccluded_irradiance(const Emitter& e, Vec3 p, Vec3 n) {
  const float L = average(e.radiance);
  switch (e.kind) {
    case EmitterKind::Point:
    case EmitterKind::Spot: {
      const Vec3 v = e.origin - p;
      const float d2 = dot(v, v);
      if (!(d2 > 0.0f)) return 0.0f;
      const Vec3 w = v / std::sqrt(d2);
      const float att = e.kind == EmitterKind::Spot ? spot_attenuation(-dot(w, e.normal), e.cos_half, e.spot_smooth, e.spot_cosine) : 1.0f;
      return L * att * std::max(dot(n, w), 0.0f) / (d2 + e.radius * e.radius);
    }
    case EmitterKind::Sun:
      return L * std::max(-dot(n, e.normal), 0.0f);
    case EmitterKind::World:  // a map's sun: from its mean direction
      if (e.map && e.map_part == 1) return L * 4.0f * kPi * std::max(dot(n, e.map->bright_direction()), 0.0f);
      return L * kPi;
    case EmitterKind::AreaRect:
    case EmitterKind::AreaDisk:
    case EmitterKind::Triangle: {
      const Vec3 centre = e.kind == EmitterKind::Triangle ? e.origin + (e.axis_u + e.axis_v) * (1.0f / 3.0f) : e.origin;
      const Vec3 v = centre - p;
      // The distance is kept above the light's size: close up the centre is no guide.
      const float d2 = std::max(dot(v, v), e.area);
      if (!(d2 > 0.0f)) return 0.0f;
      const Vec3 w = v * (1.0f / std::sqrt(dot(v, v) + 1e-30f));
      float cos_l = -dot(e.normal, w);
      if (e.kind == EmitterKind::Triangle) cos_l = std::fabs(cos_l);
      return L * e.area * std::max(cos_l, 0.0f) * std::max(dot(n, w), 0.0f) / d2;
    }
  }
  return 0.0f;
}

std::vector<uint32_t> assign_layers(const Scene& scene, std::vector<Emitter>& emitters) {
  if (scene.light_groups.empty()) return {};
  const bool any_default = std::any_of(emitters.begin(), emitters.end(), [](const Emitter& e) { return e.group == 0; });
  std::vector<uint32_t> groups;
  if (any_default) groups.push_back(0);
  for (uint32_t g = 1; g <= scene.light_groups.size(); ++g) groups.push_back(g);
  for (Emitter& e : emitters) e.layer = any_default ? e.group : e.group - 1;
  return groups;
}

}  // namespace plm
