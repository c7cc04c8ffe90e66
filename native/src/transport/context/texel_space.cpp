#include "transport/context/texel_space.h"

#include <tbb/parallel_for.h>

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

}  // namespace

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
  return s;
}

}  // namespace plm
