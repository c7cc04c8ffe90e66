// Seams between objects: where two meshes meet along a shared border (two
// floor tiles side by side, a wall split into two objects, the halves of a
// mirrored model) and their surfaces continue each other smoothly, the
// texels on both sides of the border are stitched as a seam within one mesh
// is (lightmap/stitch.h). Border edges of different meshes match when both
// end points coincide within a tolerance relative to the scene's size (a hash
// grid on quantised end points, relative to the scene's lower corner so that
// scenes far from the origin match as well as others), the normals at both
// ends agree as within a mesh, and the two triangles lie on opposite sides of
// the edge (not one on top of the other). A 90 degree corner between a wall
// and a floor is no seam: there the light rightly differs.
#pragma once

#include <cstdint>
#include <vector>

#include "lightmap/stitch.h"
#include "scene/scene.h"

namespace plm {

// A seam from mesh_a (side a0 -> a1 of the edge, in mesh_a's lightmap UVs) to
// mesh_b (b0 -> b1).
struct ObjectSeam {
  uint32_t mesh_a, mesh_b;
  SeamEdge edge;
};

// open[i]: mesh i's open edges (empty for meshes that take no part);
// `tolerance`: how far apart two end points may lie and still match, beyond a
// few float steps of their coordinates. An edge that matches more than one
// other edge (three objects meeting at one edge) is left alone.
std::vector<ObjectSeam> match_open_edges(const std::vector<std::vector<OpenEdge>>& open, double tolerance);

// The seams of a scene: within each mesh that has a lightmap, and between
// meshes whose lightmaps the bake writes from their texels (not an OL's
// meshes, unless the OL only backs them up, nor CSG carriers).
struct SceneSeams {
  std::vector<std::vector<SeamEdge>> within;  // per mesh
  std::vector<ObjectSeam> between;
  std::vector<uint8_t> joint;  // per mesh: 1 where it has seams with another mesh (stitched together with them)
};
// The tolerance is 1e-5 of the diagonal of the scene's meshes' bounds.
SceneSeams find_scene_seams(const Scene& scene);

// Stitches the meshes that share seams with others, all in one system (their
// seams within and between them): images[i] is mesh i's lightmap, read only
// where seams.joint[i].
SeamStats stitch_scene_seams(const SceneSeams& seams, const std::vector<SeamImage>& images);

}  // namespace plm
