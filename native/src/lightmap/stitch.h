// Seam stitching: where a smooth surface is cut into two UV islands, the
// bilinear lookups on the two sides of the cut read different texels, and
// their noise and their dilated borders show as a line. After dilation the
// texels that such lookups read are moved, as little as possible, so that the
// two sides agree along the seam (least squares, solved by conjugate
// gradients). Texels outside the islands (the dilated margin that filtering
// reads across the border) move freely; a baked texel moves by about its own
// error at most (the error channel), an exact one not at all. Seams across a crease (a flat-shaded box edge, a sharp edge of a
// smooth mesh) are left alone: there the light rightly differs.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "scene/scene.h"

namespace plm {

struct SeamStats {
  size_t edges = 0;      // seam edges stitched
  size_t samples = 0;    // points compared along them
  double jump_before = 0.0, jump_after = 0.0;  // RMS of the jump across the seam / mean value there
};

// A smooth edge whose two triangles map it to different UV segments, as the
// two triangles' UVs of its end points: a0 -> a1 on one side, b0 -> b1 on the other.
struct SeamEdge {
  float a0[2], a1[2], b0[2], b1[2];
};

// An edge of only one triangle of its mesh (a border), kept for matching
// against other meshes' borders (lightmap/object_seams.h).
struct OpenEdge {
  Vec3 p0, p1;          // end points
  Vec3 n0, n1;          // normals there: the corners' shading normals, or the flat triangle's
  Vec3 inward;          // unit direction in the triangle's plane from the edge towards its third corner
  float uv0[2], uv1[2];  // the triangle's lightmap UVs of p0 and p1
  bool flat;            // a flat mesh (n0 = n1 = the triangle's normal)
};

// Smooth: the shading normals of both corners agree within kSmoothNormalCos
// (smooth meshes), or the triangles lie in one plane within kFlatCos (flat
// meshes: between faces at an angle the light of a flat-shaded surface rightly jumps).
constexpr double kFlatCos = 0.99985;        // within 1 degree
constexpr float kSmoothNormalCos = 0.999f;  // within 2.6 degrees
// Both triangles along a seam cover at least this many texels (along smaller
// ones, filtering reads mostly other triangles' texels anyway).
constexpr double kMinSeamTexels = 2.0;

// The mesh's seam edges (end points matched by position, so meshes split at
// their seams count too): smooth, cut in UV, and both triangles at least
// kMinSeamTexels large. `open`, if given, receives the mesh's border edges
// whose triangle is at least kMinSeamTexels large and not degenerate.
std::vector<SeamEdge> find_seams(const Mesh& mesh, std::vector<OpenEdge>* open = nullptr);

// values: width * height texels of `channels` floats, the first three RGB and
// the fourth, if any, the texel's error (rows bottom first, UV order);
// covered: 1 for texels the mesh covers.
SeamStats stitch_seams(const std::vector<SeamEdge>& seams, const std::vector<uint8_t>& covered,
                       std::vector<float>& values, int channels, uint32_t width, uint32_t height);

// Several lightmaps stitched together (seams within each and between them),
// in one least-squares system with the same weights as stitch_seams.
struct SeamImage {
  float* colour = nullptr;  // texel t's colour channels at colour[t * stride + c]
  int stride = 0;
  const float* error = nullptr;  // texel t's error at error[t * error_stride], null for none
  int error_stride = 0;
  const uint8_t* covered = nullptr;  // 1 for texels the mesh covers
  uint32_t width = 0, height = 0;
};
// A seam from image `a` (side a0 -> a1 of the edge) to image `b` (b0 -> b1).
struct LinkedSeam {
  uint32_t a, b;
  SeamEdge edge;
};
SeamStats stitch_images(const std::vector<LinkedSeam>& seams, const std::vector<SeamImage>& images, int colours);

}  // namespace plm
