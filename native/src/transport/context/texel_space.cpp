#include "transport/context/texel_space.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "transport/plan/validate.h"

namespace plm {
namespace {

// The side of the CSG solid's own texels: the carrier's texel side (its
// surface area per covered texel), so that both hold about as many photons.
double carrier_texel_size(const TexelAreas& areas, Vec3d extent) {
  double area = 0.0, cover = 0.0;
  for (size_t t = 0; t < areas.area.size(); ++t) area += areas.area[t], cover += areas.coverage[t];
  if (area > 0.0 && cover > 0.0) return std::sqrt(area / cover);
  return 0.01 * std::max({extent.x, extent.y, extent.z, 1e-30});
}

// Morton code of p in [lo, hi]: 10 bits an axis, interleaved.
uint32_t morton(Vec3d p, Vec3d lo, Vec3d hi) {
  auto spread = [](uint32_t v) {  // 10 bits to every third of 30
    v = (v | (v << 16)) & 0x030000FFu;
    v = (v | (v << 8)) & 0x0300F00Fu;
    v = (v | (v << 4)) & 0x030C30C3u;
    return (v | (v << 2)) & 0x09249249u;
  };
  auto cell = [](double x, double a, double b) {
    const double f = b > a ? (x - a) / (b - a) : 0.0;
    return uint32_t(std::clamp(f, 0.0, 1.0) * 1023.0);
  };
  return spread(cell(p.x, lo.x, hi.x)) | spread(cell(p.y, lo.y, hi.y)) << 1 | spread(cell(p.z, lo.z, hi.z)) << 2;
}

}  // namespace

void judge_groups(const Scene& scene, TexelSpace& s) {
  const size_t units = s.covered_begin.size();
  s.judged.assign(units, kNoGroup);
  s.judged_groups = 0;
  // Each unit's bounding box centre.
  std::vector<Vec3d> centre(units, Vec3d{0, 0, 0});
  Vec3d lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (size_t u = 0; u < units; ++u) {
    Vec3d a{1e300, 1e300, 1e300}, b{-1e300, -1e300, -1e300};
    if (u < scene.meshes.size()) {
      const Mesh& m = scene.meshes[u];
      for (uint32_t v = 0; v < m.vertex_count; ++v) a = min(a, to_double(m.positions[v])), b = max(b, to_double(m.positions[v]));
    } else {
      const csg::CsgObject& o = *scene.csgs[u - scene.meshes.size()].object;
      a = o.bounds_lo(), b = o.bounds_hi();
    }
    if (!(a.x <= b.x)) continue;
    centre[u] = (a + b) * 0.5;
    lo = min(lo, centre[u]), hi = max(hi, centre[u]);
  }
  std::vector<std::pair<uint32_t, uint32_t>> small;  // (Morton code, unit)
  for (size_t u = 0; u < units; ++u) {
    const size_t texels = s.covered_count(u);
    if (texels == 0) continue;
    if (texels >= kJudgedTexels) s.judged[u] = s.judged_groups++;
    else small.push_back({morton(centre[u], lo, hi), uint32_t(u)});
  }
  std::sort(small.begin(), small.end());
  uint64_t in_group = 0;
  uint32_t first_small = s.judged_groups;
  for (const auto& [code, u] : small) {
    if (in_group == 0 || in_group >= kJudgedTexels) s.judged[u] = s.judged_groups++, in_group = 0;
    else s.judged[u] = s.judged_groups - 1;
    in_group += s.covered_count(u);
  }
  // A last short group joins the one before it (if there is one among the small).
  if (in_group > 0 && in_group < kJudgedTexels && s.judged_groups >= first_small + 2) {
    const uint32_t last = s.judged_groups - 1;
    for (const auto& [code, u] : small)
      if (s.judged[u] == last) s.judged[u] = last - 1;
    --s.judged_groups;
  }
}

TexelSpace build_texel_space(const Scene& scene, std::vector<std::string>& warnings) {
  TexelSpace s;
  s.areas.resize(scene.meshes.size());
  s.views.resize(scene.meshes.size());
  s.normals.resize(scene.meshes.size());
  s.covered_begin.assign(scene.meshes.size(), 0);
  // Normals and texel areas per mesh in parallel (the caller's arena), the
  // global texel order and the warnings in mesh order after.
  tbb::parallel_for(size_t(0), scene.meshes.size(), [&](size_t i) {
    s.normals[i] = triangle_normals(scene.meshes[i]);
    if (scene.meshes[i].has_lightmap()) s.areas[i] = compute_texel_areas(scene.meshes[i]);
  });
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const Mesh& mesh = scene.meshes[i];
    s.views[i] = {&mesh, s.texel_count, nullptr, s.normals[i].data()};
    s.covered_begin[i] = s.covered.size();
    if (scene.own_texels(mesh)) {
      s.views[i].texel_area = s.areas[i].area.data();
      const uint32_t n = mesh.lightmap_width * mesh.lightmap_height;
      for (uint32_t t = 0; t < n; ++t)
        if (s.areas[i].area[t] > 0.0) s.covered.push_back({uint32_t(i), t});
      s.texel_count += n;
    }
    add_mesh_warnings(mesh, mesh.has_lightmap() ? &s.areas[i] : nullptr, warnings);
  }
  // CSG solids: texels on their primitives' faces (split where the solid's
  // boundary cuts them) for those with a carrier.
  s.csg_maps.resize(scene.csgs.size());
  s.csg_views.resize(scene.csgs.size());
  for (size_t c = 0; c < scene.csgs.size(); ++c) {
    const CsgSolid& solid = scene.csgs[c];
    s.csg_views[c] = {solid.object.get(), nullptr, s.texel_count};
    s.covered_begin.push_back(s.covered.size());
    for (const std::string& w : solid.object->warnings()) warnings.push_back(w);
    if (solid.carrier < 0) continue;
    const TexelAreas& carrier = s.areas[size_t(solid.carrier)];
    csg::CsgLightmapSettings ls;
    ls.texel_size = carrier_texel_size(carrier, solid.object->bounds_hi() - solid.object->bounds_lo());
    // The solid's texels cover every face of every primitive, also the parts
    // its carrier never shows: at most 4 texels per covered carrier texel (at
    // least 4096 in all), so that a solid far larger than its carrier does not
    // make the classification at set-up run for minutes.
    double face_area = 0.0, cover = 0.0;
    for (uint32_t k = 0; k < solid.object->primitive_count(); ++k)
      for (double a : solid.object->primitive(k).area)
        if (std::isfinite(a) && a > 0.0) face_area += a;
    for (float cv : carrier.coverage) cover += cv;
    const double budget_side = std::sqrt(face_area / std::max(4096.0, 4.0 * cover));
    if (budget_side > ls.texel_size) {
      ls.texel_size = budget_side;
      warnings.push_back("CSG solid '" + solid.object->name() + "': its primitives' faces (" +
                         std::to_string(face_area) + " m^2) are far larger than its carrier shows; its texels "
                         "are coarsened to " + std::to_string(budget_side) + " m");
    }
    s.csg_maps[c] = std::make_unique<csg::CsgLightmap>(*solid.object, ls);
    s.csg_views[c].lightmap = s.csg_maps[c].get();
    const uint32_t subs = s.csg_maps[c]->sub_texel_count();
    for (uint32_t t = 0; t < subs; ++t) s.covered.push_back({uint32_t(scene.meshes.size() + c), t});
    s.texel_count += subs;
  }
  judge_groups(scene, s);
  return s;
}

}  // namespace plm
