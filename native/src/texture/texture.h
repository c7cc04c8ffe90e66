// Image textures on materials (albedo, emission), looked up through one
// OpenImageIO TextureSystem per bake. Only a scene with textures creates one:
// an untextured bake holds a null TextureSet pointer and pays one predictable
// branch per hit.
//
// Set-up decodes every image once into linear float RGB (8/16-bit integer
// images are sRGB unless told otherwise, float images are linear: Blender's
// defaults), clamps albedo images to [0, 1] (energy), keeps their mean and
// writes them as tiled, mip-mapped float textures into a private temporary
// directory that the destructor removes. Lookups: bilinear on the full
// resolution level with repeat wrapping (a photon hit has no ray
// differentials; Cycles' Linear interpolation does the same on the CPU).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "util/math.h"

namespace plm {

// Throws plm::Error (PLM_ERROR_IO) naming owner when path cannot be opened as an image.
void check_texture_file(const std::string& path, const std::string& owner);

class TextureSet {
 public:
  // Loads the textures the scene's materials name. Throws plm::Error naming
  // the material for a file that cannot be read.
  explicit TextureSet(const Scene& scene);
  ~TextureSet();
  TextureSet(const TextureSet&) = delete;
  TextureSet& operator=(const TextureSet&) = delete;

  // The calling thread's OIIO lookup state (get once per thread or batch, never per ray).
  void* thread_info() const;

  // Albedo at barycentrics (bu, bv) of triangle tri of mesh (Embree's u, v):
  // the material's constant times its texture at the interpolated texture
  // UV; times the texture's mean where the mesh has no texture UVs.
  Vec3 albedo(const Mesh& mesh, uint32_t material, uint32_t tri, float bu, float bv, void* thread) const {
    const Slot& s = albedo_[material];
    if (s.texture < 0) return s.constant;
    if (mesh.texture_uv.empty()) return s.flat;
    return s.constant * lookup(s.texture, mesh, tri, bu, bv, thread);
  }
  // Albedo where no texture UV exists (CSG solids, L-systems): constant x mean.
  Vec3 flat_albedo(uint32_t material) const { return albedo_[material].flat; }

  // Mean emitted radiance over a triangle (the material's emission times the
  // texture's mean over the triangle's texture-UV footprint).
  Vec3 triangle_emission(const Mesh& mesh, uint32_t material, uint32_t tri, void* thread) const;
  // True where the emitted radiance varies over the mesh's triangles: an
  // emission texture and texture UVs to look it up with.
  bool emission_varies(const Mesh& mesh, uint32_t material) const {
    return emission_[material].texture >= 0 && !mesh.texture_uv.empty();
  }
  // Emitted radiance at barycentrics (bu, bv) of triangle tri (Embree's u, v):
  // the material's emission times its texture there. Only where emission_varies.
  Vec3 emission(const Mesh& mesh, uint32_t material, uint32_t tri, float bu, float bv, void* thread) const {
    const Slot& s = emission_[material];
    return s.constant * lookup(s.texture, mesh, tri, bu, bv, thread);
  }

  // Mesh names whose textured materials fall back to the mean (no texture UVs).
  std::vector<std::string> warnings;
  size_t texture_count() const { return textures_.size(); }

 private:
  struct Slot {
    int32_t texture = -1;  // index into textures_, -1 for none
    Vec3 constant, flat;   // the material's colour; colour x texture mean
  };
  struct Texture;

  Vec3 lookup(int32_t texture, const Mesh& mesh, uint32_t tri, float bu, float bv, void* thread) const;
  Vec3 lookup_st(int32_t texture, float u, float v, void* thread) const;
  int32_t load(const std::string& path, uint32_t flags, bool clamp, const std::string& owner);

  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<Texture*> textures_;
  std::vector<Slot> albedo_, emission_;
};

}  // namespace plm
