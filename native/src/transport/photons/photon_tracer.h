// The photon tracer ([Thesis §3.5.2]): photons leave the lights in proportion to
// their power, bounce diffusely with Russian roulette, and every front-side
// hit on a lightmapped surface is recorded for the texel it lands in. A batch
// of photons writes its hits into a BatchOutput; transport/film/photon_batches.h
// adds its texel hits to the sums, transport/output/ol_film.h its OL hits in order.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>
#include <vector>

#include "accel/surface_hit.h"
#include "lsystem/graph/graph.h"
#include "ol/octahedral.h"
#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "scene/texture.h"
#include "transport/context/bake_scene.h"
#include "transport/lights/emitters.h"
#include "transport/materials/material_table.h"
#include "transport/plan/settings.h"
#include "transport/rays/tracing.h"
#include "util/rng.h"

namespace plm {

struct Hit {
  uint32_t texel;  // global texel index over all lightmaps
  float r, g, b;   // flux / pick probability; divided by the photon count at the end
};

// A hit on an OL mesh: the mesh and its triangle, whose splat
// (OlMeshView::splats) says where the flux goes.
struct OlHit {
  uint32_t mesh, prim;
  float r, g, b;
};

// A hit on an L-system object: its root-OL bin and the stub key of the
// instance hit (LSystemObject::stub_key).
struct LsHit {
  uint32_t object, bin;
  uint64_t key;
  float r, g, b;
};

// A caustic photon's hit on a mesh, where it landed (kept only for
// experiments with other density estimates: PhotonTracer::keep_caustic_points).
struct CausticPoint {
  Vec3 point;
  float r, g, b;
  uint32_t mesh;
};

// What one batch of photons recorded, in photon order.
struct BatchOutput {
  std::vector<Hit> hits;
  std::vector<Hit> caustic_hits;  // scenes with lobes: hits whose path's last event was specular
  std::vector<CausticPoint> caustic_points;  // the same hits' points, if asked for
  std::vector<OlHit> ol_hits;
  std::vector<LsHit> ls_hits;
  std::vector<uint32_t> back_meshes;  // meshes whose back a photon reached (the final gather's dark backs)
  // With light groups: the layer of each hit's photon (hits, caustic_hits);
  // empty without. layer: the last photon's (set by trace_photon).
  std::vector<uint32_t> hit_layers, caustic_layers;
  uint32_t layer = 0;
  // With directional lightmaps: each hit's direction weight (3 floats a hit,
  // transport/context/split.h); empty without.
  std::vector<float> hit_u, caustic_u;
  uint64_t rays = 0;
  uint64_t truncated = 0;
  double truncated_flux = 0.0;
  // Per judged group (TexelSpace::judged): the sums over photons of the hits k
  // each left on it, and of k^2. One photon's hits share its fate (a path that
  // ends early leaves none), so the level of a group's indirect light varies
  // by sum k^2 / (sum k)^2 relative, not by the hits' own spread.
  std::vector<uint64_t> group_hits, group_hits_sq;
};

class PhotonTracer {
 public:
  // Hits on lightmapped meshes are recorded from depth 1 on where the bake
  // has a direct pass (BakeSettings::two_pass), else from depth 0; hits on OL
  // meshes at every depth (they get no direct pass). With lobes (a table with
  // any_lobes()), photons follow them and depth 1 means "after the light's
  // direct part" (see trace_photon).
  explicit PhotonTracer(const BakeScene& ctx);

  // A triangle's material (grey 0.8 in a scene without materials).
  const Material& material(const Mesh& mesh, uint32_t tri) const { return material_by_id(mesh.material_ids[tri]); }
  // Per mesh, per triangle: its material's albedo.
  std::vector<std::vector<Vec3>> triangle_albedos() const;

  // Also keep the points of caustic hits on lightmapped meshes (BatchOutput::caustic_points).
  void keep_caustic_points(bool keep) { keep_points_ = keep; }

  // Traces photons [first, first + count) into out (cleared first).
  void trace_batch(uint64_t first, uint64_t count, BatchOutput& out) const;

 private:
  const Material& material_by_id(uint32_t id) const {
    return scene_.materials.empty() ? default_material_ : scene_.materials[id];
  }

  // What a photon needs at a mesh hit, flattened per triangle into one cache
  // line (HitTri) and per mesh (HitMesh), so a bounce reads one line instead
  // of the normal, material and OL-bin arrays and divides nothing (the
  // tracer's SurfaceMap reads the hit's normal from there too). The values
  // are those the loop computed per hit, so results are bit for bit the same:
  // make_frame(-n) is exactly (t, -b) for make_frame(n) = (t, b), and
  // albedo * (1 / q) is what albedo / q evaluates.
  struct alignas(64) HitTri {
    Vec3 normal;       // unit geometric normal
    Vec3 frame_t, frame_b;  // make_frame(normal)
    Vec3 bounce;       // albedo / roulette: the flux factor of a surviving photon (untextured scenes)
    float roulette;    // survival probability min(1, max_component(albedo))
    uint32_t ol_bin;   // nearest OL bin of the normal, kNoBin if none
    uint32_t degenerate;  // 1: the photon stops here
    uint32_t pad_;
  };
  static_assert(sizeof(HitTri) == 64, "HitTri fills one cache line");
  struct HitMesh {
    const HitTri* tris;
    const float* uv;  // 6 per triangle (Mesh::uv)
    const Vec3* shading;  // 3 corner normals per triangle (Mesh::normals); null for flat meshes
    const uint8_t* contact;  // per texel: may be pressed against another surface (MeshView::contact), or null
    bool special;            // shading or contact is set: hits go through special_hit
    const uint8_t* covered;  // per texel: area > 0; null when the mesh records no texel hits
    uint64_t texel_offset;
    uint32_t width, height;
    bool ol_backup;
  };

  void build_hit_tables();
  // Albedo of a material where no texture UV exists (textures: their mean).
  Vec3 flat_albedo(uint32_t id) const;
  // kMeshOnly: no CSG solid, no L-system object, no texture (mesh_only_);
  // the compiler then drops their branches from the loop. graph_hit: the
  // record of the photon's rays that L-system callbacks write.
  // kLobes: the scene has specular lobes (lobes_); the photon follows them
  // and its path is classified (PathState), the purely diffuse loop stays as it was.
  void trace_lobe_batch(uint64_t first, uint64_t count, lsystem::GraphHit& graph_hit, BatchOutput& out) const;
  void trace_layered_batch(uint64_t first, uint64_t count, lsystem::GraphHit& graph_hit, BatchOutput& out) const;
  template <bool kMeshOnly, bool kLobes>
  void trace_photon(uint64_t index, lsystem::GraphHit& graph_hit, BatchOutput& out) const;
  // A photon path's class in a scene with lobes (docs/design/materials.md,
  // "Direct light through glass: straight rays pass panes"): by its last event
  // that is not a passage (a TRANSPARENT lobe, or a pane entered and left by
  // its parallel face): none (the light itself) is direct light, a diffuse
  // bounce indirect, a specular event a caustic.
  enum PathClass : uint8_t { kDirect, kIndirect, kCaustic };
  struct PathState {
    PathClass cls = kDirect;
    bool pane = false;  // a pane was entered and its partner not yet met
    bool pane_front = false;
    float pane_ior = 0.0f;
    Vec3 pane_normal;
    float lambda_um = 0.0f;  // a dispersed photon's wavelength (micrometres); 0: all of them
    PathClass recorded() const { return pane ? kCaustic : cls; }
    void specular() {
      cls = kCaustic;
      pane = false;
    }
  };
  // The lobe scene's work at a hit: record by the path's class, then choose
  // the diffuse part or a lobe (Russian roulette on the estimated
  // reflectance) and scatter. Returns false where the photon ends.
  // special: the hit's HitMesh where it needs shading normals (its recorded
  // flux is weighted as special_hit does), else null.
  inline bool lobe_hit(uint64_t index, const SurfaceHit& h, const HitMesh* special, Vec3& dir, bool front, Vec3 normal,
                       Vec3 albedo, const float v[3], uint32_t depth, Vec3& flux, Vec3& org, PathState& path,
                       TraceContext& tc, BatchOutput& out) const;
  // Per-hit steps of trace_photon, inline in photon_tracer.cpp (the only
  // place that calls them).
  inline bool special_hit(const HitMesh& hm, const SurfaceHit& h, Vec3 dir, bool front, Vec3 normal,
                          Vec3& flux) const;
  // The contact test of special_hit: the photon is absorbed.
  inline bool pressed(const HitMesh& hm, const SurfaceHit& h, bool front, Vec3 normal) const;
  // special_hit's shading-normal weight alone (hm.shading set).
  inline float shading_ratio(const HitMesh& hm, const SurfaceHit& h, Vec3 dir, bool front, Vec3 normal) const;
  // dir: the photon's direction, normal: the surface's on the photon's side
  // (the direction weight of directional lightmaps, into u).
  inline void record(const SurfaceHit& h, Vec3 flux, BatchOutput& out, Vec3 dir, Vec3 normal) const;
  inline void record_into(const SurfaceHit& h, Vec3 flux, std::vector<Hit>& hits, std::vector<float>& u, Vec3 dir,
                          Vec3 normal) const;
  // Hit h's direction weight into u (about the shading normal on smooth meshes).
  void add_direction(const SurfaceHit& h, Vec3 dir, Vec3 normal, std::vector<float>& u) const;
  // Traces photon `index` and adds its recorded hits per group to out.group_hits.
  template <bool kMeshOnly, bool kLobes>
  void trace_counted(uint64_t index, lsystem::GraphHit& graph_hit, BatchOutput& out) const;
  // The judged group of global texel `texel` (kNoGroup: none).
  uint32_t group_of_texel(uint32_t texel) const;

  const Scene& scene_;
  const TextureSet* textures_;  // null for an untextured scene
  RTCScene rtc_;
  const std::vector<MeshView>& views_;
  const std::vector<CsgView>& csg_views_;
  const std::vector<OlMeshView>& ol_views_;
  const std::vector<Emitter>& emitters_;
  const std::vector<ol::OctGrid>& ls_grids_;  // per L-system object: its OLs' grid
  BakeSettings settings_;
  float offset_scale_;
  uint32_t first_recorded_;
  EmitterTable table_;
  double pick_offset_ = 0.0;
  Material default_material_;
  std::vector<HitTri> hit_tris_;    // all meshes' triangles, mesh after mesh
  std::vector<HitMesh> hit_meshes_;  // per mesh
  std::vector<uint8_t> covered_;     // per texel of the meshes that record hits
  SurfaceMap surfaces_;              // triangle normals from hit_tris_
  bool mesh_only_ = false;           // trace_photon<true> applies
  bool layered_ = false;             // the bake has light groups: hits carry their photon's layer
  bool directional_ = false;         // directional lightmaps: hits carry their direction weight
  Rng::SeedHash seed_hash_{};        // of settings_.seed, for the photons' Rng
  const MaterialTable* lobes_ = nullptr;  // null in scenes without lobes
  double lambda_offset_ = 0.0;            // rotation of the photons' stratified wavelengths
  bool keep_points_ = false;
  // The first global texel of each unit with texels and its judged group, by texel.
  std::vector<std::pair<uint64_t, uint32_t>> unit_texels_;
  uint32_t judged_groups_ = 0;
};

}  // namespace plm
