// Subdivision meshes refined together (Scene::refine_cages): in parallel, cages of
// one topology sharing OpenSubdiv's plan, smooth normals applied after; the
// triangles must be those of each cage refined alone, whatever the threads.
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "api/handles.h"
#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "subdiv/subdiv.h"

namespace plm {
namespace {

// A cube cage (6 quads) moved by `offset`, with one UV island per face placed by `uv_shift`.
struct Cube {
  std::vector<float> p;
  std::vector<uint32_t> sizes = {4, 4, 4, 4, 4, 4};
  std::vector<uint32_t> idx = {0, 4, 6, 2, 3, 2, 6, 7, 7, 6, 4, 5, 5, 1, 3, 7, 1, 0, 2, 3, 5, 4, 0, 1};
  std::vector<float> uv;
  std::vector<uint32_t> mats = {0, 0, 1, 1, 0, 1};
  std::vector<uint32_t> crease_edges;
  std::vector<float> crease_weights;
  uint32_t level = 2;

  Cube(float offset, float uv_shift, bool welded = false) {
    const float base[24] = {1, 1, 1, 1, 1, -1, 1, -1, 1, 1, -1, -1, -1, 1, 1, -1, 1, -1, -1, -1, 1, -1, -1, -1};
    for (int k = 0; k < 24; ++k) p.push_back(base[k] * (1.0f + 0.1f * offset) + offset);
    for (int f = 0; f < 6; ++f) {
      // Separate islands, or (welded) every face on the same square so corners of a vertex agree less often.
      const float u0 = welded ? 0.1f : (f % 3) / 3.0f + 0.02f + uv_shift, v0 = welded ? 0.1f : (f / 3) / 2.0f + 0.02f;
      const float c[8] = {u0, v0, u0 + 0.25f, v0, u0 + 0.25f, v0 + 0.4f, u0, v0 + 0.4f};
      uv.insert(uv.end(), c, c + 8);
    }
  }
  subdiv::Cage cage() const {
    subdiv::Cage c;
    c.positions = p.data();
    c.vertex_count = uint32_t(p.size() / 3);
    c.face_sizes = sizes.data();
    c.face_count = 6;
    c.face_indices = idx.data();
    c.uv = uv.data();
    c.material_ids = mats.data();
    c.crease_edges = crease_edges.empty() ? nullptr : crease_edges.data();
    c.crease_weights = crease_weights.empty() ? nullptr : crease_weights.data();
    c.crease_count = uint32_t(crease_weights.size());
    c.level = level;
    return c;
  }
};

// Copies of one topology (moved, their UV islands shifted), and cages that differ from
// them only in their UV seams, a crease, a loose vertex or the level.
std::vector<Cube> cages() {
  std::vector<Cube> out;
  for (int k = 0; k < 5; ++k) out.emplace_back(float(k), 0.01f * float(k));
  out.emplace_back(6.0f, 0.0f, true);  // other UV seams
  out.emplace_back(7.0f, 0.0f);
  out.back().crease_edges = {0, 4};
  out.back().crease_weights = {0.6f};
  out.emplace_back(8.0f, 0.0f);
  out.back().p.insert(out.back().p.end(), {9.0f, 9.0f, 9.0f});  // a loose vertex
  out.emplace_back(9.0f, 0.0f);
  out.back().level = 3;
  out.emplace_back(10.0f, 0.0f);  // a copy of the first five again, after the others
  return out;
}

struct SceneHandle {
  plm_scene* s = nullptr;
  SceneHandle() {
    EXPECT_EQ(plm_scene_create(&s), PLM_OK);
    const float grey[3] = {0.5f, 0.5f, 0.5f}, black[3] = {0, 0, 0};
    EXPECT_EQ(plm_scene_add_material(s, "a", grey, black, nullptr), PLM_OK);
    EXPECT_EQ(plm_scene_add_material(s, "b", grey, black, nullptr), PLM_OK);
  }
  ~SceneHandle() { plm_scene_release(s); }
  uint32_t add(const Cube& c, const std::string& name) {
    uint32_t id = 0;
    EXPECT_EQ(plm_scene_add_subdiv_mesh(s, name.c_str(), c.p.data(), uint32_t(c.p.size() / 3), c.sizes.data(), 6,
                                        c.idx.data(), c.uv.data(), c.mats.data(),
                                        c.crease_edges.empty() ? nullptr : c.crease_edges.data(),
                                        c.crease_weights.empty() ? nullptr : c.crease_weights.data(),
                                        uint32_t(c.crease_weights.size()), c.level, 16, 16, &id),
              PLM_OK)
        << plm_last_error();
    return id;
  }
  const Mesh& mesh(uint32_t id) const { return s->scene.meshes[id]; }
};

template <typename T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

TEST(SubdivBatch, CagesRefinedTogetherAreEachRefinedAlone) {
  const std::vector<Cube> cubes = cages();
  SceneHandle one, two;
  for (SceneHandle* h : {&one, &two})
    for (size_t k = 0; k < cubes.size(); ++k) {
      const uint32_t id = h->add(cubes[k], "cube" + std::to_string(k));
      EXPECT_EQ(id, uint32_t(k));
      EXPECT_EQ(h->mesh(id).triangle_count(), 0u) << "refined before refine_cages";
      if (k % 2 == 0) {
        EXPECT_EQ(plm_scene_set_mesh_smooth(h->s, id, 1), PLM_OK) << plm_last_error();
      }
    }
  ASSERT_EQ(plm_scene_refine_subdiv_meshes(one.s, 1), PLM_OK) << plm_last_error();
  ASSERT_EQ(plm_scene_refine_subdiv_meshes(two.s, 2), PLM_OK) << plm_last_error();
  EXPECT_FALSE(one.s->scene.has_pending_cages());
  for (size_t k = 0; k < cubes.size(); ++k) {
    // Alone: refine() of the cage, added as an ordinary mesh, shaded smooth by the engine.
    const subdiv::RefinedMesh r = subdiv::refine("alone", cubes[k].cage());
    Scene alone;
    const float grey[3] = {0.5f, 0.5f, 0.5f}, black[3] = {0, 0, 0};
    alone.add_material("a", grey, black);
    alone.add_material("b", grey, black);
    const uint32_t id = alone.add_mesh("alone", r.positions.data(), r.vertex_count(), r.indices.data(),
                                       r.triangle_count(), r.uv.data(), r.material_ids.data(), 16, 16);
    if (k % 2 == 0) alone.set_mesh_smooth(id, true);
    const Mesh& want = alone.meshes[id];
    ASSERT_GT(want.triangle_count(), 0u);
    for (const SceneHandle* h : {&one, &two}) {
      const Mesh& got = h->mesh(uint32_t(k));
      EXPECT_TRUE(same_bits(got.positions, want.positions)) << "cage " << k;
      EXPECT_TRUE(same_bits(got.indices, want.indices)) << "cage " << k;
      EXPECT_TRUE(same_bits(got.uv, want.uv)) << "cage " << k;
      EXPECT_TRUE(same_bits(got.material_ids, want.material_ids)) << "cage " << k;
      EXPECT_TRUE(same_bits(got.normals, want.normals)) << "cage " << k;
      EXPECT_EQ(got.smooth(), k % 2 == 0) << "cage " << k;
    }
  }
  // The copies' refined UVs follow their own islands, not the first copy's.
  EXPECT_FALSE(same_bits(one.mesh(0).uv, one.mesh(1).uv));
  EXPECT_FALSE(same_bits(one.mesh(0).positions, one.mesh(4).positions));
}

TEST(SubdivBatch, TheAddCallRejectsABadCageAndLaterCallsRefineFirst) {
  SceneHandle h;
  Cube bad(0.0f, 0.0f);
  bad.idx[6] = 2;  // face 1 (3, 2, 6, 7) uses vertex 2 twice
  uint32_t id = 99;
  EXPECT_EQ(plm_scene_add_subdiv_mesh(h.s, "broken", bad.p.data(), 8, bad.sizes.data(), 6, bad.idx.data(),
                                      bad.uv.data(), nullptr, nullptr, nullptr, 0, 2, 16, 16, &id),
            PLM_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(plm_last_error()).find("mesh 'broken': cage face 1 uses vertex 2 twice"), std::string::npos)
      << plm_last_error();
  EXPECT_EQ(h.s->scene.meshes.size(), 0u);

  // Calls that need a pending mesh's triangles refine the cages first.
  const Cube good(0.0f, 0.0f);
  const uint32_t a = h.add(good, "a"), b = h.add(good, "b");
  EXPECT_TRUE(h.s->scene.has_pending_cages());
  const uint32_t triangles = 2 * 24 * 4;
  const std::vector<float> normals(size_t(triangles) * 9, 0.0f), tex(size_t(triangles) * 6, 0.5f);
  EXPECT_EQ(plm_scene_set_mesh_normals(h.s, a, normals.data()), PLM_OK) << plm_last_error();
  EXPECT_FALSE(h.s->scene.has_pending_cages());
  EXPECT_EQ(h.mesh(a).triangle_count(), triangles);
  EXPECT_EQ(h.mesh(b).triangle_count(), triangles);
  const uint32_t c = h.add(good, "c");
  EXPECT_EQ(plm_scene_set_mesh_texture_uv(h.s, c, tex.data()), PLM_OK) << plm_last_error();
  EXPECT_EQ(h.mesh(c).texture_uv.size(), size_t(triangles) * 6);
  EXPECT_EQ(plm_scene_refine_subdiv_meshes(h.s, 0), PLM_OK) << "nothing left to refine";
  EXPECT_EQ(plm_scene_refine_subdiv_meshes(nullptr, 0), PLM_ERROR_INVALID_ARGUMENT);
}

}  // namespace
}  // namespace plm
