// Scenes with known answers, built through the C API: a closed furnace box,
// a quad under a light, and a Cornell box. Used by the CLI, tests, benchmarks.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "photonlm/photonlm.h"

namespace plm_demo {

struct V3 {
  float x, y, z;
};

// Owns a scene handle; aborts nothing: check ok() after building.
struct SceneBuilder {
  plm_scene* scene = nullptr;
  plm_status status = PLM_OK;
  std::string error;
  std::vector<std::string> mesh_names;

  SceneBuilder();
  ~SceneBuilder();
  SceneBuilder(const SceneBuilder&) = delete;
  SceneBuilder& operator=(const SceneBuilder&) = delete;
  bool ok() const { return status == PLM_OK; }

  uint32_t material(const char* name, V3 albedo, V3 emission = {0, 0, 0});
  // Quad origin + s*eu + t*ev, s,t in [0,1], split in n x n cells; front side
  // along cross(eu, ev); lightmap UV (s, t), resolution res x res (0 = none).
  uint32_t quad(const char* name, V3 origin, V3 eu, V3 ev, uint32_t material, uint32_t res, uint32_t n = 1);
  // Axis-aligned box with outward faces (inward = true: faces point inside),
  // rotated by angle_z about its vertical axis; 6 faces in a 3 x 2 UV atlas of
  // face_res texels per face side (0 = no lightmap).
  uint32_t box(const char* name, V3 center, V3 size, float angle_z, uint32_t material, uint32_t face_res,
               bool inward = false);
  void light(const plm_light& light, const char* name);

 private:
  void check(plm_status s);
};

// A closed cube of side 2 whose six inward faces all have albedo rho and
// emission e: every texel's exact value is e / (1 - rho).
void build_furnace(SceneBuilder& b, float rho, float emission, uint32_t face_res);

// A Cornell box 2 m wide (floor at z = 0), red left wall, green right wall,
// two white boxes and a 0.5 x 0.5 m area light of power watts under the ceiling.
void build_cornell(SceneBuilder& b, uint32_t res, float watts = 200.0f);

}  // namespace plm_demo
