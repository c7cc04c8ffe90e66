#include "demo_scenes.h"

#include <cmath>

namespace plm_demo {

SceneBuilder::SceneBuilder() { check(plm_scene_create(&scene)); }
SceneBuilder::~SceneBuilder() { plm_scene_release(scene); }

void SceneBuilder::check(plm_status s) {
  if (s != PLM_OK && status == PLM_OK) {
    status = s;
    error = plm_last_error();
  }
}

uint32_t SceneBuilder::material(const char* name, V3 albedo, V3 emission) {
  const float a[3] = {albedo.x, albedo.y, albedo.z}, e[3] = {emission.x, emission.y, emission.z};
  uint32_t id = 0;
  check(plm_scene_add_material(scene, name, a, e, &id));
  return id;
}

uint32_t SceneBuilder::quad(const char* name, V3 o, V3 eu, V3 ev, uint32_t material, uint32_t res, uint32_t n) {
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  std::vector<float> uv;
  for (uint32_t j = 0; j <= n; ++j) {
    for (uint32_t i = 0; i <= n; ++i) {
      const float s = float(i) / n, t = float(j) / n;
      pos.insert(pos.end(), {o.x + s * eu.x + t * ev.x, o.y + s * eu.y + t * ev.y, o.z + s * eu.z + t * ev.z});
    }
  }
  for (uint32_t j = 0; j < n; ++j) {
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      const float s0 = float(i) / n, s1 = float(i + 1) / n, t0 = float(j) / n, t1 = float(j + 1) / n;
      idx.insert(idx.end(), {a, b, d, a, d, c});
      uv.insert(uv.end(), {s0, t0, s1, t0, s1, t1, s0, t0, s1, t1, s0, t1});
    }
  }
  std::vector<uint32_t> mats(idx.size() / 3, material);
  uint32_t id = 0;
  check(plm_scene_add_mesh(scene, name, pos.data(), uint32_t(pos.size() / 3), idx.data(), uint32_t(idx.size() / 3),
                           res ? uv.data() : nullptr, mats.data(), res, res, &id));
  mesh_names.push_back(name);
  return id;
}

uint32_t SceneBuilder::box(const char* name, V3 c, V3 size, float angle_z, uint32_t material, uint32_t face_res,
                           bool inward) {
  const float cs = std::cos(angle_z), sn = std::sin(angle_z);
  auto corner = [&](float sx, float sy, float sz) {
    const float x = 0.5f * size.x * sx, y = 0.5f * size.y * sy, z = 0.5f * size.z * sz;
    return V3{c.x + cs * x - sn * y, c.y + sn * x + cs * y, c.z + z};
  };
  // Each face: a corner and two edges (counter-clockwise seen from outside).
  struct Face {
    float o[3], u[3], v[3];
  };
  const Face faces[6] = {
      {{-1, -1, 1}, {1, 0, 0}, {0, 1, 0}},   // +z
      {{-1, 1, -1}, {1, 0, 0}, {0, -1, 0}},  // -z
      {{1, -1, -1}, {0, 1, 0}, {0, 0, 1}},   // +x
      {{-1, 1, -1}, {0, -1, 0}, {0, 0, 1}},  // -x
      {{1, 1, -1}, {-1, 0, 0}, {0, 0, 1}},   // +y
      {{-1, -1, -1}, {1, 0, 0}, {0, 0, 1}},  // -y
  };
  std::vector<float> pos, uv;
  std::vector<uint32_t> idx;
  for (int f = 0; f < 6; ++f) {
    const Face& F = faces[f];
    const V3 p[4] = {corner(F.o[0], F.o[1], F.o[2]),
                     corner(F.o[0] + 2 * F.u[0], F.o[1] + 2 * F.u[1], F.o[2] + 2 * F.u[2]),
                     corner(F.o[0] + 2 * F.u[0] + 2 * F.v[0], F.o[1] + 2 * F.u[1] + 2 * F.v[1],
                            F.o[2] + 2 * F.u[2] + 2 * F.v[2]),
                     corner(F.o[0] + 2 * F.v[0], F.o[1] + 2 * F.v[1], F.o[2] + 2 * F.v[2])};
    const uint32_t base = uint32_t(pos.size() / 3);
    for (const V3& q : p) pos.insert(pos.end(), {q.x, q.y, q.z});
    if (inward) idx.insert(idx.end(), {base, base + 2, base + 1, base, base + 3, base + 2});
    else idx.insert(idx.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    // Atlas cell (f % 3, f / 3) of a 3 x 2 grid, with a one-texel margin when there is room.
    const float cw = 1.0f / 3.0f, ch = 0.5f;
    const float mx = face_res > 4 ? 1.0f / (3.0f * face_res) : 0.0f, my = face_res > 4 ? 1.0f / (2.0f * face_res) : 0.0f;
    const float u0 = (f % 3) * cw + mx, u1 = (f % 3 + 1) * cw - mx, v0 = (f / 3) * ch + my, v1 = (f / 3 + 1) * ch - my;
    const float cu[4] = {u0, u1, u1, u0}, cv[4] = {v0, v0, v1, v1};
    const int order[6] = {0, inward ? 2 : 1, inward ? 1 : 2, 0, inward ? 3 : 2, inward ? 2 : 3};
    for (int k : order) uv.insert(uv.end(), {cu[k], cv[k]});
  }
  std::vector<uint32_t> mats(idx.size() / 3, material);
  uint32_t id = 0;
  check(plm_scene_add_mesh(scene, name, pos.data(), uint32_t(pos.size() / 3), idx.data(), uint32_t(idx.size() / 3),
                           face_res ? uv.data() : nullptr, mats.data(), 3 * face_res, 2 * face_res, &id));
  mesh_names.push_back(name);
  return id;
}

void SceneBuilder::light(const plm_light& l, const char* name) { check(plm_scene_add_light(scene, name, &l, nullptr)); }

void build_furnace(SceneBuilder& b, float rho, float emission, uint32_t face_res) {
  const uint32_t m = b.material("furnace", {rho, rho, rho}, {emission, emission, emission});
  b.box("furnace", {0, 0, 0}, {2, 2, 2}, 0.0f, m, face_res, true);
}

void build_cornell(SceneBuilder& b, uint32_t res, float watts) {
  const uint32_t white = b.material("white", {0.8f, 0.8f, 0.8f});
  const uint32_t red = b.material("red", {0.8f, 0.1f, 0.1f});
  const uint32_t green = b.material("green", {0.1f, 0.8f, 0.1f});
  b.quad("floor", {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, white, res);
  b.quad("ceiling", {-1, 1, 2}, {2, 0, 0}, {0, -2, 0}, white, res);
  b.quad("back", {-1, 1, 0}, {2, 0, 0}, {0, 0, 2}, white, res);
  b.quad("left", {-1, -1, 0}, {0, 2, 0}, {0, 0, 2}, red, res);
  b.quad("right", {1, 1, 0}, {0, -2, 0}, {0, 0, 2}, green, res);
  b.box("tall_box", {-0.35f, 0.3f, 0.6f}, {0.6f, 0.6f, 1.2f}, 0.3f, white, res / 2);
  b.box("short_box", {0.4f, -0.35f, 0.3f}, {0.6f, 0.6f, 0.6f}, -0.3f, white, res / 2);
  plm_light l;
  plm_light_default(&l, PLM_LIGHT_AREA_RECT);
  l.power = watts;
  l.size_x = l.size_y = 0.5f;
  l.matrix[11] = 1.98f;  // translation z; the light faces down (-Z)
  b.light(l, "ceiling_light");
}

}  // namespace plm_demo
