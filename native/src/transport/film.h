// The bake's film: every lightmap texel in one global index (meshes with
// texels of their own, mesh after mesh, then CSG solids' sub-texels), the
// covered texels in that order (the direct pass and the final gather work
// through these), and the photon sums per texel, merged batch by batch in
// batch order so that they never depend on the thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "csg/csg_lightmap.h"
#include "lightmap/texel_area.h"
#include "scene/scene.h"
#include "transport/photon_tracer.h"
#include "transport/tracing.h"

namespace plm {

// A texel that holds a value (area > 0). mesh >= the mesh count means
// sub-texel `texel` of CSG solid mesh - mesh count.
struct CoveredTexel {
  uint32_t mesh, texel;  // local texel of that mesh
};

struct TexelSpace {
  std::vector<TexelAreas> areas;           // per mesh (empty without a lightmap)
  std::vector<std::vector<Vec3>> normals;  // per mesh, per triangle (views point into them)
  std::vector<MeshView> views;             // per mesh
  std::vector<std::unique_ptr<csg::CsgLightmap>> csg_maps;  // per CSG solid (null without a carrier)
  std::vector<CsgView> csg_views;          // per CSG solid
  std::vector<CoveredTexel> covered;
  std::vector<size_t> covered_begin;  // per mesh, then per CSG solid: index of its first covered texel
  uint64_t texel_count = 0;
};

// Texel areas of every lightmap (OL meshes' lightmaps are resolved from
// their OL, CSG carriers' from their solid: they have no texels here) and
// the sub-texels of CSG solids with a carrier, at the carrier's texel size.
// Adds each mesh's warnings (validate.h) and the CSG solids'.
TexelSpace build_texel_space(const Scene& scene, std::vector<std::string>& warnings);

// Photon sums per texel over all lightmaps, merged batch by batch in order.
class Accumulators {
 public:
  // caustics: the scene has lobes, and caustic photons (BatchOutput::caustic_hits) get sums of their own.
  Accumulators(uint64_t texels, size_t meshes, bool caustics = false)
      : sum(3 * texels, 0.0), sum_sq(texels, 0.0), hits(texels, 0), back_lit(meshes, 0) {
    if (caustics) caustic.resize(texels);
  }
  std::vector<double> sum, sum_sq;  // flux / pick probability (not yet divided by the photon count)
  std::vector<uint32_t> hits;
  std::vector<uint8_t> back_lit;  // per mesh: a photon reached its back
  double total_sq = 0.0;
  uint64_t total_hits = 0;
  // Caustic photons' sums (empty without lobes): their own reconstruction
  // and variance (film_estimate.h), added to the texel.
  struct CausticSums {
    std::vector<double> sum, sum_sq;
    std::vector<uint32_t> hits;
    double total_sq = 0.0;
    uint64_t total_hits = 0;
    void resize(uint64_t texels) {
      sum.assign(3 * texels, 0.0);
      sum_sq.assign(texels, 0.0);
      hits.assign(texels, 0);
    }
    bool empty() const { return hits.empty(); }
    double phantom_sq() const { return total_hits ? total_sq / double(total_hits) : 0.0; }
  } caustic;

  // The squared flux of one average hit: the phantom hit that keeps texels
  // with few hits from looking exact.
  double phantom_sq() const { return total_hits ? total_sq / double(total_hits) : 0.0; }

  void merge(const BatchOutput& bo) {
    // Locals: the stores through the arrays could otherwise alias total_sq
    // (a loop-carried sum kept in memory). Same operations, same order.
    double* const s = sum.data();
    double* const s2 = sum_sq.data();
    uint32_t* const n = hits.data();
    double total = total_sq;
    for (const Hit& h : bo.hits) {
      const size_t t = h.texel;
      s[3 * t] += h.r;
      s[3 * t + 1] += h.g;
      s[3 * t + 2] += h.b;
      const double a = (double(h.r) + h.g + h.b) / 3.0;
      s2[t] += a * a;
      total += a * a;
      ++n[t];
    }
    total_sq = total;
    total_hits += bo.hits.size();
    for (const uint32_t m : bo.back_meshes) back_lit[m] = 1;
    if (!bo.caustic_hits.empty()) merge_caustics(bo.caustic_hits);
  }

 private:
  void merge_caustics(const std::vector<Hit>& hits_in) {
    for (const Hit& h : hits_in) {
      const size_t t = h.texel;
      caustic.sum[3 * t] += h.r;
      caustic.sum[3 * t + 1] += h.g;
      caustic.sum[3 * t + 2] += h.b;
      const double a = (double(h.r) + h.g + h.b) / 3.0;
      caustic.sum_sq[t] += a * a;
      caustic.total_sq += a * a;
      ++caustic.hits[t];
    }
    caustic.total_hits += hits_in.size();
  }
};

}  // namespace plm
