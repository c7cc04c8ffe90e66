// OL area estimation on the subdivision limit surface ([Thesis §6.3]).
// A mesh added as a subdivision cage is traced as its refined triangles, but
// its orientation-lightmap bin areas can come from the surface the
// subdivision converges to: the same bicubic / Gregory patches that place the
// refined vertices (subdiv.cpp: Blender's adaptive refinement to quality 3).
// Each patch is sampled over its ptex domain, stratified: every ptex face is
// split into k x k strata (k even) with one jittered point each; a point adds
// its area element |dP/du x dP/dv| / k^2 to the bin of its normal
// dP/du x dP/dv (outward for counter-clockwise cage faces).
//
// Variance: neighbouring strata (columns 2j, 2j+1 of a row) form pairs and
// each pair adds (y_a - y_b)^2 to the variance of its bin(s) (the collapsed
// strata estimator): an upper bound where the integrand is smooth, honest
// across bin edges. Reported in the same units as ol::AreaEstimate (m^4).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ol/area_estimation.h"
#include "subdiv/subdiv.h"

namespace plm::subdiv {

// Samples per subdivision mesh in a bake ([Thesis §8.2] used 20000 per OL).
constexpr uint64_t kLimitAreaSamples = 20000;

struct LimitAreaSettings {
  uint64_t samples = kLimitAreaSamples;  // target over the whole cage; rounded to k^2 per ptex face, k even, k >= 2
  uint64_t seed = 1;
};

// Per-bin areas of the cage's limit surface; deterministic for a seed.
// est.samples is the number of points drawn. Throws plm::Error naming `owner`
// when OpenSubdiv rejects the cage.
ol::AreaEstimate estimate_limit_area(const std::string& owner, const Cage& cage, const ol::OctGrid& grid,
                                     const LimitAreaSettings& settings = {});

// The OL areas of a subdivision mesh whose refined triangles have the exact
// per-bin areas `triangle_area`: the limit-surface estimate, except in bins
// where sampling found no limit area but triangles (which receive the photon
// hits) have some; there the triangles' area scaled by the ratio of the limit
// to the triangles' total, with a 100% error, so that no hit is orphaned.
ol::AreaEstimate mesh_limit_area(const std::string& owner, const CageCopy& cage, const ol::OctGrid& grid,
                                 const std::vector<double>& triangle_area, const LimitAreaSettings& settings = {});

}  // namespace plm::subdiv
