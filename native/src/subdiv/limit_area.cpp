// Limit-surface OL areas: see limit_area.h.
#include "subdiv/limit_area.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include <opensubdiv/far/patchMap.h>
#include <opensubdiv/far/patchTableFactory.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/ptexIndices.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include "subdiv/osd_topology.h"
#include "util/error.h"
#include "util/rng.h"

namespace plm::subdiv {

namespace {

using namespace OpenSubdiv;
using detail::Point3;

// Same isolation and patch options as subdiv.cpp's evaluate_patches (Blender's quality 3).
constexpr int kQuality = detail::kBlenderQuality;

double uniform01(Rng& rng) { return double(rng.next_u32()) * (1.0 / 4294967296.0); }

}  // namespace

ol::AreaEstimate estimate_limit_area(const std::string& owner, const Cage& c, const ol::OctGrid& grid,
                                     const LimitAreaSettings& settings) {
  if (settings.samples == 0) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": limit-surface area samples must be > 0");
  const detail::Topology topology(c);
  std::unique_ptr<Far::TopologyRefiner> refiner = detail::blender_refiner(topology.desc, owner);
  Far::TopologyRefiner::AdaptiveOptions adaptive(kQuality);
  adaptive.useInfSharpPatch = true;
  refiner->RefineAdaptive(adaptive);
  Far::PatchTableFactory::Options po(kQuality);
  po.SetEndCapType(Far::PatchTableFactory::Options::ENDCAP_GREGORY_BASIS);
  po.useInfSharpPatch = true;
  std::unique_ptr<Far::PatchTable> table(Far::PatchTableFactory::Create(*refiner, po));
  if (!table) fail(PLM_ERROR_INTERNAL, owner, ": OpenSubdiv could not build the limit-surface patches");

  std::vector<Point3> base(c.vertex_count);
  for (uint32_t i = 0; i < c.vertex_count; ++i)
    base[i] = Point3{c.positions[3 * i], c.positions[3 * i + 1], c.positions[3 * i + 2]};
  const std::vector<Point3> cv = detail::patch_control_points(*refiner, *table, base);

  // k x k strata per ptex face, k even (strata pair up along rows).
  const Far::PtexIndices ptex(*refiner);
  const uint64_t faces = uint64_t(ptex.GetNumFaces());
  const double per_face = double(settings.samples) / double(faces);
  const uint64_t k = 2 * std::max<uint64_t>(1, uint64_t(std::llround(std::sqrt(per_face) / 2.0)));
  const double cell = 1.0 / double(k), weight = cell * cell;

  ol::AreaEstimate est;
  est.area.assign(grid.bins(), 0.0);
  est.variance.assign(grid.bins(), 0.0);
  const Far::PatchMap map(*table);
  double w[20], wu[20], wv[20];
  // Area element and bin of one point; bin < 0 for a zero area element or a missing patch.
  auto sample = [&](int face, double u, double v, double& y) -> int64_t {
    y = 0.0;
    const Far::PatchTable::PatchHandle* h = map.FindPatch(face, u, v);
    if (!h) return -1;
    const Far::ConstIndexArray cvs = table->GetPatchVertices(*h);
    if (cvs.size() > 20) return -1;
    table->EvaluateBasis(*h, u, v, w, wu, wv);
    Vec3d du, dv;
    for (int j = 0; j < cvs.size(); ++j) {
      const Point3& p = cv[size_t(cvs[j])];
      du = du + Vec3d{p.x, p.y, p.z} * wu[j];
      dv = dv + Vec3d{p.x, p.y, p.z} * wv[j];
    }
    // Far scales the derivatives by 2^depth of the patch, counted from the cage face; a
    // patch under an n-gon's sub-face (its own ptex face) is one level shallower in ptex.
    const double scale = table->GetPatchParam(*h).NonQuadRoot() ? 0.25 : 1.0;
    const Vec3d n = cross(du, dv) * scale;
    const double len = length(n);
    if (!(len > 0.0) || !std::isfinite(len)) return -1;
    y = len * weight;
    return int64_t(grid.bin(n * (1.0 / len)));
  };
  for (uint64_t f = 0; f < faces; ++f) {
    Rng rng(settings.seed, f);
    for (uint64_t r = 0; r < k; ++r) {
      for (uint64_t col = 0; col < k; col += 2) {
        double ya = 0.0, yb = 0.0;
        const double ua = (double(col) + uniform01(rng)) * cell, va = (double(r) + uniform01(rng)) * cell;
        const double ub = (double(col + 1) + uniform01(rng)) * cell, vb = (double(r) + uniform01(rng)) * cell;
        const int64_t ba = sample(int(f), ua, va, ya), bb = sample(int(f), ub, vb, yb);
        if (ba >= 0) est.area[size_t(ba)] += ya;
        if (bb >= 0) est.area[size_t(bb)] += yb;
        if (ba >= 0 && ba == bb) {
          est.variance[size_t(ba)] += (ya - yb) * (ya - yb);
        } else {
          if (ba >= 0) est.variance[size_t(ba)] += ya * ya;
          if (bb >= 0) est.variance[size_t(bb)] += yb * yb;
        }
        est.total += ya + yb;
        est.total_variance += (ya - yb) * (ya - yb);
      }
    }
  }
  est.samples = faces * k * k;
  return est;
}

ol::AreaEstimate mesh_limit_area(const std::string& owner, const CageCopy& cage, const ol::OctGrid& grid,
                                 const std::vector<double>& triangle_area, const LimitAreaSettings& settings) {
  ol::AreaEstimate est = estimate_limit_area(owner, cage.view(), grid, settings);
  if (triangle_area.size() != est.area.size())
    fail(PLM_ERROR_INTERNAL, owner, ": ", triangle_area.size(), " triangle bin areas for ", est.area.size(), " bins");
  double triangles = 0.0;
  for (double a : triangle_area) triangles += a;
  const double scale = triangles > 0.0 ? est.total / triangles : 1.0;
  for (size_t b = 0; b < est.area.size(); ++b) {
    if (est.area[b] > 0.0 || !(triangle_area[b] > 0.0)) continue;
    est.area[b] = triangle_area[b] * scale;
    est.variance[b] = est.area[b] * est.area[b];
  }
  return est;
}

}  // namespace plm::subdiv
