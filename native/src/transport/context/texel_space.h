// The bake's texel space: every lightmap texel in one global index (meshes
// with texels of their own, mesh after mesh, then CSG solids' sub-texels),
// and the covered texels in that order (the direct pass and the final gather
// work through these).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "csg/csg_lightmap.h"
#include "lightmap/texel_area.h"
#include "scene/scene.h"
#include "transport/rays/tracing.h"

namespace plm {

// A texel that holds a value (area > 0). mesh >= the mesh count means
// sub-texel `texel` of CSG solid mesh - mesh count.
struct CoveredTexel {
  uint32_t mesh, texel;  // local texel of that mesh
};

// Covered texels [begin, end) in the covered order: all of them by default,
// one texel range of a sharded bake otherwise (transport/farm/texel_ranges.h).
struct CoveredSlice {
  size_t begin = 0, end = SIZE_MAX;
  CoveredSlice clamped(size_t covered) const { return {std::min(begin, covered), std::min(end, covered)}; }
  size_t size() const { return end - begin; }
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
  // Per mesh, then per CSG solid: the group whose error the target judges
  // it in (judge_groups below), kNoGroup without covered texels.
  std::vector<uint32_t> judged;
  uint32_t judged_groups = 0;

  // The group of covered texel k.
  uint32_t group_of(size_t k) const { return judged[covered[k].mesh]; }
  // The covered texels of a mesh, or of CSG solid c at unit mesh count + c.
  size_t covered_count(size_t unit) const {
    return (unit + 1 < covered_begin.size() ? covered_begin[unit + 1] : covered.size()) - covered_begin[unit];
  }
  // The covered texels of each judged group.
  std::vector<size_t> group_texels() const {
    std::vector<size_t> n(judged_groups, 0);
    for (size_t u = 0; u < judged.size(); ++u)
      if (judged[u] < judged_groups) n[judged[u]] += covered_count(u);
    return n;
  }
};

constexpr uint32_t kNoGroup = ~0u;

// An object with at least this many covered texels is judged alone: the
// target error holds for its relative RMS error (relative to its own mean).
// Smaller ones are judged with their neighbours: objects in the order of a
// Morton curve through their bounding boxes' centres, joined until a group
// has kJudgedTexels (a last short group joins the one before), so a handful
// of noisy texels on a tiny object neither decides the bake nor hides.
constexpr uint32_t kJudgedTexels = 64;

// Sets s.judged and s.judged_groups from s.covered.
void judge_groups(const Scene& scene, TexelSpace& s);

// Texel areas of every lightmap (OL meshes' lightmaps are resolved from
// their OL, CSG carriers' from their solid: they have no texels here) and
// the sub-texels of CSG solids with a carrier, at the carrier's texel size.
// Adds each mesh's warnings (transport/plan/validate.h) and the CSG solids'.
// Runs its per-mesh work in parallel: call it inside the bake's arena.
TexelSpace build_texel_space(const Scene& scene, std::vector<std::string>& warnings);

}  // namespace plm
