#include "transport/farm/shard.h"


#include <algorithm>
#include <cstddef>
#include <cstring>

#include "transport/film/photon_batches.h"
#include "transport/photons/photon_sampler.h"
#include "transport/photons/photon_tracer.h"
#include "transport/plan/scheduler.h"
#include "util/error.h"

namespace plm {
namespace {

// Feeds values into hash_bytes one piece at a time.
struct Hasher {
  uint64_t h = 0x9e3779b97f4a7c15ull;
  void bytes(const void* p, size_t n) { h = hash_bytes(p, n, h); }
  template <typename T>
  void value(const T& v) {
    bytes(&v, sizeof v);
  }
  template <typename T>
  void vec(const std::vector<T>& v) {
    value(uint64_t(v.size()));
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
  void str(const std::string& s) {
    value(uint64_t(s.size()));
    bytes(s.data(), s.size());
  }
};

}  // namespace

uint64_t hash_bytes(const void* data, size_t size, uint64_t seed) {
  const auto* p = static_cast<const unsigned char*>(data);
  uint64_t h = seed ^ (0xcbf29ce484222325ull + size);
  auto mix = [&](uint64_t w) {
    h ^= w * 0x9fb21c651e98df25ull;
    h = (h << 27 | h >> 37) * 0x87c37b91114253d5ull;
  };
  size_t i = 0;
  for (; i + 8 <= size; i += 8) {
    uint64_t w;
    std::memcpy(&w, p + i, 8);
    mix(w);
  }
  uint64_t tail = 0;
  std::memcpy(&tail, p + i, size - i);
  mix(tail ^ (uint64_t(size - i) << 56));
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdull;
  return h ^ (h >> 33);
}

std::pair<uint64_t, uint64_t> shard_batches(uint64_t batches, uint32_t k, uint32_t n) {
  if (n == 0 || k >= n) fail(PLM_ERROR_INVALID_ARGUMENT, "shard ", k, " of ", n, ": expected 0 <= shard < count");
  // Products in 128 bits: batches x n may exceed 64 bits for 2^40 photons.
  const auto at = [&](uint64_t i) { return uint64_t((unsigned __int128)batches * i / n); };
  return {at(k), at(uint64_t(k) + 1)};
}

std::vector<std::pair<uint64_t, uint64_t>> shard_segments(uint64_t first, uint64_t last) {
  std::vector<std::pair<uint64_t, uint64_t>> out;
  if (first < kCheckBatches && last > kCheckBatches) {
    out.push_back({first, kCheckBatches});
    out.push_back({kCheckBatches, last});
  } else if (first < last) {
    out.push_back({first, last});
  }
  return out;
}

std::vector<PhotonSegment> trace_segments(tbb::task_arena& arena, const PhotonTracer& tracer, unsigned threads,
                                          uint64_t cap, const Accumulators& shape, uint64_t first, uint64_t last,
                                          const std::function<void(double)>& progress) {
  std::vector<PhotonSegment> segments;
  const uint64_t total = last - first;
  uint64_t done = 0;
  for (const auto& [begin, end] : shard_segments(first, last)) {
    PhotonSegment seg;
    seg.begin = begin;
    seg.end = end;
    seg.acc = shape;  // zero sums of the right shape
    PhotonBatches batches(tracer, seg.acc, threads, cap);
    run_in_groups(
        arena, end - begin, threads,
        [&](uint64_t group_first, uint64_t n) {
          batches.trace(seg.begin + group_first, n);
          for (uint64_t b = 0; b < n; ++b) {
            const BatchOutput& bo = batches.kept(b);
            seg.rays += bo.rays;
            seg.truncated += bo.truncated;
            seg.truncated_flux += seg.acc.quantum.flux(bo.truncated_flux);
          }
        },
        [&](uint64_t merged) {
          progress(double(done + merged) / double(std::max<uint64_t>(total, 1)));
          return true;
        });
    done += end - begin;
    segments.push_back(std::move(seg));
  }
  return segments;
}

ShardLayout shard_layout(const Scene& scene, const BakeSettings& settings, const TexelSpace& space,
                         const Accumulators& acc) {
  return {scene_hash(scene),  (settings.photon_cap + kBatchPhotons - 1) / kBatchPhotons, space.texel_count, space.covered.size(),
          uint32_t(scene.meshes.size()), !acc.caustic.empty(), acc.quantum, acc.split, space.judged_groups};
}

void check_shardable(const Scene& scene, const BakeSettings& s, ShardJob::Mode mode) {
  if (s.time_budget > 0.0)
    fail(PLM_ERROR_INVALID_ARGUMENT, "a sharded bake cannot have a time budget (", s.time_budget,
         " s): its photon count would depend on each machine's speed; set a photon count instead");
  if ((mode == ShardJob::kDirect || mode == ShardJob::kGather) && s.direct_samples == 0)
    fail(PLM_ERROR_INVALID_ARGUMENT, "texel ranges split the direct pass and the final gather, and with 0 direct "
         "samples the bake has neither: shard its photons alone");
  if (s.target_error > 0.0 && mode != ShardJob::kDirect)
    fail(PLM_ERROR_INVALID_ARGUMENT, "a sharded bake cannot have a target error (", s.target_error,
         "): its photon count depends on the estimate; set a photon count instead");
  if (s.direct_samples > 0 && s.max_bounces == 0)
    fail(PLM_ERROR_INVALID_ARGUMENT, "a sharded bake needs a photon pass: with max_bounces 0 and direct samples "
         "the bake is the direct pass alone; bake it on one machine");
  if (s.photon_count == 0) fail(PLM_ERROR_INVALID_ARGUMENT, "a sharded bake needs a photon count above 0");
  if (!scene.ol_groups.empty())
    fail(PLM_ERROR_INVALID_ARGUMENT, "a sharded bake cannot have OL groups (the scene has ", scene.ol_groups.size(),
         ", the first '", scene.ol_groups[0].name, "'); bake it on one machine");
  if (!scene.lsystems.empty())
    fail(PLM_ERROR_INVALID_ARGUMENT, "a sharded bake cannot have L-system objects (the scene has ",
         scene.lsystems.size(), "); bake it on one machine");
}

uint64_t scene_hash(const Scene& scene) {
  Hasher h;
  h.value(uint64_t(scene.materials.size()));
  for (const Material& m : scene.materials) {
    h.value(m.albedo);
    h.value(m.emission);
    h.str(m.albedo_texture);
    h.str(m.emission_texture);
    h.value(m.albedo_texture_flags);
    h.value(m.emission_texture_flags);
    h.value(uint64_t(m.lobes.size()));
    for (const Lobe& l : m.lobes) {
      h.value(int32_t(l.type));
      h.value(l.color);
      h.value(l.weight);
      h.value(l.roughness);
      h.value(l.ior);
      h.value(l.abbe);
    }
  }
  h.value(uint64_t(scene.meshes.size()));
  for (const Mesh& m : scene.meshes) {
    h.vec(m.positions);
    h.vec(m.indices);
    h.vec(m.uv);
    h.vec(m.material_ids);
    h.vec(m.texture_uv);
    h.vec(m.normals);
    h.value(m.lightmap_width);
    h.value(m.lightmap_height);
    h.value(m.csg_carrier);
    h.value(m.ol_group);
  }
  h.value(uint64_t(scene.lights.size()));
  // plm_light from its type on (4-byte fields, no padding): struct_size says how the caller's header laid it out,
  // not what the light is.
  constexpr size_t kLightFrom = offsetof(plm_light, type);
  for (const Light& l : scene.lights)
    h.bytes(reinterpret_cast<const char*>(&l.desc) + kLightFrom, sizeof l.desc - kLightFrom);
  if (scene.conventions != PLM_CONVENTIONS_CYCLES_3_4) h.value(scene.conventions);  // the default hashes as before
  if (!scene.light_groups.empty()) {  // light groups (a scene without them hashes as before)
    h.value(uint64_t(scene.light_groups.size()));
    for (const std::string& g : scene.light_groups) h.str(g);
    for (const Light& l : scene.lights) h.value(l.light_group);
    for (const Mesh& m : scene.meshes) h.value(m.light_group);
    h.value(scene.world_light_group);
  }
  h.value(uint64_t(scene.csgs.size()));
  for (const CsgSolid& c : scene.csgs) h.value(c.carrier);
  h.value(uint64_t(scene.ol_groups.size()));
  h.value(uint64_t(scene.lsystems.size()));
  h.value(scene.world);
  h.value(uint8_t(scene.world_map != nullptr));
  return h.h;
}

std::string inexact_sums(const Accumulators& acc) {
  const double limit = 0x1p53 * acc.quantum.q, limit2 = 0x1p53 * acc.quantum.q2;
  uint64_t over = 0;
  auto count = [&](const std::vector<double>& sum, const std::vector<double>& sum_sq) {
    for (double v : sum) over += v >= limit;
    for (double v : sum_sq) over += v >= limit2;
  };
  count(acc.sum, acc.sum_sq);
  count(acc.caustic.sum, acc.caustic.sum_sq);
  if (over == 0) return "";
  return std::to_string(over) + " photon sums passed 2^53 flux quanta (over 2^27 photons' flux in one texel): "
         "they are rounded, and the merged bake may differ from one machine's in their last bits";
}

void check_segments(const ShardJob& job) {
  const std::vector<std::string>& names = job.sources;
  const ShardLayout& L = job.layout;
  uint64_t next = 0;
  for (size_t i = 0; i < job.segments.size(); ++i) {
    const PhotonSegment& s = job.segments[i];
    const std::string& name = i < names.size() ? names[i] : std::string("segment ") + std::to_string(i);
    if (s.begin != next)
      fail(PLM_ERROR_INVALID_ARGUMENT, name, ": holds photon batches ", s.begin, "-", s.end, " where batch ", next,
           " was expected next (a shard is missing or repeated)");
    if (s.begin < kCheckBatches && s.end > kCheckBatches)
      fail(PLM_ERROR_INVALID_ARGUMENT, name, ": its batches ", s.begin, "-", s.end, " are not cut at batch ",
           kCheckBatches);
    if (s.acc.hits.size() != L.texel_count || s.acc.back_lit.size() != L.mesh_count ||
        s.acc.caustic.empty() == L.caustics || s.acc.quantum.q != L.quantum.q || s.acc.quantum.q2 != L.quantum.q2)
      fail(PLM_ERROR_INVALID_ARGUMENT, name, ": its sums do not fit this scene (", s.acc.hits.size(),
           " texels where the scene has ", L.texel_count, ")");
    next = s.end;
  }
  // A range's gather needs the batches its estimate reads, the first kCheckBatches.
  const uint64_t end = job.mode == ShardJob::kGather ? std::min(kCheckBatches, L.batch_count) : L.batch_count;
  if (next != end)
    fail(PLM_ERROR_INVALID_ARGUMENT, "the parts hold photon batches up to ", next, " of ", end,
         ": a shard is missing");
}

}  // namespace plm
