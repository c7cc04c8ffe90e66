// A part file of a sharded bake (docs/design/sharding.md, "The part file"): the
// photon sums of one shard, or the direct pass or final gather of one texel
// range (transport/farm/texel_ranges.h), with what they belong to (scene hash,
// settings, seed, engine version, shard or range index and count, sizes), in a
// small binary format:
//
//   header  (kPartHeaderBytes, little-endian)
//     magic "PLMPART\0", format version, header size, engine version (16 chars),
//     scene hash, the settings that fix the photon pass (photon_count,
//     max_bounces, seed, direct_samples, filter_radius, dilation, texel_value,
//     sampler), shard index and count, batch count, texel count, mesh count,
//     caustic sums or not, flux quanta, segment count, light-group layers, payload size and
//     checksum, the scene file's path (256 bytes); the part's kind (photons,
//     direct, gather), gathered or not, covered texel count, the range's
//     covered texels [begin, end), the direct pass's target error, its rounds
//     and calibration records; the header's checksum
//   payload of a photon part (per segment, in batch order)
//     batches [begin, end), rays, truncated paths, truncated flux, hits and
//     squared-flux quanta in all; per texel RGB flux sums (3 doubles), squared
//     sums (double), hit counts (uint32); per mesh back-lit flags (byte);
//     the same for caustic photons where the scene has specular lobes;
//     with light groups, per layer per texel its RGB flux sums (3 doubles);
//     per judged group its photons' hits and squared hit counts (uint64
//     each: Accumulators::group_hits).
//   payload of a direct part: per texel of the range its layer sums (3
//     floats per layer, none without light groups) and its DirectSums (88
//     bytes), then the calibration records (80 bytes each)
//   payload of a gather part (where the bake gathers): per texel of the
//     range its layer sums (as a direct part's), then its GatherSums and
//     GatherInfo (100 bytes)
//
// Written to a temporary file in the same folder, flushed to disk and renamed,
// so a reader never sees half a file; read back with every size and checksum
// checked, each failure naming the file.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "photonlm/photonlm.h"
#include "transport/farm/shard.h"

namespace plm {

constexpr uint32_t kPartFormatVersion = 5;
constexpr size_t kPartHeaderBytes = 512;

enum class PartKind : uint32_t { kPhotons = 0, kDirect = 1, kGather = 2 };

struct PartHeader {
  std::string engine_version;   // plm_version(), at most 15 characters
  uint64_t scene_hash = 0;
  BakeSettings settings;  // thread_count, target_error and time_budget are not kept (0)
  uint32_t shard_index = 0, shard_count = 0;  // the shard, or the texel range, and their count
  ShardLayout layout;            // batch, texel and mesh counts, caustics, quantum (layout.scene_hash unused)
  uint32_t segment_count = 0;
  std::string scene_path;        // the scene file the shard baked (at most 255 bytes)
  PartKind kind = PartKind::kPhotons;
  uint64_t range_begin = 0, range_end = 0;  // texel parts: the range's covered texels
  double direct_target = 0.0;  // direct parts: their target error; gather parts: their direct passes'
  uint32_t direct_rounds = 0, calibration_count = 0;  // direct parts
  bool gathered = false;  // gather parts: the bake has a final gather (else the part holds no texels)
};

// "photon part", "direct part", "gather part".
const char* part_kind_name(PartKind kind);

// Writes the part atomically; throws PLM_ERROR_IO naming path.
void write_part_file(const std::string& path, const PartHeader& header, const std::vector<PhotonSegment>& segments);

// Reads and checks a part's header and the file's length (the payload is
// not read); throws
// PLM_ERROR_INVALID_ARGUMENT or PLM_ERROR_IO naming path.
PartHeader read_part_header(const std::string& path);

// Reads a whole part, checksums checked.
PartHeader read_part_file(const std::string& path, std::vector<PhotonSegment>& segments);

// A texel range's direct pass (header.kind kDirect) or gather (kGather):
// written atomically, read back with sizes and checksums checked.
void write_direct_part(const std::string& path, const PartHeader& header, const DirectResult& direct);
void write_gather_part(const std::string& path, const PartHeader& header, const GatherResult& gather);
PartHeader read_direct_part(const std::string& path, DirectResult& direct);
PartHeader read_gather_part(const std::string& path, GatherResult& gather);

// "" where part b belongs to the same bake as part a (all but the shard
// index agree), else what differs, b's value first ("seed 8 against 7").
std::string part_mismatch(const PartHeader& a, const PartHeader& b);

}  // namespace plm

namespace plm {

// The input of the merge (job.mode kMerge) or of a texel range's gather
// (kGather, which passes over gather parts): reads the photon parts one at a
// time (memory: two sums and one part), checks that all parts belong
// together (the same engine version, scene hash `scene_hash`, settings; per
// kind one count, every shard or range exactly once; photon batches tile the
// bake; direct parts share one target, gather parts were made from it) and
// adds the photon sums, exactly, into at most two segments: batches [0,
// kCheckBatches) and the rest (the final gather reads the estimate between
// them; a range's gather reads only the shards of the first segment, as its
// estimate needs no more); direct and gather parts go to job.direct and
// job.gather in range order. Errors name the part. Returns the first photon part's header (its
// settings are the bake's).
PartHeader load_parts(const std::vector<std::string>& paths, const std::string& engine_version, uint64_t scene_hash,
                      ShardJob& job);

}  // namespace plm
