// A shard's part file (docs/design.md "Sharded bakes"): the photon sums of one
// shard of a bake with what they belong to (scene hash, settings, seed,
// engine version, shard index and count, sizes), in a small binary format:
//
//   header  (kPartHeaderBytes, little-endian)
//     magic "PLMPART\0", format version, header size, engine version (16 chars),
//     scene hash, the settings that fix the photon pass (photon_count,
//     max_bounces, seed, direct_samples, filter_radius, dilation, texel_value,
//     sampler), shard index and count, batch count, texel count, mesh count,
//     caustic sums or not, flux quanta, segment count, payload size and
//     checksum, the scene file's path (256 bytes), the header's checksum
//   payload (per segment, in batch order)
//     batches [begin, end), rays, truncated paths, truncated flux, hits and
//     squared-flux quanta in all; per texel RGB flux sums (3 doubles), squared
//     sums (double), hit counts (uint32); per mesh back-lit flags (byte);
//     the same for caustic photons where the scene has specular lobes.
//
// Written to a temporary file in the same folder, flushed to disk and renamed,
// so a reader never sees half a file; read back with every size and checksum
// checked, each failure naming the file.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "photonlm/photonlm.h"
#include "transport/shard.h"

namespace plm {

constexpr uint32_t kPartFormatVersion = 1;
constexpr size_t kPartHeaderBytes = 512;

struct PartHeader {
  std::string engine_version;   // plm_version(), at most 15 characters
  uint64_t scene_hash = 0;
  plm_bake_settings settings{};  // thread_count, target_error and time_budget are not kept (0)
  uint32_t shard_index = 0, shard_count = 0;
  ShardLayout layout;            // batch, texel and mesh counts, caustics, quantum (layout.scene_hash unused)
  uint32_t segment_count = 0;
  std::string scene_path;        // the scene file the shard baked (at most 255 bytes)
};

// Writes the part atomically; throws PLM_ERROR_IO naming path.
void write_part_file(const std::string& path, const PartHeader& header, const std::vector<PhotonSegment>& segments);

// Reads and checks a part's header and the file's length (the payload is
// not read); throws
// PLM_ERROR_INVALID_ARGUMENT or PLM_ERROR_IO naming path.
PartHeader read_part_header(const std::string& path);

// Reads a whole part, checksums checked.
PartHeader read_part_file(const std::string& path, std::vector<PhotonSegment>& segments);

// "" where part b belongs to the same bake as part a (all but the shard
// index agree), else what differs, b's value first ("seed 8 against 7").
std::string part_mismatch(const PartHeader& a, const PartHeader& b);

}  // namespace plm

namespace plm {

// The merge's input: reads the parts one at a time (memory: two sums and
// one part), checks that they belong together (the same engine version,
// scene hash `scene_hash`, settings, shard count; every shard exactly once;
// their batches tile the bake) and adds them, exactly, into at most two
// segments: batches [0, kCheckBatches) and the rest (the final gather reads
// the estimate between them). Errors name the part. Returns the first part's
// header (its settings are the bake's).
PartHeader load_parts(const std::vector<std::string>& paths, const std::string& engine_version, uint64_t scene_hash,
                      ShardJob& job);

}  // namespace plm
