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

// The mesh's seam edges (end points matched by position, so meshes split at
// their seams count too). Smooth: the shading normals of both corners agree
// on both sides (smooth meshes), or the triangles lie in one plane within a
// degree (flat meshes: between faces at an angle the light of a flat-shaded
// surface rightly jumps); and both triangles cover at least two texels (along
// smaller ones, filtering reads mostly other triangles' texels anyway).
std::vector<SeamEdge> find_seams(const Mesh& mesh);

// values: width * height texels of `channels` floats, the first three RGB and
// the fourth, if any, the texel's error (rows bottom first, UV order);
// covered: 1 for texels the mesh covers.
SeamStats stitch_seams(const std::vector<SeamEdge>& seams, const std::vector<uint8_t>& covered,
                       std::vector<float>& values, int channels, uint32_t width, uint32_t height);

}  // namespace plm
