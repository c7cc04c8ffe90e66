// Catmull-Clark subdivision of a polygon cage with OpenSubdiv (Far), matching
// the defaults of Blender 3.4's Subdivision Surface modifier, into the
// triangle mesh the rest of the engine bakes.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace plm::subdiv {

// The most refined triangles one cage may produce (a clear error beyond).
constexpr uint64_t kMaxRefinedTriangles = uint64_t(1) << 25;  // 33.5 M
constexpr uint32_t kMaxLevel = 10;
// Blender welds the UVs of corners that share a vertex when they differ by
// less than this in u and in v (STD_UV_CONNECT_LIMIT); welded corners are
// smoothed together, the others form UV seams (island boundaries).
constexpr float kUvConnectLimit = 1e-4f;

// A polygon cage as Blender stores it. Pointers are borrowed.
struct Cage {
  const float* positions = nullptr;         // vertex_count * 3
  uint32_t vertex_count = 0;
  const uint32_t* face_sizes = nullptr;     // face_count, each >= 3
  uint32_t face_count = 0;
  const uint32_t* face_indices = nullptr;   // sum(face_sizes) vertex indices
  const float* uv = nullptr;                // sum(face_sizes) * 2 (per face corner), or NULL
  const uint32_t* material_ids = nullptr;   // face_count, or NULL
  const uint32_t* crease_edges = nullptr;   // crease_count * 2 vertex indices (edges of the cage)
  const float* crease_weights = nullptr;    // crease_count Blender creases in [0, 1]
  uint32_t crease_count = 0;
  uint32_t level = 1;                       // 1..kMaxLevel
};

// The refined mesh: vertices on the limit surface, every refined quad split
// into two triangles (corners 0-1-2 and 0-2-3, as Blender's loop triangles).
struct RefinedMesh {
  std::vector<float> positions;       // 3 per vertex
  std::vector<uint32_t> indices;      // 3 per triangle
  std::vector<float> uv;              // 6 per triangle; empty without cage UVs
  std::vector<uint32_t> material_ids; // 1 per triangle; empty without cage ids
  uint32_t vertex_count() const { return uint32_t(positions.size() / 3); }
  uint32_t triangle_count() const { return uint32_t(indices.size() / 3); }
};

// Blender 3.4 maps an edge crease c in [0, 1] to OpenSubdiv sharpness 10 c^2.
inline float blender_crease_to_sharpness(float crease) { return crease * crease * 10.0f; }

// A cage's shape, owned (no UVs or materials): what limit-surface sampling
// (limit_area.h) needs of it; about (24 + 4 n) bytes per cage vertex of
// valence n, 4^(level-1) times less than the refined mesh.
struct CageCopy {
  std::vector<float> positions;
  std::vector<uint32_t> face_sizes, face_indices, crease_edges;
  std::vector<float> crease_weights;
  uint32_t level = 1;

  // c must be valid (prepare() accepted it).
  static CageCopy of(const Cage& c);
  Cage view() const;
};

// A cage that prepare() checked and copied: its shape, UVs and material ids,
// its welded UVs and OpenSubdiv's base-level topology (which OpenSubdiv
// accepted), owned.
struct PreparedCage;
struct PreparedCageDelete {
  void operator()(PreparedCage* cage) const;
};
using PreparedCagePtr = std::unique_ptr<PreparedCage, PreparedCageDelete>;

// Checks the cage and copies it; throws plm::Error (naming `owner` and the bad
// index) on invalid input, on a topology OpenSubdiv rejects, or when the result
// would exceed kMaxRefinedTriangles. What refine() does later can then fail only
// for want of memory (or an engine bug), never for the input.
PreparedCagePtr prepare(const std::string& owner, const Cage& cage);
// The prepared cage's shape, shared (it outlives the prepared cage).
std::shared_ptr<const CageCopy> shape(const PreparedCage& cage);

// Refines a prepared cage (consumed). Large cages use the calling thread's
// TBB arena for their per-vertex work; the result does not depend on threads.
RefinedMesh refine(const std::string& owner, PreparedCagePtr cage);

// prepare() then refine().
RefinedMesh refine(const std::string& owner, const Cage& cage);

// What refining a cage depends on besides its vertex and UV values (OpenSubdiv's
// refinements and limit patches): made once and shared, read only, by every
// cage of the same topology.
struct RefinementPlan;
struct RefinementPlanDelete {
  void operator()(RefinementPlan* plan) const;
};
using RefinementPlanPtr = std::unique_ptr<RefinementPlan, RefinementPlanDelete>;

// The plan of a prepared cage's topology; takes the cage's base refiner, so the
// cage is then refined with this plan only.
RefinementPlanPtr plan(const std::string& owner, PreparedCage& cage);
// Refines a prepared cage with the plan of a cage of the same topology (same_topology);
// the result is refine()'s, bit for bit.
RefinedMesh refine(const RefinementPlan& plan, const PreparedCage& cage);

// Cages of one topology: the same faces, creases, UV seams (welded UV indices)
// and level. topology_hash is equal for them (and rarely for others).
uint64_t topology_hash(const PreparedCage& cage);
bool same_topology(const PreparedCage& a, const PreparedCage& b);

}  // namespace plm::subdiv
