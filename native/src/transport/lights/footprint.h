// Where sun and world photons start (docs/design/lights.md, "Sun and sky
// photons are aimed at what records them"): on the box around everything that
// records photons (lightmaps, OLs, CSG solids, L-system objects) as seen along
// the photon's direction, a share `aim` of them, the rest on the box around all
// geometry, so that light reaching the recording objects only by way of other
// geometry still arrives. A line's density per unit area across its direction
// is aim / A_r(d) where it crosses the recording box plus (1 - aim) / A_s(d)
// where it crosses the scene's, the A(d) being the boxes' exact projected
// areas: photons carry radiance over that density, so the sum stays unbiased.
// Blockers outside the recording box still block: a photon starts `reach`
// behind the box, outside all geometry.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "util/math.h"

namespace plm {

struct Footprint {
  Vec3 lo, hi;              // the box around what records photons
  Vec3 scene_lo, scene_hi;  // the box around all geometry (and portals); holds lo, hi
  float aim = 1.0f;         // share of photons aimed at the recording box (1: the two boxes are one)
  float reach = 0.0f;       // how far back from the box a photon starts (the scene's diameter or more)
  // Radius of the sphere around the scene: sun and world power is the flux
  // through its disk (emitters.h), by which lights share photons and samples.
  float radius = 0.0f;
};

// Area of box [lo, hi] projected along unit d: each axis' face pair is seen with |d_axis|.
inline float projected_area(Vec3 lo, Vec3 hi, Vec3 d) {
  const Vec3 e = hi - lo;
  return std::fabs(d.x) * e.y * e.z + std::fabs(d.y) * e.x * e.z + std::fabs(d.z) * e.x * e.y;
}

// Whether the line o + t d (any t) crosses box [lo, hi].
inline bool line_crosses_box(Vec3 lo, Vec3 hi, Vec3 o, Vec3 d) {
  float t0 = -std::numeric_limits<float>::infinity(), t1 = std::numeric_limits<float>::infinity();
  const float os[3] = {o.x, o.y, o.z}, ds[3] = {d.x, d.y, d.z}, ls[3] = {lo.x, lo.y, lo.z}, hs[3] = {hi.x, hi.y, hi.z};
  for (int a = 0; a < 3; ++a) {
    if (ds[a] == 0.0f) {
      if (os[a] < ls[a] || os[a] > hs[a]) return false;
      continue;
    }
    const float inv = 1.0f / ds[a];
    float ta = (ls[a] - os[a]) * inv, tb = (hs[a] - os[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1;
}

// A point where a line along unit d enters box [lo, hi], uniform over the
// box's projected area: a face turned towards the line chosen by its
// projected area with u0, a uniform point on it with what is left of u0 and u1.
inline Vec3 point_entering_box(Vec3 lo, Vec3 hi, Vec3 d, float u0, float u1) {
  const Vec3 e = hi - lo;
  const float w[3] = {std::fabs(d.x) * e.y * e.z, std::fabs(d.y) * e.x * e.z, std::fabs(d.z) * e.x * e.y};
  float v = u0 * (w[0] + w[1] + w[2]);
  int a = 0;
  while (a < 2 && (v >= w[a] || w[a] <= 0.0f)) v -= w[a++];
  const float s = w[a] > 0.0f ? std::clamp(v / w[a], 0.0f, 1.0f) : u0;
  const float ds[3] = {d.x, d.y, d.z}, ls[3] = {lo.x, lo.y, lo.z}, hs[3] = {hi.x, hi.y, hi.z}, es[3] = {e.x, e.y, e.z};
  float p[3];
  p[a] = ds[a] > 0.0f ? ls[a] : hs[a];
  p[(a + 1) % 3] = ls[(a + 1) % 3] + s * es[(a + 1) % 3];
  p[(a + 2) % 3] = ls[(a + 2) % 3] + u1 * es[(a + 2) % 3];
  return {p[0], p[1], p[2]};
}

// The density of the line o + t d per unit area across unit d.
inline float footprint_density(const Footprint& f, Vec3 o, Vec3 d) {
  float density = 0.0f;
  if (f.aim > 0.0f && line_crosses_box(f.lo, f.hi, o, d)) {
    const float a = projected_area(f.lo, f.hi, d);
    if (a > 0.0f) density += f.aim / a;
  }
  if (f.aim < 1.0f && line_crosses_box(f.scene_lo, f.scene_hi, o, d)) {
    const float a = projected_area(f.scene_lo, f.scene_hi, d);
    if (a > 0.0f) density += (1.0f - f.aim) / a;
  }
  return density;
}

// Where a photon travelling along unit d starts: the recording box (u0 below
// aim, rescaled) or the scene's box, uniform over its projected area, `reach`
// back along d.
inline Vec3 footprint_origin(const Footprint& f, Vec3 d, float u0, float u1) {
  const bool aimed = u0 < f.aim;
  if (f.aim < 1.0f) u0 = std::fmin(aimed ? u0 / f.aim : (u0 - f.aim) / (1.0f - f.aim), 0.99999994f);
  const Vec3 q = aimed ? point_entering_box(f.lo, f.hi, d, u0, u1)
                       : point_entering_box(f.scene_lo, f.scene_hi, d, u0, u1);
  return q - d * f.reach;
}

}  // namespace plm
