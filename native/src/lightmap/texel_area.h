// Exact texel areas: every triangle is clipped against the texel grid in UV
// space; the UV area it covers in a texel, times the triangle's ratio of world
// area to UV area, is the world area that texel receives photons over.
#pragma once

#include <cstdint>
#include <vector>

#include "scene/scene.h"

namespace plm {

// Texels covered less than this are treated as empty (see compute_texel_areas).
constexpr double kMinCoverage = 1e-3;

struct TexelAreas {
  std::vector<double> area;      // world area per texel (m^2), rows bottom first
  std::vector<float> coverage;   // covered fraction of each texel (> 1 where UVs overlap)
  std::vector<Vec3> position;    // world position inside the texel's covered surface
  std::vector<Vec3> normal;      // area-weighted unit normal of that surface
  // Triangles touching each texel (CSR): tri_ids[tri_begin[t] .. tri_begin[t + 1]).
  std::vector<uint32_t> tri_begin;
  std::vector<uint32_t> tri_ids;
  uint32_t zero_uv_triangles = 0;   // world area > 0 but no UV area: light not recorded
  uint32_t first_zero_uv_triangle = 0;
  uint32_t outside_triangles = 0;   // partly or wholly outside the [0,1] UV square
  uint32_t first_outside_triangle = 0;
  uint32_t overlapping_texels = 0;  // coverage above 1: UV islands overlap
  uint32_t first_overlapping_texel = 0;
};

// Area of a polygon given as (x, y) pairs.
double polygon_area(const double* xy, int n);

// Area of triangle (x0,y0)-(x1,y1)-(x2,y2), in texel units, inside each texel
// of a width x height grid; calls add(texel index, area, x, y) for every
// touched texel, (x, y) a point inside the piece.
template <typename Add>
void clip_triangle_to_grid(const double tri[6], uint32_t width, uint32_t height, Add&& add);

TexelAreas compute_texel_areas(const Mesh& mesh);


}  // namespace plm

#include "lightmap/texel_area_impl.h"
