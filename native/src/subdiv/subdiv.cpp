// OpenSubdiv refinement of a polygon cage. Settings follow Blender 3.4's
// Subdivision Surface modifier defaults, checked against Blender itself
// (blend_tests/test_subdiv.py):
//   Catmull-Clark, triangles split by the Catmark rule (TRI_SUB_CATMARK),
//   boundary_smooth = ALL            -> VTX_BOUNDARY_EDGE_ONLY,
//   uv_smooth = PRESERVE_BOUNDARIES  -> FVAR_LINEAR_BOUNDARIES,
//   use_creases = True               -> edge sharpness 10 c^2, CREASE_UNIFORM,
//   use_limit_surface = True, quality = 3
//                                    -> vertices and UVs evaluated as Blender does: on the
//                                       bicubic patches of an adaptive refinement isolated to
//                                       level 3 (Gregory end caps, inf-sharp patches), at the
//                                       ptex coordinates of the uniformly refined vertices.
//                                       (The exact limit, PrimvarRefiner::Limit, differs from
//                                       Blender by up to ~1e-3 of the size at smooth corners
//                                       and near creases sharper than 3.)
#include "subdiv/subdiv.h"
#include "subdiv/osd_topology.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <unordered_set>

#include <opensubdiv/far/patchMap.h>
#include <opensubdiv/far/patchTable.h>
#include <opensubdiv/far/patchTableFactory.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/ptexIndices.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "util/error.h"
#include "util/math.h"

namespace plm::subdiv {

namespace {

using namespace OpenSubdiv;

// Primvar types for Far::PrimvarRefiner (accumulated in double).
using detail::Point3;

struct Point2 {
  double u = 0, v = 0;
  void Clear() { u = v = 0; }
  void AddWithWeight(const Point2& s, float w) {
    u += w * s.u;
    v += w * s.v;
  }
};

uint64_t edge_key(uint32_t a, uint32_t b) {
  if (a > b) std::swap(a, b);
  return (uint64_t(a) << 32) | b;
}

// Welds the corners of each vertex whose UVs agree within kUvConnectLimit
// (as Blender's subdivision converter does); returns a value index per corner.
std::vector<int> weld_uvs(const Cage& c, size_t corner_count, std::vector<Point2>& values) {
  // Corners grouped by vertex (CSR).
  std::vector<uint32_t> start(size_t(c.vertex_count) + 1, 0);
  for (size_t k = 0; k < corner_count; ++k) ++start[c.face_indices[k] + 1];
  for (uint32_t v = 0; v < c.vertex_count; ++v) start[v + 1] += start[v];
  std::vector<uint32_t> fill(start.begin(), start.end() - 1);
  std::vector<uint32_t> corners(corner_count);
  for (size_t k = 0; k < corner_count; ++k) corners[fill[c.face_indices[k]]++] = uint32_t(k);

  std::vector<int> index(corner_count, -1);
  values.clear();
  for (uint32_t v = 0; v < c.vertex_count; ++v) {
    const size_t first_value = values.size();
    for (uint32_t i = start[v]; i < start[v + 1]; ++i) {
      const uint32_t k = corners[i];
      const double u = c.uv[2 * k], w = c.uv[2 * k + 1];
      int found = -1;
      for (size_t j = first_value; j < values.size(); ++j) {
        if (std::fabs(values[j].u - u) < kUvConnectLimit && std::fabs(values[j].v - w) < kUvConnectLimit) {
          found = int(j);
          break;
        }
      }
      if (found < 0) {
        found = int(values.size());
        values.push_back(Point2{u, w});
      }
      index[k] = found;
    }
  }
  return index;
}

using detail::kBlenderQuality;

// Vertices per task of the per-vertex loops: a cage refined to fewer stays on one thread.
constexpr size_t kGrain = 8192;

// Where a refined vertex lies: ptex face and (u, v) in it.
struct PtexCoord {
  int face = -1;
  double u = 0, v = 0;
};

// Ptex coordinates of the 4 corners of every face of the last uniform level. A quad's
// ptex (u, v) runs (0,0) (1,0) (1,1) (0,1) over its corners; an n-gon has one ptex face
// per corner, (0,0) at the corner, (1,1) at the face centre. Far orders child face j of a
// parent quad so that its corner k lies at (P_j + P_k) / 2 of the parent's corners P, and
// child j of an n-gon as (corner j, next edge, centre, previous edge).
void face_corner_ptex(const Far::TopologyRefiner& refiner, int level, std::vector<int>& face_ptex,
                      std::vector<std::array<double, 8>>& face_uv) {
  static constexpr double kUnit[8] = {0, 0, 1, 0, 1, 1, 0, 1};
  const Far::PtexIndices ptex(refiner);
  const Far::TopologyLevel& base = refiner.GetLevel(0);
  face_ptex.assign(size_t(refiner.GetLevel(1).GetNumFaces()), -1);
  face_uv.assign(face_ptex.size(), {});
  for (int f = 0; f < base.GetNumFaces(); ++f) {
    const int n = base.GetFaceVertices(f).size();
    const Far::ConstIndexArray children = base.GetFaceChildFaces(f);
    for (int j = 0; j < children.size(); ++j) {
      const int c = children[j];
      if (n == 4) {
        face_ptex[size_t(c)] = ptex.GetFaceId(f);
        for (int k = 0; k < 4; ++k)
          for (int a = 0; a < 2; ++a) face_uv[size_t(c)][2 * k + a] = 0.5 * (kUnit[2 * j + a] + kUnit[2 * k + a]);
      } else {
        face_ptex[size_t(c)] = ptex.GetFaceId(f) + j;
        std::copy(kUnit, kUnit + 8, face_uv[size_t(c)].begin());
      }
    }
  }
  for (int l = 1; l < level; ++l) {
    const Far::TopologyLevel& parent = refiner.GetLevel(l);
    std::vector<int> next_ptex(size_t(refiner.GetLevel(l + 1).GetNumFaces()), -1);
    std::vector<std::array<double, 8>> next_uv(next_ptex.size());
    for (int f = 0; f < parent.GetNumFaces(); ++f) {
      const Far::ConstIndexArray children = parent.GetFaceChildFaces(f);
      const std::array<double, 8>& P = face_uv[size_t(f)];
      for (int j = 0; j < children.size(); ++j) {
        const size_t c = size_t(children[j]);
        next_ptex[c] = face_ptex[size_t(f)];
        for (int k = 0; k < 4; ++k)
          for (int a = 0; a < 2; ++a) next_uv[c][2 * k + a] = 0.5 * (P[2 * j + a] + P[2 * k + a]);
      }
    }
    face_ptex.swap(next_ptex);
    face_uv.swap(next_uv);
  }
}

// Blender's limit surface for one topology: the patches of an adaptive refinement, as
// Blender's OpenSubdiv evaluator builds them.
struct LimitPatches {
  std::unique_ptr<Far::TopologyRefiner> refiner;
  std::unique_ptr<Far::PatchTable> table;
  std::unique_ptr<Far::PatchMap> map;
};

LimitPatches limit_patches(const Far::TopologyDescriptor& desc, bool fvar, const std::string& owner) {
  LimitPatches lp;
  lp.refiner = detail::blender_refiner(desc, owner);
  Far::TopologyRefiner::AdaptiveOptions adaptive(kBlenderQuality);
  adaptive.considerFVarChannels = fvar;
  adaptive.useInfSharpPatch = true;
  lp.refiner->RefineAdaptive(adaptive);
  Far::PatchTableFactory::Options po(kBlenderQuality);
  po.SetEndCapType(Far::PatchTableFactory::Options::ENDCAP_GREGORY_BASIS);
  po.useInfSharpPatch = true;
  po.generateFVarTables = fvar;
  po.generateFVarLegacyLinearPatches = false;
  lp.table.reset(Far::PatchTableFactory::Create(*lp.refiner, po));
  if (!lp.table) fail(PLM_ERROR_INTERNAL, owner, ": OpenSubdiv could not build the limit-surface patches");
  lp.map = std::make_unique<Far::PatchMap>(*lp.table);
  return lp;
}

// The patches evaluated at ptex coordinates, in parallel (each entry on its own).
// found[i] tells whether entry i got a value: not where no face holds it (a loose
// vertex) or no patch is found (should not happen).
void evaluate_patches(const LimitPatches& lp, const std::vector<Point3>& base_vertex,
                      const std::vector<Point2>* base_fvar, const std::vector<PtexCoord>& vertex_at,
                      std::vector<Point3>& pos_out, std::vector<uint8_t>& vertex_found,
                      const std::vector<PtexCoord>& fvar_at, std::vector<Point2>& fvar_out,
                      std::vector<uint8_t>& fvar_found) {
  const Far::TopologyRefiner& refiner = *lp.refiner;
  const Far::PatchTable& table = *lp.table;
  const Far::PatchMap& map = *lp.map;
  const bool fvar = base_fvar != nullptr;
  const std::vector<Point3> cv = detail::patch_control_points(refiner, table, base_vertex);
  Far::PrimvarRefiner primvar(refiner);
  std::vector<Point2> fv;
  if (fvar) {
    fv.resize(size_t(refiner.GetNumFVarValuesTotal(0) + table.GetNumLocalPointsFaceVarying(0)));
    std::copy(base_fvar->begin(), base_fvar->end(), fv.begin());
    size_t fo = 0;
    for (int l = 1; l <= refiner.GetMaxLevel(); ++l) {
      const size_t n_parent = size_t(refiner.GetLevel(l - 1).GetNumFVarValues(0));
      Point2* src = fv.data() + fo;
      Point2* dst = src + n_parent;
      primvar.InterpolateFaceVarying(l, src, dst, 0);
      fo += n_parent;
    }
    if (table.GetNumLocalPointsFaceVarying(0) > 0)
      table.ComputeLocalPointValuesFaceVarying(fv.data(), fv.data() + refiner.GetNumFVarValuesTotal(0), 0);
  }

  vertex_found.assign(vertex_at.size(), 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, vertex_at.size(), kGrain), [&](const tbb::blocked_range<size_t>& r) {
    double w[20], wu[20], wv[20];
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const PtexCoord& pc = vertex_at[i];
      if (pc.face < 0) continue;
      const Far::PatchTable::PatchHandle* h = map.FindPatch(pc.face, pc.u, pc.v);
      if (!h) continue;
      const Far::ConstIndexArray cvs = table.GetPatchVertices(*h);
      if (cvs.size() > 20) continue;
      table.EvaluateBasis(*h, pc.u, pc.v, w, wu, wv);
      Point3 p;
      for (int k = 0; k < cvs.size(); ++k) p.AddWithWeight(cv[size_t(cvs[k])], float(w[k]));
      pos_out[i] = p;
      vertex_found[i] = 1;
    }
  });
  fvar_found.assign(fvar_at.size(), 0);
  if (!fvar) return;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, fvar_at.size(), kGrain), [&](const tbb::blocked_range<size_t>& r) {
    double w[20], wu[20], wv[20];
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const PtexCoord& pc = fvar_at[i];
      if (pc.face < 0) continue;
      const Far::PatchTable::PatchHandle* h = map.FindPatch(pc.face, pc.u, pc.v);
      if (!h) continue;
      const Far::ConstIndexArray cvs = table.GetPatchFVarValues(*h, 0);
      if (cvs.size() > 20) continue;
      table.EvaluateBasisFaceVarying(*h, pc.u, pc.v, w, wu, wv, nullptr, nullptr, nullptr, 0);
      Point2 t;
      for (int k = 0; k < cvs.size(); ++k) t.AddWithWeight(fv[size_t(cvs[k])], float(w[k]));
      fvar_out[i] = t;
      fvar_found[i] = 1;
    }
  });
}

}  // namespace

CageCopy CageCopy::of(const Cage& c) {
  CageCopy k;
  k.positions.assign(c.positions, c.positions + 3 * size_t(c.vertex_count));
  k.face_sizes.assign(c.face_sizes, c.face_sizes + c.face_count);
  size_t corners = 0;
  for (uint32_t n : k.face_sizes) corners += n;
  k.face_indices.assign(c.face_indices, c.face_indices + corners);
  if (c.crease_count > 0) {
    k.crease_edges.assign(c.crease_edges, c.crease_edges + 2 * size_t(c.crease_count));
    k.crease_weights.assign(c.crease_weights, c.crease_weights + c.crease_count);
  }
  k.level = c.level;
  return k;
}

Cage CageCopy::view() const {
  Cage c;
  c.positions = positions.data();
  c.vertex_count = uint32_t(positions.size() / 3);
  c.face_sizes = face_sizes.data();
  c.face_count = uint32_t(face_sizes.size());
  c.face_indices = face_indices.data();
  c.crease_edges = crease_edges.empty() ? nullptr : crease_edges.data();
  c.crease_weights = crease_weights.empty() ? nullptr : crease_weights.data();
  c.crease_count = uint32_t(crease_weights.size());
  c.level = level;
  return c;
}

// The cage as prepare() checked it: its shape (shared with the mesh, for the
// OL areas on the limit surface), owned copies of its UVs and material ids,
// the welded UVs and the base-level refiner (RefineUniform refines it in place).
struct PreparedCage {
  std::shared_ptr<const CageCopy> shape;
  std::vector<float> uv;
  std::vector<uint32_t> material_ids;
  std::vector<Point2> uv_values;  // welded (weld_uvs), one per distinct corner UV of a vertex
  std::vector<int> uv_index;      // per corner, into uv_values
  std::unique_ptr<detail::Topology> topology;
  Far::TopologyDescriptor::FVarChannel channel;
  std::unique_ptr<Far::TopologyRefiner> refiner;

  // A Cage over the copies.
  Cage view() const {
    Cage c = shape->view();
    c.uv = uv.empty() ? nullptr : uv.data();
    c.material_ids = material_ids.empty() ? nullptr : material_ids.data();
    return c;
  }
};

void PreparedCageDelete::operator()(PreparedCage* cage) const { delete cage; }

PreparedCagePtr prepare(const std::string& owner, const Cage& c) {
  // ---- validation: every error names the cage and the index ----
  if (c.vertex_count == 0 || c.face_count == 0)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": the subdivision cage has ", c.vertex_count, " vertices and ",
         c.face_count, " faces; both must be > 0");
  if (!c.positions || !c.face_sizes || !c.face_indices)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": positions, face sizes and face indices must not be NULL");
  if (c.level < 1 || c.level > kMaxLevel)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": subdivision level ", c.level, " is not in [1, ", kMaxLevel, "]");
  if (c.crease_count > 0 && (!c.crease_edges || !c.crease_weights))
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": ", c.crease_count,
         " creases but the crease edges or weights are NULL");
  if (c.vertex_count > uint32_t(INT32_MAX) || c.face_count > uint32_t(INT32_MAX))
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": the subdivision cage is too large for OpenSubdiv");

  for (uint32_t i = 0; i < c.vertex_count; ++i) {
    const float* p = c.positions + 3 * size_t(i);
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": cage vertex ", i, " has a non-finite position (", p[0], ", ", p[1],
           ", ", p[2], ")");
    if (std::max({std::fabs(p[0]), std::fabs(p[1]), std::fabs(p[2])}) > kMaxCoordinate)
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": cage vertex ", i, " is beyond the engine's range of +-",
           kMaxCoordinate, " m");
  }
  uint64_t corner_count = 0;
  for (uint32_t f = 0; f < c.face_count; ++f) {
    if (c.face_sizes[f] < 3)
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": cage face ", f, " has ", c.face_sizes[f],
           " vertices; a face needs at least 3");
    corner_count += c.face_sizes[f];
  }
  if (corner_count > uint64_t(INT32_MAX))
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": the subdivision cage has too many face corners (", corner_count, ")");
  // Level L turns a cage face of n corners into n * 4^(L-1) quads, two triangles each.
  const uint64_t triangles = 2 * corner_count << (2 * (c.level - 1));
  if (triangles > kMaxRefinedTriangles)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": subdivision level ", c.level, " would make ", triangles,
         " triangles, more than the limit of ", kMaxRefinedTriangles, "; lower the level");

  std::unordered_set<uint64_t> edges;
  edges.reserve(size_t(corner_count));
  {
    size_t k = 0;
    for (uint32_t f = 0; f < c.face_count; ++f) {
      const uint32_t n = c.face_sizes[f];
      for (uint32_t j = 0; j < n; ++j) {
        const uint32_t v = c.face_indices[k + j];
        if (v >= c.vertex_count)
          fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": cage face ", f, " corner ", j, " uses vertex ", v,
               " but the cage has ", c.vertex_count, " vertices");
        for (uint32_t i = 0; i < j; ++i)
          if (c.face_indices[k + i] == v)
            fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": cage face ", f, " uses vertex ", v, " twice (corners ", i,
                 " and ", j, ")");
        edges.insert(edge_key(v, c.face_indices[k + (j + 1) % n]));
      }
      if (c.uv) {
        for (uint32_t j = 0; j < 2 * n; ++j) {
          const float t = c.uv[2 * k + j];
          if (!std::isfinite(t) || std::fabs(t) > 1e4f)
            fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": cage face ", f, " corner ", j / 2, " has the lightmap UV ",
                 "coordinate ", t, " (must be finite and within +-1e4)");
        }
      }
      k += n;
    }
  }
  for (uint32_t e = 0; e < c.crease_count; ++e) {
    const uint32_t a = c.crease_edges[2 * e], b = c.crease_edges[2 * e + 1];
    const float w = c.crease_weights[e];
    if (a >= c.vertex_count || b >= c.vertex_count || a == b)
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": crease ", e, " joins vertices ", a, " and ", b,
           ", which is not an edge of a cage of ", c.vertex_count, " vertices");
    if (!edges.count(edge_key(a, b)))
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": crease ", e, " names the edge ", a, "-", b,
           ", which no cage face has");
    if (!(w >= 0.0f && w <= 1.0f))
      fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": crease ", e, " has weight ", w, "; Blender creases are in [0, 1]");
  }

  // ---- the copy, and its topology as OpenSubdiv sees it ----
  PreparedCagePtr p(new PreparedCage);
  p->shape = std::make_shared<const CageCopy>(CageCopy::of(c));
  if (c.uv) p->uv.assign(c.uv, c.uv + 2 * corner_count);
  if (c.material_ids) p->material_ids.assign(c.material_ids, c.material_ids + c.face_count);
  const Cage own = p->view();
  if (own.uv) p->uv_index = weld_uvs(own, size_t(corner_count), p->uv_values);
  p->topology = std::make_unique<detail::Topology>(own);
  Far::TopologyDescriptor& desc = p->topology->desc;
  if (own.uv) {
    p->channel.numValues = int(p->uv_values.size());
    p->channel.valueIndices = p->uv_index.data();
    desc.numFVarChannels = 1;
    desc.fvarChannels = &p->channel;
  }
  p->refiner = detail::blender_refiner(desc, owner);  // OpenSubdiv's own checks of the topology
  return p;
}

RefinedMesh refine(const std::string& owner, const Cage& cage) { return refine(owner, prepare(owner, cage)); }

namespace {

template <typename T>
uint64_t hash_values(uint64_t h, const std::vector<T>& v) {
  h = (h ^ v.size()) * 1099511628211ull;
  const unsigned char* b = reinterpret_cast<const unsigned char*>(v.data());
  for (size_t i = 0; i < v.size() * sizeof(T); ++i) h = (h ^ b[i]) * 1099511628211ull;  // FNV-1a
  return h;
}

}  // namespace

std::shared_ptr<const CageCopy> shape(const PreparedCage& cage) { return cage.shape; }

uint64_t topology_hash(const PreparedCage& c) {
  const CageCopy& s = *c.shape;
  uint64_t h = 14695981039346656037ull;
  h = (h ^ (s.positions.size() / 3)) * 1099511628211ull;
  h = (h ^ s.level) * 1099511628211ull;
  h = (h ^ (c.uv.empty() ? 0u : 1u)) * 1099511628211ull;
  h = hash_values(h, s.face_sizes);
  h = hash_values(h, s.face_indices);
  h = hash_values(h, s.crease_edges);
  h = hash_values(h, s.crease_weights);
  return hash_values(h, c.uv_index);
}

bool same_topology(const PreparedCage& a, const PreparedCage& b) {
  const CageCopy &x = *a.shape, &y = *b.shape;
  return x.positions.size() == y.positions.size() && x.level == y.level && a.uv.empty() == b.uv.empty() &&
         x.face_sizes == y.face_sizes && x.face_indices == y.face_indices && x.crease_edges == y.crease_edges &&
         x.crease_weights == y.crease_weights && a.uv_index == b.uv_index;
}

// What refining depends on besides the cage's vertex and UV values: OpenSubdiv's uniform
// refinement, the limit patches and where each refined vertex lies on them. Cages of one
// topology share it (read only).
struct RefinementPlan {
  std::unique_ptr<Far::TopologyRefiner> uniform;  // refined to the cage's level
  LimitPatches patches;
  std::vector<PtexCoord> vertex_at, fvar_at;  // per refined vertex / UV value of the last level
};

void RefinementPlanDelete::operator()(RefinementPlan* plan) const { delete plan; }

RefinementPlanPtr plan(const std::string& owner, PreparedCage& cage) {
  RefinementPlanPtr p(new RefinementPlan);
  const bool uv = !cage.uv.empty();
  p->uniform = std::move(cage.refiner);
  Far::TopologyRefiner& refiner = *p->uniform;
  const int level = int(cage.shape->level);
  Far::TopologyRefiner::UniformOptions uniform(level);
  uniform.fullTopologyInLastLevel = true;  // needed by Limit / LimitFaceVarying
  refiner.RefineUniform(uniform);
  const Far::TopologyLevel& last = refiner.GetLevel(level);
  std::vector<int> face_ptex;
  std::vector<std::array<double, 8>> face_uv;
  face_corner_ptex(refiner, level, face_ptex, face_uv);
  p->vertex_at.resize(size_t(last.GetNumVertices()));
  p->fvar_at.resize(uv ? size_t(last.GetNumFVarValues(0)) : 0);
  for (int f = 0; f < last.GetNumFaces(); ++f) {
    const Far::ConstIndexArray fv = last.GetFaceVertices(f);
    for (int k = 0; k < fv.size() && k < 4; ++k) {
      PtexCoord& a = p->vertex_at[size_t(fv[k])];
      if (a.face < 0) a = PtexCoord{face_ptex[size_t(f)], face_uv[size_t(f)][2 * k], face_uv[size_t(f)][2 * k + 1]};
    }
    if (!uv) continue;
    const Far::ConstIndexArray fuv = last.GetFaceFVarValues(f, 0);
    for (int k = 0; k < fuv.size() && k < 4; ++k) {
      PtexCoord& a = p->fvar_at[size_t(fuv[k])];
      if (a.face < 0) a = PtexCoord{face_ptex[size_t(f)], face_uv[size_t(f)][2 * k], face_uv[size_t(f)][2 * k + 1]};
    }
  }
  for (int f = 0; f < last.GetNumFaces(); ++f) {
    const int n = last.GetFaceVertices(f).size();
    if (n != 4)  // Catmull-Clark refinement makes only quads
      fail(PLM_ERROR_INTERNAL, owner, ": refined face ", f, " has ", n, " vertices instead of 4");
  }
  p->patches = limit_patches(cage.topology->desc, uv, owner);
  return p;
}

RefinedMesh refine(const std::string& owner, PreparedCagePtr prepared) {
  const RefinementPlanPtr p = plan(owner, *prepared);
  return refine(*p, *prepared);
}

RefinedMesh refine(const RefinementPlan& plan, const PreparedCage& prepared) {
  const Cage c = prepared.view();
  const Far::TopologyRefiner& refiner = *plan.uniform;
  const Far::TopologyLevel& last = refiner.GetLevel(int(c.level));

  // ---- material ids, level by level ----
  Far::PrimvarRefiner primvar(refiner);
  std::vector<uint32_t> mat, mat_next;
  if (c.material_ids) {
    mat.assign(c.material_ids, c.material_ids + c.face_count);
    for (int l = 1; l <= int(c.level); ++l) {
      mat_next.assign(size_t(refiner.GetLevel(l).GetNumFaces()), 0u);
      primvar.InterpolateFaceUniform(l, mat, mat_next);
      mat.swap(mat_next);
    }
  }

  // ---- Blender's limit surface: patches evaluated at the ptex coordinates of the vertices ----
  std::vector<Point3> base_pos(c.vertex_count);
  for (uint32_t i = 0; i < c.vertex_count; ++i)
    base_pos[i] = Point3{c.positions[3 * i], c.positions[3 * i + 1], c.positions[3 * i + 2]};
  std::vector<Point3> limit(plan.vertex_at.size());
  std::vector<Point2> uv_limit(plan.fvar_at.size());
  std::vector<uint8_t> vertex_found, fvar_found;
  evaluate_patches(plan.patches, base_pos, c.uv ? &prepared.uv_values : nullptr, plan.vertex_at, limit, vertex_found,
                   plan.fvar_at, uv_limit, fvar_found);

  // ---- where no patch holds a vertex (a loose vertex): the exact limit of the uniform refinement ----
  const bool all_vertices = std::all_of(vertex_found.begin(), vertex_found.end(), [](uint8_t f) { return f != 0; });
  const bool all_fvar = std::all_of(fvar_found.begin(), fvar_found.end(), [](uint8_t f) { return f != 0; });
  if (!all_vertices || !all_fvar) {
    std::vector<Point3> pos = base_pos, pos_next;
    std::vector<Point2> uv = prepared.uv_values, uv_next;
    for (int l = 1; l <= int(c.level); ++l) {
      const Far::TopologyLevel& child = refiner.GetLevel(l);
      pos_next.assign(size_t(child.GetNumVertices()), Point3{});
      primvar.Interpolate(l, pos, pos_next);
      pos.swap(pos_next);
      if (c.uv) {
        uv_next.assign(size_t(child.GetNumFVarValues(0)), Point2{});
        primvar.InterpolateFaceVarying(l, uv, uv_next, 0);
        uv.swap(uv_next);
      }
    }
    std::vector<Point3> exact(pos.size());
    primvar.Limit(pos, exact);
    for (size_t i = 0; i < limit.size(); ++i)
      if (!vertex_found[i]) limit[i] = exact[i];
    if (c.uv) {
      std::vector<Point2> exact_uv(uv.size());
      primvar.LimitFaceVarying(uv, exact_uv, 0);
      for (size_t i = 0; i < uv_limit.size(); ++i)
        if (!fvar_found[i]) uv_limit[i] = exact_uv[i];
    }
  }

  // ---- the triangle mesh ----
  const size_t faces = size_t(last.GetNumFaces());
  RefinedMesh out;
  out.positions.resize(limit.size() * 3);
  out.indices.resize(faces * 6);
  if (c.uv) out.uv.resize(faces * 12);
  if (c.material_ids) out.material_ids.resize(faces * 2);
  static constexpr int kTri[2][3] = {{0, 1, 2}, {0, 2, 3}};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, limit.size(), kGrain), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      out.positions[3 * i] = float(limit[i].x);
      out.positions[3 * i + 1] = float(limit[i].y);
      out.positions[3 * i + 2] = float(limit[i].z);
    }
  });
  tbb::parallel_for(tbb::blocked_range<size_t>(0, faces, kGrain / 4), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t f = r.begin(); f < r.end(); ++f) {
      const Far::ConstIndexArray fv = last.GetFaceVertices(int(f));
      for (int t = 0; t < 2; ++t) {
        for (int k = 0; k < 3; ++k) out.indices[6 * f + 3 * size_t(t) + size_t(k)] = uint32_t(fv[kTri[t][k]]);
        if (c.material_ids) out.material_ids[2 * f + size_t(t)] = mat[f];
      }
      if (!c.uv) continue;
      const Far::ConstIndexArray fuv = last.GetFaceFVarValues(int(f), 0);
      for (int t = 0; t < 2; ++t)
        for (int k = 0; k < 3; ++k) {
          const Point2& q = uv_limit[size_t(fuv[kTri[t][k]])];
          out.uv[12 * f + 6 * size_t(t) + 2 * size_t(k)] = float(q.u);
          out.uv[12 * f + 6 * size_t(t) + 2 * size_t(k) + 1] = float(q.v);
        }
    }
  });
  return out;
}

}  // namespace plm::subdiv
