// The OpenSubdiv set-up that refinement (subdiv.cpp) and limit-surface
// sampling (limit_area.cpp) share: the control-point type, a cage's topology
// as a Far descriptor, and Blender 3.4's Subdivision Surface defaults.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opensubdiv/far/patchTable.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include "subdiv/subdiv.h"
#include "util/error.h"

namespace plm::subdiv::detail {

// Isolation level of Blender's limit-surface patches (the modifier's quality, default 3).
constexpr int kBlenderQuality = 3;

// Positions for Far::PrimvarRefiner and patch evaluation, accumulated in double.
struct Point3 {
  double x = 0, y = 0, z = 0;
  void Clear() { x = y = z = 0; }
  void AddWithWeight(const Point3& s, float w) {
    x += w * s.x;
    y += w * s.y;
    z += w * s.z;
  }
};

// A valid cage's topology as Far needs it: faces, and its creases (weight > 0)
// as sharpness. desc points into the vectors, so a Topology is not copied.
struct Topology {
  std::vector<int> face_sizes, face_indices, crease_pairs;
  std::vector<float> sharpness;
  OpenSubdiv::Far::TopologyDescriptor desc;

  explicit Topology(const Cage& c) : face_sizes(c.face_sizes, c.face_sizes + c.face_count) {
    size_t corners = 0;
    for (int n : face_sizes) corners += size_t(n);
    face_indices.assign(c.face_indices, c.face_indices + corners);
    for (uint32_t e = 0; e < c.crease_count; ++e) {
      if (c.crease_weights[e] <= 0.0f) continue;
      crease_pairs.push_back(int(c.crease_edges[2 * e]));
      crease_pairs.push_back(int(c.crease_edges[2 * e + 1]));
      sharpness.push_back(blender_crease_to_sharpness(c.crease_weights[e]));
    }
    desc.numVertices = int(c.vertex_count);
    desc.numFaces = int(c.face_count);
    desc.numVertsPerFace = face_sizes.data();
    desc.vertIndicesPerFace = face_indices.data();
    desc.numCreases = int(sharpness.size());
    desc.creaseVertexIndexPairs = crease_pairs.empty() ? nullptr : crease_pairs.data();
    desc.creaseWeights = sharpness.empty() ? nullptr : sharpness.data();
  }
  Topology(const Topology&) = delete;
  Topology& operator=(const Topology&) = delete;
};

using RefinerFactory = OpenSubdiv::Far::TopologyRefinerFactory<OpenSubdiv::Far::TopologyDescriptor>;

// Blender's defaults, measured against Blender 3.4
// (docs/design/geometry-kinds.md, "Subdivision surfaces are refined in the
// engine, as Blender evaluates them"): Catmull-Clark also on triangles,
// boundary smooth "All" = edges only, UV smooth "Keep Boundaries", uniform
// creasing.
inline RefinerFactory::Options blender_options() {
  using OpenSubdiv::Sdc::Options;
  Options sdc;
  sdc.SetVtxBoundaryInterpolation(Options::VTX_BOUNDARY_EDGE_ONLY);
  sdc.SetFVarLinearInterpolation(Options::FVAR_LINEAR_BOUNDARIES);
  sdc.SetCreasingMethod(Options::CREASE_UNIFORM);
  sdc.SetTriangleSubdivision(Options::TRI_SUB_CATMARK);
  return RefinerFactory::Options(OpenSubdiv::Sdc::SCHEME_CATMARK, sdc);
}

// A refiner for desc with Blender's options; fails naming `owner` if OpenSubdiv rejects it.
inline std::unique_ptr<OpenSubdiv::Far::TopologyRefiner> blender_refiner(
    const OpenSubdiv::Far::TopologyDescriptor& desc, const std::string& owner) {
  std::unique_ptr<OpenSubdiv::Far::TopologyRefiner> refiner(RefinerFactory::Create(desc, blender_options()));
  if (!refiner) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": OpenSubdiv rejected the cage topology");
  return refiner;
}

// The control points of `table` (built from `refiner`): the base vertices, every vertex of
// the adaptive hierarchy level by level, then the end caps' local points.
inline std::vector<Point3> patch_control_points(const OpenSubdiv::Far::TopologyRefiner& refiner,
                                                const OpenSubdiv::Far::PatchTable& table,
                                                const std::vector<Point3>& base) {
  OpenSubdiv::Far::PrimvarRefiner primvar(refiner);
  std::vector<Point3> cv(size_t(refiner.GetNumVerticesTotal() + table.GetNumLocalPoints()));
  std::copy(base.begin(), base.end(), cv.begin());
  size_t offset = 0;
  for (int l = 1; l <= refiner.GetMaxLevel(); ++l) {
    const size_t n_parent = size_t(refiner.GetLevel(l - 1).GetNumVertices());
    Point3* src = cv.data() + offset;
    Point3* dst = src + n_parent;
    primvar.Interpolate(l, src, dst);
    offset += n_parent;
  }
  if (table.GetNumLocalPoints() > 0) table.ComputeLocalPointValues(cv.data(), cv.data() + refiner.GetNumVerticesTotal());
  return cv;
}

}  // namespace plm::subdiv::detail
