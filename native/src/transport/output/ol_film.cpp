#include "transport/output/ol_film.h"

#include <algorithm>
#include <memory>

#include "ol/area_estimation.h"
#include "subdiv/limit_area.h"
#include "transport/photons/photon_sampler.h"

namespace plm {

OlGroups build_ol_groups(const Scene& scene, std::vector<std::string>& warnings) {
  OlGroups out;
  std::vector<ol::OrientationLightmap>& ols = out.maps;
  std::vector<std::vector<ol::Splat>>& splats = out.splats;
  std::vector<uint32_t>& mesh_counts = out.mesh_counts;
  splats.assign(scene.meshes.size(), {});
  mesh_counts.assign(scene.ol_groups.size(), 0);
  for (size_t g = 0; g < scene.ol_groups.size(); ++g) {
    const OlGroup& group = scene.ol_groups[g];
    ols.emplace_back(group.resolution ? group.resolution : kAutoOlResolution, kOlBatches);
    ol::OrientationLightmap& map = ols.back();
    const ol::OctGrid& grid = map.grid();
    std::vector<double> area(map.bins(), 0.0), area_var(map.bins(), 0.0);
    for (size_t i = 0; i < scene.meshes.size(); ++i) {
      const Mesh& mesh = scene.meshes[i];
      if (mesh.ol_group != int32_t(g)) continue;
      ++mesh_counts[g];
      splats[i].assign(mesh.triangle_count(), ol::Splat::nearest_only(kNoBin));
      const bool limit = group.limit_area && mesh.cage;
      std::vector<double> cage_tri_area(limit ? map.bins() : 0, 0.0);
      for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
        const Vec3d p0 = to_double(mesh.vertex(t, 0)), p1 = to_double(mesh.vertex(t, 1)), p2 = to_double(mesh.vertex(t, 2));
        const Vec3d n = cross(p1 - p0, p2 - p0);
        const double len = length(n);
        if (!(len > 0.0)) continue;  // degenerate: no normal, no area, no hits
        const Vec3d unit = n * (1.0 / len);
        ol::Splat& s = splats[i][t];
        if (limit) {
          s = ol::Splat::nearest_only(grid.bin(unit));
          cage_tri_area[s.nearest] += 0.5 * len;
        } else {
          s = ol::Splat::bilinear(grid, unit);
          s.add_to(area, 0.5 * len);
        }
      }
      if (limit) {  // a subdivision mesh: the areas of its limit surface (subdiv/limit_area.h)
        const ol::AreaEstimate e = subdiv::mesh_limit_area("mesh '" + mesh.name + "' (" + std::to_string(i) + ")",
                                                           *mesh.cage, grid, cage_tri_area,
                                                           {subdiv::kLimitAreaSamples, i + 1});
        for (size_t b = 0; b < area.size(); ++b) area[b] += e.area[b], area_var[b] += e.variance[b];
      }
    }
    map.set_area(std::move(area), std::move(area_var));
    if (mesh_counts[g] == 0)
      warnings.push_back("OL group '" + group.name + "' (" + std::to_string(g) +
                         ") has no meshes: its orientation lightmap is black");
  }
  out.views.resize(scene.meshes.size());
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const int32_t g = scene.meshes[i].ol_group;
    if (g >= 0) out.views[i] = {g, splats[i].data(), scene.ol_groups[size_t(g)].backup};
  }
  return out;
}

LSystemOls build_lsystem_ols(const Scene& scene, tbb::task_arena& arena, std::vector<LSystemOutput>& out,
                             std::vector<std::string>& warnings) {
  LSystemOls ls;
  out.resize(scene.lsystems.size());
  for (size_t l = 0; l < scene.lsystems.size(); ++l) {
    const lsystem::LSystemObject& obj = *scene.lsystems[l];
    ls.grids.emplace_back(obj.ol_resolution());
    LSystemOutput& lo = out[l];
    lo.object = scene.lsystems[l];
    lo.root = std::make_unique<ol::OrientationLightmap>(obj.ol_resolution(), kOlBatches);
    arena.execute([&] { ls.areas.push_back(obj.estimate_areas(ls.grids.back(), warnings)); });
    lo.root->set_area(ls.areas.back().root, ls.areas.back().root_variance);
    lo.stats.resolution = obj.ol_resolution();
    lo.stats.primitives = ls.areas.back().primitives;
    lo.stats.truncated = ls.areas.back().truncated ? 1u : 0u;
    lo.stats.stub_instances = ls.areas.back().stub_instances;
    lo.stats.area = lo.root->total_area();
  }
  return ls;
}

uint64_t merge_ol_hits(uint64_t batch, const BatchOutput& bo, OlGroups& groups, const LSystemOls& ls,
                       std::vector<LSystemOutput>& lsystems) {
  const uint32_t replicate = uint32_t(batch % kOlBatches);
  for (const OlHit& h : bo.ol_hits) {
    const OlMeshView& view = groups.views[h.mesh];
    groups.maps[size_t(view.group)].add_splat_hit(view.splats[h.prim], {h.r, h.g, h.b}, replicate);
  }
  for (const LsHit& h : bo.ls_hits) {
    LSystemOutput& lo = lsystems[h.object];
    const Vec3d c = lo.root->grid().centre(h.bin);  // falls back into bin h.bin
    const Vec3 n = to_float(c), rgb{h.r, h.g, h.b};
    lo.root->add_hit(n, rgb, replicate);
    ++lo.stats.hits;
    const lsystem::OlAreas& areas = ls.areas[h.object];
    if (lo.object->ol_level() == 0 || areas.stubs_dropped) continue;
    auto it = lo.stubs.find(h.key);
    if (it == lo.stubs.end()) {
      it = lo.stubs.emplace(h.key, ol::OrientationLightmap(lo.root->resolution(), kOlBatches)).first;
      const auto a = areas.stubs.find(h.key);
      if (a != areas.stubs.end()) it->second.set_area(a->second, std::vector<double>(a->second.size(), 0.0));
    }
    it->second.add_hit(n, rgb, replicate);
  }
  return bo.ol_hits.size() + bo.ls_hits.size();
}

void finish_ol_groups(const Scene& scene, uint64_t photons, OlGroups& groups, std::vector<OlImage>& images) {
  images.resize(groups.maps.size());
  for (size_t g = 0; g < groups.maps.size(); ++g) {
    ol::OrientationLightmap& map = groups.maps[g];
    OlImage& img = images[g];
    img.name = scene.ol_groups[g].name;
    img.resolution = map.resolution();
    const size_t n = map.bins();
    img.rgb.assign(3 * n, 0.0f);
    img.error.assign(n, 0.0f);
    img.area.resize(n);
    img.hits.resize(n);
    img.stats.resolution = img.resolution;
    img.stats.mesh_count = groups.mesh_counts[g];
    img.stats.area = map.total_area();
    if (photons > 0) map.finalize(photons, kBatchPhotons);
    for (uint32_t b = 0; b < n; ++b) {
      img.area[b] = float(map.area(b));
      img.hits[b] = float(map.hits(b));
      img.stats.hits += map.hits(b);
      if (!map.finalized()) continue;
      double mean = 0.0;
      for (int c = 0; c < 3; ++c) {
        img.rgb[3 * b + c] = float(map.radiosity(b, c));
        mean += map.radiosity(b, c) / 3.0;
      }
      img.error[b] = float(map.radiosity_error(b));
      img.stats.flux += mean * kPiD * map.area(b);
    }
    if (photons > 0) img.stats.orphan_flux = map.orphan_flux() / double(photons);
  }
}

void finish_lsystems(uint64_t photons, std::vector<LSystemOutput>& lsystems) {
  for (LSystemOutput& lo : lsystems) {
    if (photons > 0) {
      lo.root->finalize(photons, kBatchPhotons);
      for (auto& [key, stub] : lo.stubs)
        if (stub.total_area() > 0.0) stub.finalize(photons, kBatchPhotons);
    }
    lo.stats.stubs = lo.stubs.size();
    if (lo.root->finalized())
      for (uint32_t b = 0; b < lo.root->bins(); ++b) {
        double mean = 0.0;
        for (int c = 0; c < 3; ++c) mean += lo.root->radiosity(b, c) / 3.0;
        lo.stats.flux += mean * kPiD * lo.root->area(b);
      }
    const lsystem::GraphStats gs = lo.object->graph().stats();
    lo.stats.classes = gs.classes;
    lo.stats.cache_hits = gs.cache_hits;
    lo.stats.cache_misses = gs.cache_misses;
    lo.stats.cache_bytes = gs.peak_cached_bytes;
    lo.stats.class_bytes = gs.class_bytes;
  }
}

Vec3 LSystemOutput::light_at(Vec3d p, Vec3d n) const {
  const Vec3 nf = to_float(n);
  if (!root->finalized()) return {0, 0, 0};
  if (object->ol_level() > 0 && !stubs.empty()) {
    // The stub of the instance under p: the first hit of a short ray back through the surface.
    const Vec3d size = object->bounds_hi() - object->bounds_lo();
    const double eps = 1e-3 * std::max({size.x, size.y, size.z, 1e-30});
    lsystem::GraphHit hit;
    if (object->first_hit(p + n * eps, -n, 0.0, 2.0 * eps, &hit)) {
      const auto it = stubs.find(object->stub_key(hit));
      if (it != stubs.end() && it->second.finalized() && it->second.hits(it->second.bin_of(nf)) >= kStubMinHits)
        return it->second.lookup(nf);
    }
  }
  return root->lookup(nf);
}

}  // namespace plm
