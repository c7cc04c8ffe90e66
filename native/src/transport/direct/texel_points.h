// Where a texel's sample points lie, for the direct pass and the final
// gather alike: stratified points over the part of the texel its triangles
// cover or, with PLM_TEXEL_CYCLES, over its central half where a triangle
// covers the centre, folded into that triangle as Cycles bakes it; barely
// covered texels sample their covered pieces directly.
#pragma once

#include <cstdint>
#include <vector>

#include "lightmap/texel_area.h"
#include "photonlm/photonlm.h"
#include "transport/plan/settings.h"
#include "transport/rays/tracing.h"

namespace plm {

// The shading normal at point p of triangle tri of a smooth mesh, from p's
// barycentric coordinates.
Vec3 shading_normal_at(const Mesh& mesh, uint32_t tri, Vec3 p, Vec3 geometric);

class TexelPoints {
 public:
  TexelPoints(const std::vector<MeshView>& views, const std::vector<TexelAreas>& areas,
              const BakeSettings& settings);

  // Where a texel's sample points lie: its strata cover the texel (origin,
  // side per stratum), or with PLM_TEXEL_CYCLES its central half if a
  // triangle (owner) covers the centre; points there are folded into the
  // owner as Cycles does (mirrored_point), or mapped affinely when the window
  // lies inside it. Barely covered texels (sparse) sample their covered
  // pieces directly.
  struct TexelWindow {
    float origin_x = 0.0f, origin_y = 0.0f, side = 1.0f;
    int64_t owner = -1;
    bool sparse = false, affine = false;
    Vec3 base, du, dv;
  };
  TexelWindow texel_window(uint32_t mesh, uint32_t texel, uint32_t strata_per_side) const;
  // The point for texel coordinates (x, y) (or, sparse, the piece numbers
  // w); false outside the islands.
  bool texel_point(const TexelWindow& tw, uint32_t mesh, uint32_t texel, float x, float y, const float w[3], Vec3& p,
                   Vec3& n, uint32_t& tri) const {
    if (tw.sparse) return point_in_pieces(mesh, texel, w, p, n, tri);
    if (tw.owner < 0) return surface_point(mesh, texel, x, y, p, n, tri);
    tri = uint32_t(tw.owner);
    p = tw.affine ? tw.base + tw.du * (x - tw.origin_x) + tw.dv * (y - tw.origin_y) : mirrored_point(mesh, tri, x, y);
    n = views_[mesh].normals[tri];
    return true;
  }

 private:
  bool surface_point(uint32_t mesh, uint32_t texel, float x, float y, Vec3& p, Vec3& n, uint32_t& tri) const;
  bool point_in_pieces(uint32_t mesh, uint32_t texel, const float u[3], Vec3& p, Vec3& n, uint32_t& tri) const;
  int64_t centre_owner(uint32_t mesh, uint32_t texel) const;
  Vec3 mirrored_point(uint32_t mesh, uint32_t tri, float x, float y) const;
  // If the square [ox, ox + size]^2 of texel coordinates lies inside triangle
  // tri's UVs (mirrored_point is then the point itself): the point at (ox, oy)
  // and its change per texel in x and y, so a sample costs two multiply-adds.
  bool window_map(uint32_t mesh, uint32_t tri, float ox, float oy, float size, Vec3& base, Vec3& du, Vec3& dv) const;

  const std::vector<MeshView>& views_;
  const std::vector<TexelAreas>& areas_;
  bool cycles_window_;  // sample the texel's central half (PLM_TEXEL_CYCLES), not all of it
};

}  // namespace plm
