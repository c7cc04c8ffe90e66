#include "transport/emitters.h"

#include <cstring>

namespace plm {

float spot_attenuation(float c, float cos_half, float spot_smooth) {
  if (c <= cos_half) return 0.0f;
  const float t = c - cos_half;
  if (spot_smooth > 0.0f && t < spot_smooth) {
    const float x = t / spot_smooth;
    return c * x * x * (3.0f - 2.0f * x);
  }
  return c;
}

namespace {

Transform to_transform(const float m[16]) {
  Transform t;
  std::memcpy(t.m, m, sizeof(t.m));
  return t;
}

// Integral of spot_attenuation over the sphere of directions (midpoint rule in cos).
double spot_solid_angle_integral(float cos_half, float spot_smooth) {
  const int n = 4096;
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double c = cos_half + (1.0 - cos_half) * (i + 0.5) / n;
    sum += spot_attenuation(float(c), cos_half, spot_smooth);
  }
  return 2.0 * kPiD * sum * (1.0 - cos_half) / n;
}

Emitter light_emitter(const Light& light) {
  const plm_light& l = light.desc;
  const Transform m = to_transform(l.matrix);
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
      break;
    case PLM_LIGHT_SPOT: {
      e.kind = EmitterKind::Spot;
      e.radius = l.radius;
      e.normal = normalize(m.vector({0, 0, -1}));
      e.cos_half = std::cos(0.5f * l.spot_size);
      e.spot_smooth = (1.0f - e.cos_half) * l.spot_blend;
      const Vec3 intensity = color * (l.power / (4.0f * kPi));
      // Directions are drawn uniformly inside the cone and weighted by the falloff.
      e.scale = intensity * (2.0f * kPi * (1.0f - e.cos_half));
      e.flux = intensity * float(spot_solid_angle_integral(e.cos_half, e.spot_smooth));
      break;
    }
    case PLM_LIGHT_AREA_RECT:
    case PLM_LIGHT_AREA_DISK: {
      e.kind = l.type == PLM_LIGHT_AREA_RECT ? EmitterKind::AreaRect : EmitterKind::AreaDisk;
      e.axis_u = m.vector({0.5f * l.size_x, 0, 0});
      e.axis_v = m.vector({0, 0.5f * l.size_y, 0});
      e.normal = -normalize(cross(e.axis_u, e.axis_v));
      // Cycles: radiance P / (4 A), one-sided, so the flux pi L A = pi P / 4 whatever the size.
      e.flux = color * (kPi * l.power / 4.0f);
      e.scale = e.flux;
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

std::vector<Emitter> build_emitters(const Scene& scene, Vec3 center, float radius) {
  std::vector<Emitter> out;
  const float disk_area = kPi * radius * radius;
  for (const Light& light : scene.lights) {
    Emitter e = light_emitter(light);
    if (e.kind == EmitterKind::Sun) {
      // Irradiance S on a surface facing the sun: flux S through the disk that covers the scene.
      e.origin = center;
      e.radius = radius;
      make_frame(e.normal, e.axis_u, e.axis_v);
      const Vec3 color{light.desc.color[0], light.desc.color[1], light.desc.color[2]};
      e.flux = color * (light.desc.power * disk_area);
      e.scale = e.flux;
    }
    if (max_component(e.flux) > 0.0f) out.push_back(e);
  }
  for (const Mesh& mesh : scene.meshes) {
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      const Vec3 emission = scene.materials.empty() ? Vec3{} : scene.materials[mesh.material_ids[t]].emission;
      if (max_component(emission) <= 0.0f) continue;
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
      out.push_back(e);
    }
  }
  if (max_component(scene.world) > 0.0f) {
    // Uniform radiance from every direction: flux L * 4 pi * (disk area).
    Emitter e{};
    e.kind = EmitterKind::World;
    e.origin = center;
    e.radius = radius;
    e.flux = scene.world * (4.0f * kPi * disk_area);
    e.scale = e.flux;
    out.push_back(e);
  }
  return out;
}

EmitterSample sample_emitter(const Emitter& e, const float u[4]) {
  EmitterSample s;
  s.weight = e.scale;
  switch (e.kind) {
    case EmitterKind::Point:
    case EmitterKind::Spot: {
      if (e.kind == EmitterKind::Point) {
        s.direction = uniform_sphere(u[0], u[1]);
      } else {
        // Uniform in the cone around the axis.
        const float c = 1.0f - u[0] * (1.0f - e.cos_half);
        const float sn = std::sqrt(std::fmax(0.0f, 1.0f - c * c));
        const float phi = 2.0f * kPi * u[1];
        Vec3 t, b;
        make_frame(e.normal, t, b);
        s.direction = t * (sn * std::cos(phi)) + b * (sn * std::sin(phi)) + e.normal * c;
        s.weight = e.scale * spot_attenuation(c, e.cos_half, e.spot_smooth);
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
      Vec3 t, b;
      make_frame(e.normal, t, b);
      s.direction = t * local.x + b * local.y + e.normal * local.z;
      break;
    }
    case EmitterKind::Triangle: {
      float a = u[0], b = u[1];
      if (a + b > 1.0f) {
        a = 1.0f - a;
        b = 1.0f - b;
      }
      s.origin = e.origin + e.axis_u * a + e.axis_v * b;
      // Pick a side with u[2], reuse the remainder of it for the direction.
      const bool back = u[2] >= 0.5f;
      const float u2 = back ? 2.0f * u[2] - 1.0f : 2.0f * u[2];
      const Vec3 n = back ? -e.normal : e.normal;
      const Vec3 local = cosine_hemisphere(u2, u[3]);
      Vec3 t, bt;
      make_frame(n, t, bt);
      s.direction = t * local.x + bt * local.y + n * local.z;
      break;
    }
    case EmitterKind::Sun:
    case EmitterKind::World: {
      Vec3 d = e.normal, t = e.axis_u, b = e.axis_v;
      if (e.kind == EmitterKind::World) {
        d = uniform_sphere(u[0], u[1]);
        make_frame(d, t, b);
      } else if (e.cos_half < 1.0f) {
        // A direction uniform over the sun's disk of directions.
        const float c = 1.0f - u[0] * (1.0f - e.cos_half);
        const float sn = std::sqrt(std::fmax(0.0f, 1.0f - c * c));
        const float phi = 2.0f * kPi * u[1];
        d = t * (sn * std::cos(phi)) + b * (sn * std::sin(phi)) + e.normal * c;
        make_frame(d, t, b);
      }
      float x, y;
      concentric_disk(u[2], u[3], x, y);
      s.origin = e.origin + (t * x + b * y) * e.radius - d * (2.0f * e.radius);
      s.direction = d;
      break;
    }
  }
  return s;
}

}  // namespace plm

