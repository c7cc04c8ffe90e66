// Image textures on materials (albedo, emission), decoded once per bake into
// memory and looked up by the engine itself. Only a scene with textures
// creates a TextureSet: an untextured bake holds a null TextureSet pointer and
// pays one predictable branch per hit.
//
// Set-up reads every image once (util/image_file.h) into linear
// float RGB (8/16-bit integer images are sRGB unless told otherwise, float
// images are linear: Blender's defaults), clamps albedo images to [0, 1]
// (energy) and keeps their mean. Lookups: bilinear on the full-resolution
// pixels (12 bytes each) with periodic wrapping, pixel centres at
// ((i + 0.5) / width, (j + 0.5) / height), Blender's v = 0 the image's bottom
// row (a photon hit has no ray differentials; Cycles' Linear interpolation
// does the same on the CPU). 8-bit sRGB images are filtered encoded and
// decoded after the lookup, as Cycles does. Lookups only read the set: any
// number of threads may share it, no per-thread state and no files.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "util/math.h"

namespace plm {

// The image's pixel count; throws plm::Error (PLM_ERROR_IO) naming owner when
// path cannot be opened as an image.
uint64_t check_texture_file(const std::string& path, const std::string& owner);

class TextureSet {
 public:
  // Loads the textures the scene's materials name. Throws plm::Error naming
  // the material for a file that cannot be read.
  explicit TextureSet(const Scene& scene);
  ~TextureSet();
  TextureSet(const TextureSet&) = delete;
  TextureSet& operator=(const TextureSet&) = delete;


  // Albedo at barycentrics (bu, bv) of triangle tri of mesh (Embree's u, v):
  // the material's constant times its texture at the interpolated texture
  // UV; times the texture's mean where the mesh has no texture UVs.
  Vec3 albedo(const Mesh& mesh, uint32_t material, uint32_t tri, float bu, float bv) const {
    const Slot& s = albedo_[material];
    if (s.texture < 0) return s.constant;
    if (mesh.texture_uv.empty()) return s.flat;
    return s.constant * lookup(s.texture, mesh, tri, bu, bv);
  }
  // Albedo where no texture UV exists (CSG solids, L-systems): constant x mean.
  Vec3 flat_albedo(uint32_t material) const { return albedo_[material].flat; }

  // Mean emitted radiance over a triangle (the material's emission times the
  // texture's mean over the triangle's texture-UV footprint).
  Vec3 triangle_emission(const Mesh& mesh, uint32_t material, uint32_t tri) const;
  // True where the emitted radiance varies over the mesh's triangles: an
  // emission texture and texture UVs to look it up with.
  bool emission_varies(const Mesh& mesh, uint32_t material) const {
    return emission_[material].texture >= 0 && !mesh.texture_uv.empty();
  }
  // Emitted radiance at barycentrics (bu, bv) of triangle tri (Embree's u, v):
  // the material's emission times its texture there. Only where emission_varies.
  Vec3 emission(const Mesh& mesh, uint32_t material, uint32_t tri, float bu, float bv) const {
    const Slot& s = emission_[material];
    return s.constant * lookup(s.texture, mesh, tri, bu, bv);
  }

  // Mesh names whose textured materials fall back to the mean (no texture UVs).
  std::vector<std::string> warnings;
  size_t texture_count() const { return textures_.size(); }

  // One decoded image.
  struct Texture {
    std::vector<float> rgb;  // width x height x 3, row 0 = the image's top row
    uint32_t width = 0, height = 0;
    Vec3 mean;
    bool decode_after = false;  // 8-bit sRGB: filtered encoded, decoded after the lookup (as Cycles does)
  };
  // The bilinear lookup at texture coordinates (u, v) (periodic; v = 0 is the
  // bottom row); the texture's mean where u or v is not finite.
  static Vec3 sample(const Texture& texture, float u, float v);

 private:
  struct Slot {
    int32_t texture = -1;  // index into textures_, -1 for none
    Vec3 constant, flat;   // the material's colour; colour x texture mean
  };

  Vec3 lookup(int32_t texture, const Mesh& mesh, uint32_t tri, float bu, float bv) const;

  std::vector<Texture> textures_;
  std::vector<Slot> albedo_, emission_;
};

}  // namespace plm
