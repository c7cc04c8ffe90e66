// libFuzzer target for the C API: the input is decoded into a
// sequence of calls (add material / material lobe / mesh / subdivision cage / light / CSG solid, set
// world / world map (from memory or an EXR file), bake, copy, write EXR, read warnings and stats,
// structs of the wrong size, light groups and their layers, release) with arbitrary floats, sizes and indices. The
// library must never crash, hang, leak or trip a sanitizer, and a bake that
// returns PLM_OK must give finite, non-negative lightmaps and statistics.
//
// Build and run: scripts/fuzz.sh [seconds]. Input format (all little endian):
// a stream of ops, one byte each, each followed by its operands: the bytes
// 208, 209, 210 and 211 are ops 13, 14, 15 and 16 (lobe, world map, struct
// sizes, light groups), every other byte is op byte % 13 (material ... start
// over). No fuzzer find in the corpus has one of the four as an op byte, so
// each decodes to the calls it was found with;
// a float operand is a tag byte and then either 4 raw bytes (tag % 8 == 0),
// one byte indexing kSpecialFloats (tag % 8 == 1), or one signed byte / 16.
// Reading past the end gives zeros. native/fuzz/make_corpus.py writes seeds.
// PHOTONLM_FUZZ_TRACE=1 prints the main calls of an input (crash -> test).
//
// Floats cover the full range by default. PHOTONLM_FUZZ_TAME=1 keeps finite
// floats within +-1e8, flushes magnitudes below 1e-6 to 0 and skips meshes
// with a triangle degenerate in float but not in double: the filter that let
// fuzzing go on while the bugs it first found (docs/robustness.md) were open.
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include "photonlm/photonlm.h"

namespace {

bool g_full_range = false;
bool g_trace = false;  // PHOTONLM_FUZZ_TRACE=1: print the calls (to turn a crash into a test)
std::string g_dir;  // a private temporary folder for EXR files

const float kSpecialFloats[] = {0.0f, -0.0f, 1.0f, -1.0f, 0.5f, 0.99f, 1.0000001f, 2.0f, 1e-30f, 1e-45f,
                                1.17549435e-38f, 1e8f, 1e15f, 1e19f, 1e30f, -1e30f, 3.4e38f, -3.4e38f,
                                NAN, -NAN, INFINITY, -INFINITY, 3.14159265f, 6.2831853f, 16384.0f, 1e-4f};

struct Reader {
  const uint8_t* p;
  size_t n;
  bool done() const { return n == 0; }
  uint8_t u8() {
    if (n == 0) return 0;
    --n;
    return *p++;
  }
  uint32_t u32() {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t(u8()) << (8 * i);
    return v;
  }
  uint16_t u16() { return uint16_t(u8() | (u8() << 8)); }
  float f() {
    const uint8_t tag = u8();
    float v;
    if (tag % 8 == 0) {
      const uint32_t bits = u32();
      std::memcpy(&v, &bits, sizeof v);
    } else if (tag % 8 == 1) {
      v = kSpecialFloats[u8() % (sizeof(kSpecialFloats) / sizeof(float))];
    } else {
      v = float(int8_t(u8())) / 16.0f;
    }
    if (!g_full_range && std::isfinite(v)) {
      if (std::fabs(v) > 1e8f) v = std::copysign(1e8f, v);
      if (std::fabs(v) < 1e-6f) v = 0.0f;  // denormal-small edges: NaN normals (known bug)
    }
    return v;
  }
  const char* name() {
    switch (u8() % 4) {
      case 0: return nullptr;
      case 1: return "";
      case 2: return "thing";
      default: return "a name with 'quotes' and \xc3\xa9";
    }
  }
  uint32_t lightmap_side() {
    static const uint32_t sides[] = {0, 1, 2, 3, 4, 5, 7, 8, 16, 0, 4, 16385, 0xFFFFFFFFu, 1, 2, 8};
    return sides[u8() % 16];
  }
};

struct State {
  plm_scene* scene = nullptr;
  plm_result* result = nullptr;
  uint32_t materials = 0, meshes = 0, csgs = 0;
  ~State() {
    plm_result_release(result);
    plm_scene_release(scene);
  }
};

void check(bool ok, const char* what) {
  if (!ok) {
    fprintf(stderr, "fuzz_scene_api: invariant broken: %s (last error: %s)\n", what, plm_last_error());
    abort();
  }
}

// Every call that fails leaves a message naming what was wrong.
void expect_message(plm_status s) {
  if (s != PLM_OK) check(plm_last_error()[0] != '\0', "a failed call left no message");
  check(plm_status_string(s)[0] != '\0', "status without a name");
}

// The size of T's older layout (photonlm.h "Struct sizes"), or the current
// one for a struct that has none: with the current one, the sizes the
// library must accept.
template <typename T>
uint32_t older_size() {
  return sizeof(T);
}
template <>
uint32_t older_size<plm_bake_settings>() {
  return offsetof(plm_bake_settings, texel_value);
}
template <>
uint32_t older_size<plm_bake_stats>() {
  return offsetof(plm_bake_stats, error_above);
}
template <>
uint32_t older_size<plm_lobe>() {
  return offsetof(plm_lobe, weight);
}
template <typename T>
bool known_size(uint32_t size) {
  return size == sizeof(T) || size == older_size<T>() ||
         (std::is_same_v<T, plm_bake_settings> && size == offsetof(plm_bake_settings, directional));
}

// A struct_size for T: mostly the current one, else the older layout, zero,
// a few bytes off, or garbage.
template <typename T>
uint32_t struct_size_of(Reader& in) {
  const uint32_t current = sizeof(T);
  switch (in.u8() % 8) {
    case 0: return 0;
    case 1: return older_size<T>();
    case 2: return current + 8;  // a newer header's
    case 3: return current - 4;
    case 4: return in.u32();
    default: return current;
  }
}

// Refused sizes must say so: PLM_ERROR_STRUCT_SIZE with a message naming the struct.
void expect_size_refused(plm_status s, const char* name) {
  check(s == PLM_ERROR_STRUCT_SIZE, "a struct_size the library does not know is refused");
  check(std::strstr(plm_last_error(), name) != nullptr, "a refused struct_size names the struct");
}

void check_result(const State& st) {
  plm_bake_stats stats;
  stats.struct_size = sizeof stats;
  check(plm_result_stats(st.result, &stats) == PLM_OK, "stats of a result");
  check(std::isfinite(stats.emitted_power) && stats.emitted_power >= 0, "emitted power finite");
  check(std::isfinite(stats.seconds_total), "seconds finite");
  for (uint32_t m = 0; m < st.meshes; ++m) {
    uint32_t w = 0, h = 0;
    if (plm_result_lightmap_size(st.result, m, &w, &h) != PLM_OK) continue;  // geometry-only mesh
    check(w > 0 && h > 0 && w <= 64 && h <= 64, "lightmap size as added");
    const size_t n = size_t(w) * h;
    std::vector<float> rgb(3 * n), err(n), hits(n), cov(n);
    check(plm_result_copy_lightmap(st.result, m, rgb.data(), err.data(), hits.data(), cov.data()) == PLM_OK,
          "copy a lightmap");
    for (float v : rgb) check(std::isfinite(v) && v >= 0.0f, "texel values finite and >= 0");
    for (float v : err) check(std::isfinite(v) && v >= 0.0f, "texel errors finite and >= 0");
    for (float v : hits) check(v >= 0.0f && v == std::floor(v), "hit counts are whole numbers");
    for (float v : cov) check(std::isfinite(v) && v >= 0.0f, "coverage finite and >= 0");
    if (plm_result_directional(st.result)) {  // SH bands: L0 the lightmap's, every band finite
      for (uint32_t band = 0; band < 4; ++band) {
        check(plm_result_copy_lightmap_sh(st.result, m, band, rgb.data()) == PLM_OK, "copy an SH band");
        for (float v : rgb) check(std::isfinite(v), "SH bands finite");
      }
    } else {
      check(plm_result_copy_lightmap_sh(st.result, m, 0, rgb.data()) == PLM_ERROR_INVALID_ARGUMENT,
            "no SH bands without directional lightmaps");
    }
  }
  for (uint32_t i = 0; i < plm_result_warning_count(st.result); ++i)
    check(plm_result_warning(st.result, i)[0] != '\0', "warnings are not empty");
}

int cancel_after(void* user, double fraction, const char* stage) {
  check(fraction >= 0.0 && fraction <= 1.0 && stage != nullptr, "progress fraction in [0, 1] with a stage");
  int* left = static_cast<int*>(user);
  return --*left > 0;
}

// Was a bug (HardCases.NearlyDegenerateTriangleDoesNotAbort, fixed): a
// triangle whose float cross product has no length but whose double area is
// > 0 got texels, a NaN normal, and NaN rays that aborted inside Embree. The
// tame mode still skips such meshes.
bool float_degenerate_only(const float* pos, const uint32_t* idx, uint32_t tc, uint32_t vc) {
  for (uint32_t t = 0; t < tc; ++t) {
    if (idx[3 * t] >= vc || idx[3 * t + 1] >= vc || idx[3 * t + 2] >= vc) return false;  // rejected anyway
    const float* p0 = pos + 3 * idx[3 * t];
    const float* p1 = pos + 3 * idx[3 * t + 1];
    const float* p2 = pos + 3 * idx[3 * t + 2];
    float e1[3], e2[3];
    double d1[3], d2[3];
    for (int k = 0; k < 3; ++k) {
      e1[k] = p1[k] - p0[k], e2[k] = p2[k] - p0[k];
      d1[k] = double(p1[k]) - p0[k], d2[k] = double(p2[k]) - p0[k];
    }
    const float c[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double dc[3] = {d1[1] * d2[2] - d1[2] * d2[1], d1[2] * d2[0] - d1[0] * d2[2], d1[0] * d2[1] - d1[1] * d2[0]};
    const float len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    const double dlen = std::sqrt(dc[0] * dc[0] + dc[1] * dc[1] + dc[2] * dc[2]);
    if (!(len > 0.0f && std::isfinite(len)) && dlen > 0.0) return true;
  }
  return false;
}

void add_mesh(State& st, Reader& in) {
  const char* name = in.name();
  const uint32_t vc = in.u8() % 10, tc = in.u8() % 10;
  std::vector<float> pos(3 * size_t(vc) + 1);
  for (uint32_t i = 0; i < 3 * vc; ++i) pos[i] = in.f();
  std::vector<uint32_t> idx(3 * size_t(tc) + 1);
  for (uint32_t i = 0; i < 3 * tc; ++i) idx[i] = in.u8() % (vc + 1);  // vc itself is out of range
  const uint8_t flags = in.u8();
  std::vector<float> uv(6 * size_t(tc) + 1);
  for (uint32_t i = 0; i < 6 * tc; ++i) uv[i] = in.f();
  std::vector<uint32_t> mats(size_t(tc) + 1);
  for (uint32_t i = 0; i < tc; ++i) mats[i] = in.u8() % (st.materials + 1);
  const uint32_t w = in.lightmap_side(), h = in.lightmap_side();
  if (!g_full_range && float_degenerate_only(pos.data(), idx.data(), tc, vc)) return;
  uint32_t id = 0;
  const plm_status s =
      plm_scene_add_mesh(flags & 1 ? st.scene : nullptr, name, flags & 2 ? pos.data() : nullptr, vc,
                         flags & 4 ? idx.data() : nullptr, tc, flags & 8 ? uv.data() : nullptr,
                         flags & 16 ? mats.data() : nullptr, w, h, &id);
  expect_message(s);
  if (g_trace) {
    fprintf(stderr, "add_mesh %u vertices:", vc);
    for (uint32_t i = 0; i < 3 * vc; ++i) fprintf(stderr, " %g", pos[i]);
    fprintf(stderr, "; %u triangles:", tc);
    for (uint32_t i = 0; i < 3 * tc; ++i) fprintf(stderr, " %u", idx[i]);
    fprintf(stderr, "; uv:");
    for (uint32_t i = 0; i < 6 * tc; ++i) fprintf(stderr, " %g", uv[i]);
    fprintf(stderr, "; materials:");
    for (uint32_t i = 0; i < tc; ++i) fprintf(stderr, " %u", mats[i]);
    fprintf(stderr, "; flags %u lightmap %u x %u -> %d\n", flags, w, h, int(s));
  }
  if (s == PLM_OK) check(id == st.meshes++, "mesh ids count up");
}

// A subdivision cage: polygons of 2 to 6 corners (2 is invalid), indices
// that may be out of range, optional UVs, materials and creases, level 0-4.
void add_subdiv(State& st, Reader& in) {
  const char* name = in.name();
  const uint32_t vc = in.u8() % 12, fc = in.u8() % 8;
  std::vector<float> pos(3 * size_t(vc) + 1);
  for (uint32_t i = 0; i < 3 * vc; ++i) pos[i] = in.f();
  std::vector<uint32_t> sizes(size_t(fc) + 1);
  uint32_t corners = 0;
  for (uint32_t f = 0; f < fc; ++f) corners += sizes[f] = 2 + in.u8() % 5;
  std::vector<uint32_t> idx(size_t(corners) + 1);
  for (uint32_t i = 0; i < corners; ++i) idx[i] = in.u8() % (vc + 1);  // vc itself is out of range
  std::vector<float> uv(2 * size_t(corners) + 1);
  for (uint32_t i = 0; i < 2 * corners; ++i) uv[i] = in.f();
  std::vector<uint32_t> mats(size_t(fc) + 1);
  for (uint32_t f = 0; f < fc; ++f) mats[f] = in.u8() % (st.materials + 1);
  const uint32_t cc = in.u8() % 4;
  std::vector<uint32_t> edges(2 * size_t(cc) + 1);
  std::vector<float> weights(size_t(cc) + 1);
  for (uint32_t i = 0; i < cc; ++i) {
    edges[2 * i] = in.u8() % (vc + 1), edges[2 * i + 1] = in.u8() % (vc + 1);
    weights[i] = in.f();
  }
  const uint8_t flags = in.u8();
  const uint32_t level = in.u8() % 5, w = in.lightmap_side(), h = in.lightmap_side();
  uint32_t id = 0;
  const plm_status s = plm_scene_add_subdiv_mesh(
      st.scene, name, flags & 1 ? pos.data() : nullptr, vc, flags & 2 ? sizes.data() : nullptr, fc,
      flags & 4 ? idx.data() : nullptr, flags & 8 ? uv.data() : nullptr, flags & 16 ? mats.data() : nullptr,
      flags & 32 ? edges.data() : nullptr, flags & 32 ? weights.data() : nullptr, flags & 32 ? cc : 0, level, w, h,
      &id);
  expect_message(s);
  if (g_trace) fprintf(stderr, "add_subdiv %u vertices %u faces level %u flags %u -> %d\n", vc, fc, level, flags, int(s));
  if (s == PLM_OK) check(id == st.meshes++, "mesh ids count up");
}

// A well-formed quad or box-like fan, so that many inputs reach the bake.
void add_quad(State& st, Reader& in) {
  const float o[3] = {in.f(), in.f(), in.f()}, a[3] = {in.f(), in.f(), in.f()}, b[3] = {in.f(), in.f(), in.f()};
  const float pos[12] = {o[0], o[1], o[2], o[0] + a[0], o[1] + a[1], o[2] + a[2],
                         o[0] + a[0] + b[0], o[1] + a[1] + b[1], o[2] + a[2] + b[2], o[0] + b[0], o[1] + b[1], o[2] + b[2]};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  const uint32_t mats[2] = {in.u8() % (st.materials + 1), 0};
  const uint32_t res = 1 + in.u8() % 8;
  if (!g_full_range && float_degenerate_only(pos, idx, 2, 4)) return;
  uint32_t id = 0;
  const plm_status s = plm_scene_add_mesh(st.scene, "quad", pos, 4, idx, 2, uv, st.materials ? mats : nullptr,
                                          res, res, &id);
  if (g_trace)
    fprintf(stderr, "add_quad o (%g %g %g) a (%g %g %g) b (%g %g %g) material %u res %u -> %d\n", o[0], o[1], o[2],
            a[0], a[1], a[2], b[0], b[1], b[2], mats[0], res, int(s));
  expect_message(s);
  if (s == PLM_OK) check(id == st.meshes++, "mesh ids count up");
}

// A lobe on a material (ids may be out of range), with arbitrary values and
// sometimes a struct_size the library does not know.
void add_lobe(State& st, Reader& in) {
  const uint32_t material = in.u8() % (st.materials + 2);
  const int type = int(in.u8() % 8) - 1;  // -1 and 6 are invalid
  plm_lobe l;
  plm_lobe_default(&l, plm_lobe_type(type < 0 || type > 5 ? 0 : type));
  l.type = type;
  const uint8_t fields = in.u8();
  if (fields & 1)
    for (float& c : l.color) c = in.f();
  if (fields & 2) l.roughness = in.f();
  if (fields & 4) l.ior = in.f();
  if (fields & 8) l.abbe = in.f();
  if (fields & 16) l.weight = in.f();
  if (fields & 32) l.struct_size = struct_size_of<plm_lobe>(in);
  const bool null_scene = fields & 128, null_lobe = (fields & 64) && (fields & 32);
  const plm_status s = plm_scene_add_material_lobe(null_scene ? nullptr : st.scene, material, null_lobe ? nullptr : &l);
  expect_message(s);
  if (!null_scene && !null_lobe && !known_size<plm_lobe>(l.struct_size)) expect_size_refused(s, "plm_lobe");
  if (g_trace)
    fprintf(stderr,
            "add_lobe material %u type %d color (%g %g %g) roughness %g ior %g abbe %g weight %g size %u -> %d\n",
            material, l.type, l.color[0], l.color[1], l.color[2], l.roughness, l.ior, l.abbe, l.weight,
            l.struct_size, int(s));
}

// An environment map as the world, from memory or from an EXR file written
// here: 0-8 pixels a side (0 and over 2^28 pixels are errors), arbitrary or
// small positive pixels, no, an arbitrary or a turning rotation.
void set_world_map(State& st, Reader& in) {
  const uint8_t flags = in.u8();
  uint32_t w = in.u8() % 9, h = in.u8() % 9;
  std::vector<float> rgb(3 * size_t(w) * h + 1);
  for (size_t i = 0; i + 1 < rgb.size(); ++i) rgb[i] = flags & 2 ? in.f() : float(in.u8()) / 64.0f;
  float rotation[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  if (flags & 8) {
    for (float& r : rotation) r = in.f();
  } else {  // about z
    const float a = in.f(), c = std::cos(a), s = std::sin(a);
    rotation[0] = c, rotation[1] = -s, rotation[3] = s, rotation[4] = c;
  }
  const float strength = in.f();
  const float* rot = flags & 4 ? nullptr : rotation;
  plm_status s;
  if (flags & 16) {  // through a file: written when it can be, else a missing or empty name
    const std::string path = g_dir + "/world.exr";
    const bool written =
        w > 0 && h > 0 && plm_write_lightmap_exr(path.c_str(), w, h, rgb.data(), nullptr, nullptr) == PLM_OK;
    const std::string missing = g_dir + "/missing.exr";
    const char* name = flags & 32 ? (flags & 64 ? nullptr : "") : written ? path.c_str() : missing.c_str();
    s = plm_scene_set_world_map_file(st.scene, name, rot, strength);
    if (written) check(unlink(path.c_str()) == 0, "the world map file exists after writing it");
  } else {
    if (flags & 1) w = 1u << 15, h = 1u << 14;  // 2^29 pixels: refused before any is read
    s = plm_scene_set_world_map(flags & 128 ? nullptr : st.scene, flags & 64 ? nullptr : rgb.data(), w, h, rot,
                                strength);
  }
  expect_message(s);
  if (g_trace) fprintf(stderr, "set_world_map %u x %u flags %u strength %g -> %d\n", w, h, flags, strength, int(s));
}

// Structs whose struct_size may be wrong, older or current: the library takes
// the sizes it knows, refuses the others naming the struct, and writes no
// byte past the caller's size.
void struct_sizes(State& st, Reader& in) {
  switch (in.u8() % 3) {
    case 0: {  // stats into a guarded buffer
      unsigned char buf[sizeof(plm_bake_stats) + 64];
      std::memset(buf, 0xA5, sizeof buf);
      const uint32_t size = struct_size_of<plm_bake_stats>(in);
      std::memcpy(buf, &size, sizeof size);
      const plm_status s = plm_result_stats(st.result, reinterpret_cast<plm_bake_stats*>(buf));
      expect_message(s);
      const bool known = known_size<plm_bake_stats>(size);
      if (st.result && !known) expect_size_refused(s, "plm_bake_stats");
      if (st.result && known) check(s == PLM_OK, "stats of a known size are written");
      const size_t untouched = s == PLM_OK ? size : sizeof size;
      for (size_t i = untouched; i < sizeof buf; ++i) check(buf[i] == 0xA5, "no byte past struct_size is written");
      uint32_t kept;
      std::memcpy(&kept, buf, sizeof kept);
      check(kept == size, "struct_size is left as the caller set it");
      break;
    }
    case 1: {  // settings of any size for a small bake
      plm_bake_settings s;
      plm_bake_settings_default(&s);
      s.photon_count = in.u16() % 501;
      s.direct_samples = in.u8() % 3;
      s.max_bounces = in.u8() % 9;
      s.thread_count = 1;
      s.struct_size = struct_size_of<plm_bake_settings>(in);
      plm_result* r = nullptr;
      const plm_status status = plm_bake(st.scene, &s, nullptr, nullptr, &r);
      expect_message(status);
      if (!known_size<plm_bake_settings>(s.struct_size)) expect_size_refused(status, "plm_bake_settings");
      if (g_trace) fprintf(stderr, "bake with struct_size %u -> %d\n", s.struct_size, int(status));
      if (status == PLM_OK) {
        plm_result_release(st.result);
        st.result = r;
        check_result(st);
      }
      break;
    }
    default: {  // a light, or CSG nodes whose elements disagree on their size
      if (in.u8() & 1) {
        plm_light l;
        plm_light_default(&l, PLM_LIGHT_POINT);
        l.struct_size = struct_size_of<plm_light>(in);
        const plm_status s = plm_scene_add_light(st.scene, in.name(), &l, nullptr);
        expect_message(s);
        if (!known_size<plm_light>(l.struct_size)) expect_size_refused(s, "plm_light");
      } else {
        plm_csg_primitive p{};
        p.struct_size = sizeof p;
        p.matrix[0] = p.matrix[5] = p.matrix[10] = 1.0;
        plm_csg_node nodes[2] = {{sizeof(plm_csg_node), PLM_CSG_UNION, 0, 1},
                                 {sizeof(plm_csg_node), PLM_CSG_LEAF, 0, 0}};
        nodes[in.u8() % 2].struct_size = struct_size_of<plm_csg_node>(in);
        const uint32_t child = 1;
        const plm_status s = plm_scene_add_csg(st.scene, in.name(), &p, 1, nodes, 2, &child, 1, 0, nullptr);
        expect_message(s);
        if (nodes[0].struct_size != sizeof(plm_csg_node) || nodes[1].struct_size != sizeof(plm_csg_node))
          expect_size_refused(s, "plm_csg_node");
        else if (s == PLM_OK)
          st.csgs++;
      }
      break;
    }
  }
}

void add_light(State& st, Reader& in) {
  plm_light l;
  const int type = int(in.u8() % 8) - 1;  // -1 and 6 are invalid, 5 is a portal
  plm_light_default(&l, plm_light_type(type < 0 || type > 5 ? 0 : type));
  l.type = type;
  const uint8_t fields = in.u8();
  if (fields & 1) l.power = in.f();
  if (fields & 2) l.radius = in.f();
  if (fields & 4) l.angle = in.f();
  if (fields & 8) l.size_x = in.f(), l.size_y = in.f();
  if (fields & 16) l.spot_size = in.f(), l.spot_blend = in.f();
  if (fields & 32)
    for (float& c : l.color) c = in.f();
  for (int k = in.u8() % 5; k > 0; --k) {
    const uint8_t element = in.u8() % 16;  // read before the value: C++17 evaluates `a[i()] = f()` right to left
    l.matrix[element] = in.f();
  }
  const plm_status s = plm_scene_add_light(fields & 128 ? nullptr : st.scene, in.name(), fields & 64 ? nullptr : &l,
                                           nullptr);
  expect_message(s);
  if (g_trace) {
    fprintf(stderr, "add_light type %d power %g color (%g %g %g) radius %g angle %g size %g x %g spot %g/%g matrix",
            l.type, l.power, l.color[0], l.color[1], l.color[2], l.radius, l.angle, l.size_x, l.size_y, l.spot_size,
            l.spot_blend);
    for (float v : l.matrix) fprintf(stderr, " %g", v);
    fprintf(stderr, " -> %d\n", int(s));
  }
}

void bake(State& st, Reader& in) {
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = in.u16() % 2001;
  s.max_bounces = in.u8() % 17;
  s.seed = in.u32();
  // One thread: an abort on two TBB workers at once kills libFuzzer before it
  // writes the crash input (seen with Embree's assertions). The unit tests
  // cover threads.
  s.thread_count = 1 + 0 * in.u8();
  const uint8_t flags = in.u8();
  s.dilation = flags & 1 ? 5000 : flags % 10;
  s.direct_samples = in.u8() % 5;
  if (flags & 2) {  // steering, always with a small photon cap and time budget
    s.target_error = in.f();
    s.time_budget = std::fmod(std::fabs(in.f()), 0.05f);
    if (s.photon_count == 0) s.photon_count = 1;
  }
  if (flags & 4) s.filter_radius = in.u8() % 70;  // above 64 is an error
  if (flags & 64) s.directional = 1;
  int calls = 1 + in.u8() % 8;
  // NULL settings mean the defaults, a million photons: too slow to fuzz, so
  // only on a scene without meshes, which fails before tracing.
  const bool null_settings = (flags & 8) && st.meshes == 0;
  plm_result* r = reinterpret_cast<plm_result*>(&st);  // must be overwritten
  const plm_status status =
      plm_bake(flags & 32 ? nullptr : st.scene, null_settings ? nullptr : &s, flags & 16 ? cancel_after : nullptr,
               &calls, &r);
  expect_message(status);
  if (g_trace)
    fprintf(stderr, "bake photons %llu bounces %u seed %u direct %u dilation %u -> %d %s\n",
            (unsigned long long)s.photon_count, s.max_bounces, s.seed, s.direct_samples, s.dilation, int(status),
            status == PLM_OK ? "" : plm_last_error());
  if (status != PLM_OK) {
    // With a NULL scene plm_bake returns before touching out_result.
    check(r == nullptr || (flags & 32), "a failed bake returns no result");
    return;
  }
  plm_result_release(st.result);
  st.result = r;
  check_result(st);
}

// Light groups: a group declared (any name), a light, a mesh or the world put
// into a group (any ids), then a layer of the last result copied: finite.
void light_groups(State& st, Reader& in) {
  uint32_t id = 0;
  const uint8_t what = in.u8();
  if (what & 1) expect_message(plm_scene_add_light_group(st.scene, in.name(), &id));
  const uint32_t group = in.u8() % 4, target = in.u8() % 8;
  switch (what >> 1 & 3) {
    case 0: expect_message(plm_scene_set_light_group(st.scene, target, group)); break;
    case 1: expect_message(plm_scene_set_mesh_light_group(st.scene, target, group)); break;
    case 2: expect_message(plm_scene_set_world_light_group(st.scene, group)); break;
    default: break;
  }
  const uint32_t layers = plm_result_layer_count(st.result), layer = in.u8() % (layers + 2);
  (void)plm_result_layer_name(st.result, layer);
  double error = 0.0;
  const plm_status e = plm_result_layer_error(st.result, layer, &error);
  expect_message(e);
  if (e == PLM_OK) check(std::isfinite(error) && error >= 0.0, "a layer's error is finite");
  const uint32_t mesh = in.u8() % (st.meshes + 2);
  uint32_t w = 0, h = 0;
  if (plm_result_lightmap_size(st.result, mesh, &w, &h) != PLM_OK) return;
  std::vector<float> rgb(3 * size_t(w) * h), err(size_t(w) * h);
  const plm_status s = plm_result_copy_lightmap_layer(st.result, mesh, layer, rgb.data(), err.data());
  expect_message(s);
  if (s != PLM_OK) return;
  for (const float v : rgb) check(std::isfinite(v), "a layer's texels are finite");
  for (const float v : err) check(std::isfinite(v) && v >= 0.0f, "a layer's errors are finite, >= 0");
}

void copy(State& st, Reader& in) {
  const uint32_t mesh = in.u8() % (st.meshes + 2);
  uint32_t w = 0, h = 0;
  const plm_status s = plm_result_lightmap_size(st.result, mesh, &w, &h);
  expect_message(s);
  if (s != PLM_OK) {
    float dummy[3];
    expect_message(plm_result_copy_lightmap(st.result, mesh, dummy, dummy, dummy, dummy));
    return;
  }
  const size_t n = size_t(w) * h;
  std::vector<float> rgb(3 * n), err(n), hits(n), cov(n);
  const uint8_t which = in.u8();
  expect_message(plm_result_copy_lightmap(st.result, mesh, which & 1 ? rgb.data() : nullptr,
                                          which & 2 ? err.data() : nullptr, which & 4 ? hits.data() : nullptr,
                                          which & 8 ? cov.data() : nullptr));
}

// A CSG solid: 1-4 primitives with arbitrary or plausible matrices, a small
// arbitrary tree (cycles, bad indices and unbounded trees included).
void add_csg(State& st, Reader& in) {
  plm_csg_primitive prims[4];
  const uint32_t np = 1 + in.u8() % 4;
  for (uint32_t i = 0; i < np; ++i) {
    plm_csg_primitive& p = prims[i];
    p.struct_size = sizeof p;
    p.shape = in.u8() % 8;
    p.material = in.u8() % (st.materials + 2);
    if (in.u8() & 1) {
      for (double& m : p.matrix) m = in.f();
    } else {  // a scaled, translated canonical shape
      const double k = in.f();
      const double m[12] = {k, 0, 0, in.f(), 0, k, 0, in.f(), 0, 0, k, in.f()};
      for (int j = 0; j < 12; ++j) p.matrix[j] = m[j];
    }
    p.major_radius = in.f();
    p.minor_radius = in.f();
  }
  plm_csg_node nodes[6];
  const uint32_t nn = 1 + in.u8() % 6;
  for (uint32_t i = 0; i < nn; ++i) {
    nodes[i].struct_size = sizeof nodes[i];
    nodes[i].op = in.u8() % 5;
    nodes[i].first = in.u8() % 8;
    nodes[i].count = in.u8() % 4;
  }
  uint32_t children[8];
  const uint32_t nc = in.u8() % 8;
  for (uint32_t i = 0; i < nc; ++i) children[i] = in.u8() % 8;
  uint32_t id = 0;
  const plm_status s = plm_scene_add_csg(st.scene, in.name(), prims, np, nodes, nn, nc ? children : nullptr, nc,
                                         in.u8() % 8, &id);
  expect_message(s);
  if (g_trace) fprintf(stderr, "add_csg %u primitives, %u nodes, %u children -> %d\n", np, nn, nc, int(s));
  if (s == PLM_OK) check(id == st.csgs++, "CSG ids count up");
}

void write_exr(State& st, Reader& in) {
  const uint32_t mesh = in.u8() % (st.meshes + 2);
  const uint8_t where = in.u8() % 4;
  std::string path = g_dir + "/lightmap.exr";
  if (where == 1) path = g_dir + "/missing/lightmap.exr";
  if (where == 2) path = "";
  const plm_status s = plm_result_write_exr(st.result, mesh, where == 3 ? nullptr : path.c_str());
  expect_message(s);
  if (s == PLM_OK) check(unlink(path.c_str()) == 0, "the EXR file exists after PLM_OK");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* tame = getenv("PHOTONLM_FUZZ_TAME");
  g_full_range = !(tame && *tame && *tame != '0');
  const char* trace = getenv("PHOTONLM_FUZZ_TRACE");
  g_trace = trace && *trace && *trace != '0';
  char tmpl[] = "/tmp/photonlm_fuzz_XXXXXX";
  const char* dir = mkdtemp(tmpl);
  if (!dir) abort();
  g_dir = dir;
  atexit([] { rmdir(g_dir.c_str()); });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Reader in{data, size};
  State st;
  check(plm_scene_create(&st.scene) == PLM_OK, "create a scene");
  for (int ops = 0; ops < 48 && !in.done(); ++ops) {
    const uint8_t byte = in.u8();
    switch (byte >= 208 && byte <= 211 ? 13 + (byte - 208) : byte % 13) {
      case 0: {
        const char* name = in.name();
        float albedo[3], emission[3];
        for (float& v : albedo) v = in.f();
        for (float& v : emission) v = in.f();
        const uint8_t nulls = in.u8();
        uint32_t id = 0;
        const plm_status s = plm_scene_add_material(st.scene, name, nulls & 1 ? nullptr : albedo,
                                                    nulls & 2 ? nullptr : emission, &id);
        expect_message(s);
        if (g_trace)
          fprintf(stderr, "add_material albedo (%g %g %g) emission (%g %g %g) -> %d\n", albedo[0], albedo[1],
                  albedo[2], emission[0], emission[1], emission[2], int(s));
        if (s == PLM_OK) check(id == st.materials++, "material ids count up");
        break;
      }
      case 1: add_mesh(st, in); break;
      case 2: add_quad(st, in); break;
      case 3: add_light(st, in); break;
      case 4: {
        float world[3];
        for (float& v : world) v = in.f();
        expect_message(plm_scene_set_world(in.u8() & 1 ? st.scene : nullptr, world));
        break;
      }
      case 5: bake(st, in); break;
      case 6: copy(st, in); break;
      case 7: write_exr(st, in); break;
      case 8: {
        const uint32_t i = in.u8();
        (void)plm_result_warning(st.result, plm_result_warning_count(st.result) + i);
        plm_bake_stats stats;
        stats.struct_size = sizeof stats;
        expect_message(plm_result_stats(st.result, i & 1 ? &stats : nullptr));
        break;
      }
      case 9: add_csg(st, in); break;
      case 10: {
        const uint32_t csg = in.u8() % (st.csgs + 1), mesh = in.u8() % (st.meshes + 1);
        expect_message(plm_scene_set_csg_carrier(st.scene, csg, mesh));
        break;
      }
      case 11: add_subdiv(st, in); break;
      case 13: add_lobe(st, in); break;
      case 14: set_world_map(st, in); break;
      case 15: struct_sizes(st, in); break;
      case 16: light_groups(st, in); break;
      default:  // 12: start over with an empty scene
        plm_result_release(st.result);
        st.result = nullptr;
        plm_scene_release(st.scene);
        st.scene = nullptr;
        st.materials = st.meshes = st.csgs = 0;
        check(plm_scene_create(&st.scene) == PLM_OK, "create a scene");
        break;
    }
  }
  return 0;
}
