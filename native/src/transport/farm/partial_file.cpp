#include "transport/farm/partial_file.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

#include "transport/farm/texel_ranges.h"
#include "transport/plan/scheduler.h"
#include "util/error.h"

namespace plm {
namespace {

constexpr char kMagic[8] = {'P', 'L', 'M', 'P', 'A', 'R', 'T', '\0'};
constexpr size_t kVersionChars = 16, kPathChars = 256;

// Little-endian fields into and out of the header's bytes (x86-64 and
// AArch64 are little-endian: plain copies).
struct Cursor {
  unsigned char* p;
  size_t at = 0;
  template <typename T>
  void put(T v) {
    std::memcpy(p + at, &v, sizeof v);
    at += sizeof v;
  }
  template <typename T>
  T get() {
    T v;
    std::memcpy(&v, p + at, sizeof v);
    at += sizeof v;
    return v;
  }
  void put_chars(const std::string& s, size_t n) {
    std::memset(p + at, 0, n);
    std::memcpy(p + at, s.data(), std::min(s.size(), n - 1));
    at += n;
  }
  std::string get_chars(size_t n) {
    const char* c = reinterpret_cast<const char*>(p + at);
    at += n;
    return std::string(c, strnlen(c, n - 1));
  }
};

uint64_t segment_bytes(uint64_t texels, uint32_t meshes, bool caustics, uint32_t layers, uint32_t groups) {
  const uint64_t sums = texels * (3 * 8 + 8 + 4);
  return 9 * 8 + sums + meshes + (caustics ? sums : 0) + texels * layers * 3 * 8 + uint64_t(groups) * 2 * 8;
}

// Texel parts' records: DirectSums, DirectCalibration, GatherSums + GatherInfo.
constexpr uint64_t kDirectTexelBytes = 6 * 8 + 2 * 4 + 6 * 4 + 2 * 4, kCalibrationBytes = 8 + 8 + 8 + 4 + 4 + 8 + 4 * 8 + 4 + 4,
                   kGatherTexelBytes = 5 * 8 + 2 * 4 + 4 + 4 + 4 * 8 + 3 * 4;
// With light groups, each texel record of a direct or gather part ends with
// the texel's layer sums (3 floats per layer).
uint64_t layer_bytes(uint32_t layers) { return uint64_t(layers) * 3 * 4; }
// Texel records are packed and checksummed this many at a time (writer and reader alike).
constexpr size_t kTexelChunk = 4096;

uint64_t payload_bytes_of(const PartHeader& h) {
  const uint64_t texels = h.range_end - h.range_begin;
  switch (h.kind) {
    case PartKind::kPhotons:
      return h.segment_count *
             segment_bytes(h.layout.texel_count, h.layout.mesh_count, h.layout.caustics, h.layout.split.slots(),
                           h.layout.judged_groups);
    case PartKind::kDirect:
      return texels * (kDirectTexelBytes + layer_bytes(h.layout.split.slots())) +
             uint64_t(h.calibration_count) * kCalibrationBytes;
    case PartKind::kGather:
      return h.gathered ? texels * (kGatherTexelBytes + layer_bytes(h.layout.split.slots())) : 0;
  }
  return 0;
}

struct FileCloser {
  void operator()(FILE* f) const {
    if (f) std::fclose(f);
  }
};
using File = std::unique_ptr<FILE, FileCloser>;

// Writes arrays and chains their checksum.
struct Writer {
  FILE* f;
  uint64_t sum = 0;
  bool ok = true;
  void bytes(const void* data, size_t n) {
    if (n == 0) return;
    sum = hash_bytes(data, n, sum);
    ok = ok && std::fwrite(data, 1, n, f) == n;
  }
  template <typename T>
  void value(T v) {
    bytes(&v, sizeof v);
  }
  template <typename T>
  void array(const std::vector<T>& v) {
    bytes(v.data(), v.size() * sizeof(T));
  }
};

struct Reader {
  FILE* f;
  const std::string& path;
  uint64_t sum = 0;
  void bytes(void* data, size_t n) {
    if (n == 0) return;
    if (std::fread(data, 1, n, f) != n) fail(PLM_ERROR_IO, path, ": the part file ends early (truncated?)");
    sum = hash_bytes(data, n, sum);
  }
  template <typename T>
  T value() {
    T v;
    bytes(&v, sizeof v);
    return v;
  }
  template <typename T>
  void array(std::vector<T>& v) {
    bytes(v.data(), v.size() * sizeof(T));
  }
};

void encode_header(const PartHeader& h, uint64_t payload_bytes, uint64_t payload_sum, unsigned char* buf) {
  std::memset(buf, 0, kPartHeaderBytes);
  Cursor c{buf};
  for (char m : kMagic) c.put(m);
  c.put(kPartFormatVersion);
  c.put(uint32_t(kPartHeaderBytes));
  c.put_chars(h.engine_version, kVersionChars);
  c.put(h.scene_hash);
  const BakeSettings& s = h.settings;
  c.put(uint64_t(s.photon_count));
  for (uint32_t v : {s.max_bounces, s.seed, s.direct_samples, s.filter_radius, s.dilation, s.texel_value, s.sampler})
    c.put(v);
  c.put(h.shard_index);
  c.put(h.shard_count);
  c.put(h.layout.batch_count);
  c.put(h.layout.texel_count);
  c.put(h.layout.mesh_count);
  c.put(uint32_t(h.layout.caustics));
  c.put(h.layout.quantum.q);
  c.put(h.layout.quantum.q2);
  c.put(h.segment_count);
  c.put(h.layout.split.layers);
  c.put(payload_bytes);
  c.put(payload_sum);
  c.put_chars(h.scene_path, kPathChars);
  c.put(uint32_t(h.kind));
  c.put(uint32_t(h.gathered));
  c.put(h.layout.covered);
  c.put(h.range_begin);
  c.put(h.range_end);
  c.put(h.direct_target);
  c.put(h.direct_rounds);
  c.put(h.calibration_count);
  c.put(uint32_t(h.layout.split.directional));
  c.put(h.layout.judged_groups);
  Cursor end{buf, kPartHeaderBytes - 8};
  end.put(hash_bytes(buf, kPartHeaderBytes - 8));
}

PartHeader decode_header(unsigned char* buf, const std::string& path, uint64_t& payload_bytes, uint64_t& payload_sum) {
  if (std::memcmp(buf, kMagic, sizeof kMagic) != 0)
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": not a photonlm part file (no PLMPART magic)");
  Cursor c{buf, sizeof kMagic};
  const uint32_t version = c.get<uint32_t>(), header_bytes = c.get<uint32_t>();
  if (version != kPartFormatVersion || header_bytes != kPartHeaderBytes)
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": part file format ", version, " (header ", header_bytes,
         " bytes); this engine reads format ", kPartFormatVersion);
  Cursor check{buf, kPartHeaderBytes - 8};
  if (check.get<uint64_t>() != hash_bytes(buf, kPartHeaderBytes - 8))
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": the part file's header is damaged (checksum)");
  PartHeader h;
  h.engine_version = c.get_chars(kVersionChars);
  h.scene_hash = c.get<uint64_t>();
  BakeSettings& s = h.settings;
  s.photon_count = c.get<uint64_t>();
  for (uint32_t* v : {&s.max_bounces, &s.seed, &s.direct_samples, &s.filter_radius, &s.dilation, &s.texel_value,
                      &s.sampler})
    *v = c.get<uint32_t>();
  h.shard_index = c.get<uint32_t>();
  h.shard_count = c.get<uint32_t>();
  h.layout.batch_count = c.get<uint64_t>();
  h.layout.texel_count = c.get<uint64_t>();
  h.layout.mesh_count = c.get<uint32_t>();
  h.layout.caustics = c.get<uint32_t>() != 0;
  h.layout.quantum.q = c.get<double>();
  h.layout.quantum.q2 = c.get<double>();
  h.layout.quantum.inv_q = 1.0 / h.layout.quantum.q;
  h.layout.quantum.inv_q2 = 1.0 / h.layout.quantum.q2;
  h.segment_count = c.get<uint32_t>();
  h.layout.split.layers = c.get<uint32_t>();
  payload_bytes = c.get<uint64_t>();
  payload_sum = c.get<uint64_t>();
  h.scene_path = c.get_chars(kPathChars);
  const uint32_t kind = c.get<uint32_t>();
  h.kind = PartKind(kind);
  h.gathered = c.get<uint32_t>() != 0;
  h.layout.covered = c.get<uint64_t>();
  h.range_begin = c.get<uint64_t>();
  h.range_end = c.get<uint64_t>();
  h.direct_target = c.get<double>();
  h.direct_rounds = c.get<uint32_t>();
  h.calibration_count = c.get<uint32_t>();
  h.layout.split.directional = c.get<uint32_t>() != 0;
  s.directional = h.layout.split.directional;
  h.layout.judged_groups = c.get<uint32_t>();
  const bool texel_part = h.kind != PartKind::kPhotons;
  if (kind > 2 || h.shard_count == 0 || h.shard_index >= h.shard_count ||
      h.segment_count > (texel_part ? 0u : 2u) || h.range_begin > h.range_end || h.range_end > h.layout.covered)
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": a part of kind ", kind, ", shard or range ", h.shard_index, " of ",
         h.shard_count, " with ", h.segment_count, " segments and texels ", h.range_begin, "-", h.range_end,
         " is not a valid part");
  if (h.layout.judged_groups > h.layout.covered)  // every judged group holds covered texels
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": ", h.layout.judged_groups, " judged groups for ", h.layout.covered,
         " covered texels: not a valid part");
  const uint64_t want = payload_bytes_of(h);
  if (payload_bytes != want)
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": the header gives ", payload_bytes, " payload bytes where its sizes need ",
         want);
  return h;
}

File open_part(const std::string& path, unsigned char* header, uint64_t& payload_bytes, uint64_t& payload_sum,
               PartHeader& out) {
  File f(std::fopen(path.c_str(), "rb"));
  if (!f) fail(PLM_ERROR_IO, path, ": cannot open the part file: ", std::strerror(errno));
  if (std::fread(header, 1, kPartHeaderBytes, f.get()) != kPartHeaderBytes)
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": too short for a part file (truncated?)");
  out = decode_header(header, path, payload_bytes, payload_sum);
  if (std::fseek(f.get(), 0, SEEK_END) != 0 || uint64_t(std::ftell(f.get())) != kPartHeaderBytes + payload_bytes)
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": the part file holds ", std::ftell(f.get()), " bytes where its header gives ",
         kPartHeaderBytes + payload_bytes, " (truncated or damaged)");
  std::fseek(f.get(), long(kPartHeaderBytes), SEEK_SET);
  return f;
}

// Writes header and payload (fill(Writer&) writes payload_bytes_of(header) bytes) to a temporary
// file in path's folder, flushed to disk, then renames it to path.
template <typename Fill>
void write_part(const std::string& path, const PartHeader& header, Fill&& fill) {
  char host[64] = {0};
  gethostname(host, sizeof host - 1);
  const std::string tmp = path + ".tmp-" + host + "-" + std::to_string(getpid());
  File f(std::fopen(tmp.c_str(), "wb"));
  if (!f) fail(PLM_ERROR_IO, tmp, ": cannot create the part file: ", std::strerror(errno));
  const uint64_t payload = payload_bytes_of(header);
  unsigned char buf[kPartHeaderBytes];
  // The header first with a zero checksum (space), then again once the payload's is known.
  encode_header(header, payload, 0, buf);
  Writer w{f.get()};
  w.ok = std::fwrite(buf, 1, kPartHeaderBytes, f.get()) == kPartHeaderBytes;
  w.sum = 0;
  fill(w);
  encode_header(header, payload, w.sum, buf);
  bool ok = w.ok && std::fseek(f.get(), 0, SEEK_SET) == 0 &&
            std::fwrite(buf, 1, kPartHeaderBytes, f.get()) == kPartHeaderBytes && std::fflush(f.get()) == 0 &&
            fsync(fileno(f.get())) == 0;
  ok = std::fclose(f.release()) == 0 && ok;
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(tmp.c_str());
    fail(PLM_ERROR_IO, path, ": cannot write the part file: ", std::strerror(e));
  }
}

// Opens a part of kind `kind`, checks its size against its header, and reads
// its payload with read(Reader&, header); the checksum is checked after.
template <typename Read>
PartHeader read_part(const std::string& path, PartKind kind, Read&& read) {
  unsigned char buf[kPartHeaderBytes];
  uint64_t bytes = 0, want_sum = 0;
  PartHeader h;
  File f = open_part(path, buf, bytes, want_sum, h);
  if (h.kind != kind)
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": a ", part_kind_name(h.kind), " where a ", part_kind_name(kind),
         " was expected");
  Reader r{f.get(), path};
  read(r, h);
  if (r.sum != want_sum) fail(PLM_ERROR_INVALID_ARGUMENT, path, ": the part file's sums are damaged (checksum)");
  return h;
}

// Per-texel records packed kTexelChunk at a time: put(i, cursor) writes record i.
template <typename Put>
void write_records(Writer& w, size_t count, uint64_t record_bytes, Put&& put) {
  std::vector<unsigned char> chunk(std::min(count, kTexelChunk) * record_bytes);
  for (size_t i0 = 0; i0 < count; i0 += kTexelChunk) {
    const size_t n = std::min(kTexelChunk, count - i0);
    Cursor c{chunk.data()};
    for (size_t i = i0; i < i0 + n; ++i) put(i, c);
    w.bytes(chunk.data(), n * record_bytes);
  }
}

template <typename Get>
void read_records(Reader& r, size_t count, uint64_t record_bytes, Get&& get) {
  std::vector<unsigned char> chunk(std::min(count, kTexelChunk) * record_bytes);
  for (size_t i0 = 0; i0 < count; i0 += kTexelChunk) {
    const size_t n = std::min(kTexelChunk, count - i0);
    r.bytes(chunk.data(), n * record_bytes);
    Cursor c{chunk.data()};
    for (size_t i = i0; i < i0 + n; ++i) get(i, c);
  }
}

void put_stratified(Cursor& c, const StratifiedSums& s) {
  for (double v : {s.rgb[0], s.rgb[1], s.rgb[2], s.sum_sq, s.pair_sq}) c.put(v);
  c.put(s.paired);
  c.put(s.count);
}

void get_stratified(Cursor& c, StratifiedSums& s) {
  for (double* v : {&s.rgb[0], &s.rgb[1], &s.rgb[2], &s.sum_sq, &s.pair_sq}) *v = c.get<double>();
  s.paired = c.get<uint32_t>();
  s.count = c.get<uint32_t>();
}

// A texel record's values must be what a bake writes: checksums catch damage,
// not a part made by hand, whose NaN or negative distances would reach integer
// conversions in the estimate.
void check_record(bool ok, const std::string& path, const char* what, uint64_t texel) {
  if (!ok)
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": ", what, " of covered texel ", texel,
         " out of range (not a part a bake wrote)");
}

bool non_negative(double v) { return v >= 0.0 && std::isfinite(v); }

bool finite_sums(const StratifiedSums& s) {
  return std::isfinite(s.rgb[0]) && std::isfinite(s.rgb[1]) && std::isfinite(s.rgb[2]) && non_negative(s.sum_sq) &&
         non_negative(s.pair_sq) && s.paired <= s.count;
}

// A texel record's split (transport/context/split.h): the layers' light, finite
// and >= 0, then the direction moment's, finite.
void read_split(Cursor& c, float* out, const SplitLayout& split, const std::string& path, const char* what,
                uint64_t texel) {
  bool ok = true;
  for (uint32_t f = 0; f < 3 * split.slots(); ++f) {
    out[f] = c.get<float>();
    ok = ok && (f < 3 * split.layers ? non_negative(out[f]) : std::isfinite(out[f]));
  }
  check_record(ok, path, what, texel);
}

}  // namespace

const char* part_kind_name(PartKind kind) {
  switch (kind) {
    case PartKind::kPhotons: return "photon part";
    case PartKind::kDirect: return "direct part";
    case PartKind::kGather: return "gather part";
  }
  return "part";
}

void write_part_file(const std::string& path, const PartHeader& header, const std::vector<PhotonSegment>& segments) {
  PartHeader h = header;
  h.kind = PartKind::kPhotons;
  h.segment_count = uint32_t(segments.size());
  const bool caustics = h.layout.caustics;
  write_part(path, h, [&](Writer& w) {
    for (const PhotonSegment& s : segments) {
      const Accumulators& a = s.acc;
      for (uint64_t v : {s.begin, s.end, s.rays, s.truncated, a.total_hits, a.total_sq_q, a.caustic.total_hits,
                         a.caustic.total_sq_q})
        w.value(v);
      w.value(s.truncated_flux);
      w.array(a.sum);
      w.array(a.sum_sq);
      w.array(a.hits);
      w.array(a.back_lit);
      if (caustics) {
        w.array(a.caustic.sum);
        w.array(a.caustic.sum_sq);
        w.array(a.caustic.hits);
      }
      w.array(a.split_sum);
      std::vector<uint64_t> k(h.layout.judged_groups, 0), k_sq(k);  // every group, hit or not
      std::copy_n(a.group_hits.begin(), std::min(a.group_hits.size(), k.size()), k.begin());
      std::copy_n(a.group_hits_sq.begin(), std::min(a.group_hits_sq.size(), k.size()), k_sq.begin());
      w.array(k);
      w.array(k_sq);
    }
  });
}

void write_direct_part(const std::string& path, const PartHeader& header, const DirectResult& direct) {
  PartHeader h = header;
  h.kind = PartKind::kDirect;
  h.segment_count = 0;
  h.calibration_count = uint32_t(direct.calibration.size());
  h.direct_rounds = direct.rounds;
  if (direct.sums.size() != h.range_end - h.range_begin)
    fail(PLM_ERROR_INTERNAL, path, ": ", direct.sums.size(), " direct sums for texels ", h.range_begin, "-",
         h.range_end);
  write_part(path, h, [&](Writer& w) {
    const uint32_t slots = h.layout.split.slots();
    write_records(w, direct.sums.size(), kDirectTexelBytes + layer_bytes(slots), [&](size_t i, Cursor& c) {
      const DirectSums& d = direct.sums[i];
      for (uint32_t f = 0; f < 3 * slots; ++f) c.put(direct.split_rgb[3 * i * slots + f]);
      put_stratified(c, d);
      c.put(d.choice_sq);
      for (float v : {d.sky_rgb[0], d.sky_rgb[1], d.sky_rgb[2], d.sky_pair_sq, d.other_pair_sq, d.sky_inv_distance})
        c.put(v);
      c.put(d.sky_rays);
      c.put(d.sky_blocked);
    });
    write_records(w, direct.calibration.size(), kCalibrationBytes, [&](size_t i, Cursor& c) {
      const DirectCalibration& r = direct.calibration[i];
      c.put(r.texel);
      c.put(r.measured);
      c.put(r.estimated);
      c.put(r.used);
      c.put(r.count_before);
      c.put(r.sum_sq_before);
      for (double v : {r.sky_measured, r.sky_estimated, r.other_measured, r.other_estimated}) c.put(v);
      c.put(r.used_split);
      c.put(uint32_t(0));  // padding
    });
  });
}

void write_gather_part(const std::string& path, const PartHeader& header, const GatherResult& gather) {
  PartHeader h = header;
  h.kind = PartKind::kGather;
  h.segment_count = 0;
  const size_t texels = h.gathered ? h.range_end - h.range_begin : 0;
  if (gather.sums.size() != texels || gather.info.size() != texels)
    fail(PLM_ERROR_INTERNAL, path, ": ", gather.sums.size(), " gather sums for texels ", h.range_begin, "-",
         h.range_end);
  write_part(path, h, [&](Writer& w) {
    const uint32_t slots = h.layout.split.slots();
    write_records(w, texels, kGatherTexelBytes + layer_bytes(slots), [&](size_t i, Cursor& c) {
      for (uint32_t f = 0; f < 3 * slots; ++f) c.put(gather.split_rgb[3 * i * slots + f]);
      put_stratified(c, gather.sums[i]);
      const GatherInfo& g = gather.info[i];
      c.put(g.unknown);
      c.put(g.dark);
      for (double v : {g.lookup_all, g.lookup_cells, g.lookup_rays, g.lookup_wide}) c.put(v);
      for (float v : {g.hit_distance, g.calibration_measured, g.calibration_estimated}) c.put(v);
    });
  });
}

PartHeader read_direct_part(const std::string& path, DirectResult& direct) {
  return read_part(path, PartKind::kDirect, [&](Reader& r, const PartHeader& h) {
    direct = DirectResult();
    direct.rounds = h.direct_rounds;
    direct.sums.resize(h.range_end - h.range_begin);
    direct.slots = h.layout.split.slots();
    direct.split_rgb.resize(3 * size_t(direct.slots) * direct.sums.size());
    read_records(r, direct.sums.size(), kDirectTexelBytes + layer_bytes(direct.slots), [&](size_t i, Cursor& c) {
      DirectSums& d = direct.sums[i];
      read_split(c, direct.split_rgb.data() + 3 * i * direct.slots, h.layout.split, path, "the direct sums' split",
                  h.range_begin + i);
      get_stratified(c, d);
      d.choice_sq = c.get<double>();
      for (float* v : {&d.sky_rgb[0], &d.sky_rgb[1], &d.sky_rgb[2], &d.sky_pair_sq, &d.other_pair_sq,
                       &d.sky_inv_distance})
        *v = c.get<float>();
      d.sky_rays = c.get<uint32_t>();
      d.sky_blocked = c.get<uint32_t>();
      const uint64_t texel = h.range_begin + i;
      check_record(finite_sums(d) && non_negative(d.choice_sq), path, "the direct sums", texel);
      check_record(non_negative(d.sky_pair_sq) && non_negative(d.other_pair_sq) && std::isfinite(d.sky_rgb[0]) &&
                       std::isfinite(d.sky_rgb[1]) && std::isfinite(d.sky_rgb[2]),
                   path, "the sky sums", texel);
      check_record(d.sky_blocked <= d.sky_rays && non_negative(d.sky_inv_distance) &&
                       (d.sky_blocked == 0 || d.sky_inv_distance > 0.0f),
                   path, "the sky's blocked rays or their distances", texel);
    });
    direct.calibration.resize(h.calibration_count);
    read_records(r, direct.calibration.size(), kCalibrationBytes, [&](size_t i, Cursor& c) {
      DirectCalibration& d = direct.calibration[i];
      d.texel = c.get<uint64_t>();
      d.measured = c.get<double>();
      d.estimated = c.get<double>();
      d.used = c.get<uint32_t>();
      d.count_before = c.get<uint32_t>();
      d.sum_sq_before = c.get<double>();
      for (double* v : {&d.sky_measured, &d.sky_estimated, &d.other_measured, &d.other_estimated}) *v = c.get<double>();
      d.used_split = c.get<uint32_t>();
      c.get<uint32_t>();  // padding
    });
    for (const DirectCalibration& d : direct.calibration)
      if (d.texel < h.range_begin || d.texel >= h.range_end)
        fail(PLM_ERROR_INVALID_ARGUMENT, path, ": a calibration texel (", d.texel, ") outside its range ",
             h.range_begin, "-", h.range_end);
  });
}

PartHeader read_gather_part(const std::string& path, GatherResult& gather) {
  return read_part(path, PartKind::kGather, [&](Reader& r, const PartHeader& h) {
    gather = GatherResult();
    const size_t texels = h.gathered ? h.range_end - h.range_begin : 0;
    gather.sums.resize(texels);
    gather.info.resize(texels);
    gather.slots = h.layout.split.slots();
    gather.split_rgb.resize(3 * size_t(gather.slots) * texels);
    read_records(r, texels, kGatherTexelBytes + layer_bytes(gather.slots), [&](size_t i, Cursor& c) {
      read_split(c, gather.split_rgb.data() + 3 * i * gather.slots, h.layout.split, path, "the gather sums' split",
                  h.range_begin + i);
      get_stratified(c, gather.sums[i]);
      GatherInfo& g = gather.info[i];
      g.unknown = c.get<uint32_t>();
      g.dark = c.get<uint32_t>();
      for (double* v : {&g.lookup_all, &g.lookup_cells, &g.lookup_rays, &g.lookup_wide}) *v = c.get<double>();
      for (float* v : {&g.hit_distance, &g.calibration_measured, &g.calibration_estimated}) *v = c.get<float>();
      const uint64_t texel = h.range_begin + i;
      check_record(finite_sums(gather.sums[i]), path, "the gather sums", texel);
      check_record(non_negative(g.lookup_all) && non_negative(g.lookup_cells) && non_negative(g.lookup_rays) &&
                       non_negative(g.lookup_wide) && non_negative(g.calibration_measured) &&
                       non_negative(g.calibration_estimated),
                   path, "the gather's error terms", texel);
      check_record(g.hit_distance >= 0.0f, path, "the gather's hit distance", texel);  // +inf: nothing hit
    });
  });
}

PartHeader read_part_header(const std::string& path) {
  unsigned char buf[kPartHeaderBytes];
  uint64_t bytes = 0, sum = 0;
  PartHeader h;
  open_part(path, buf, bytes, sum, h);
  return h;
}

PartHeader read_part_file(const std::string& path, std::vector<PhotonSegment>& segments) {
  return read_part(path, PartKind::kPhotons, [&](Reader& r, const PartHeader& h) {
    const ShardLayout& L = h.layout;
    segments.clear();
    for (uint32_t i = 0; i < h.segment_count; ++i) {
      PhotonSegment s;
      s.acc = Accumulators(L.texel_count, L.mesh_count, L.caustics, L.quantum, L.split);
      Accumulators& a = s.acc;
      s.begin = r.value<uint64_t>();
      s.end = r.value<uint64_t>();
      s.rays = r.value<uint64_t>();
      s.truncated = r.value<uint64_t>();
      a.total_hits = r.value<uint64_t>();
      a.total_sq_q = r.value<uint64_t>();
      a.caustic.total_hits = r.value<uint64_t>();
      a.caustic.total_sq_q = r.value<uint64_t>();
      s.truncated_flux = r.value<double>();
      r.array(a.sum);
      r.array(a.sum_sq);
      r.array(a.hits);
      r.array(a.back_lit);
      if (L.caustics) {
        r.array(a.caustic.sum);
        r.array(a.caustic.sum_sq);
        r.array(a.caustic.hits);
      }
      r.array(a.split_sum);
      a.group_hits.resize(L.judged_groups);
      a.group_hits_sq.resize(L.judged_groups);
      r.array(a.group_hits);
      r.array(a.group_hits_sq);
      a.total_sq = double(a.total_sq_q) * L.quantum.q2;
      a.caustic.total_sq = double(a.caustic.total_sq_q) * L.quantum.q2;
      segments.push_back(std::move(s));
    }
  });
}

std::string part_mismatch(const PartHeader& a, const PartHeader& b) {
  // b's value first: the message is about b ("its seed 8 against 7").
  const BakeSettings &s = a.settings, &t = b.settings;
  auto against = [](const std::string& what, auto mine, auto theirs) {
    return what + " " + std::to_string(mine) + " against " + std::to_string(theirs);
  };
  if (a.engine_version != b.engine_version) return "engine version " + b.engine_version + " against " + a.engine_version;
  if (a.scene_hash != b.scene_hash) return "scene (another scene or another version of it)";
  if (s.seed != t.seed) return against("seed", t.seed, s.seed);
  if (s.photon_count != t.photon_count) return against("photon count", t.photon_count, s.photon_count);
  if (s.max_bounces != t.max_bounces || s.direct_samples != t.direct_samples || s.filter_radius != t.filter_radius ||
      s.dilation != t.dilation || s.texel_value != t.texel_value || s.sampler != t.sampler)
    return "settings (max_bounces, direct_samples, filter_radius, dilation, texel_value or sampler)";
  if (s.directional != t.directional)
    return std::string("settings: ") + (t.directional ? "directional" : "plain") + " lightmaps against " +
           (s.directional ? "directional" : "plain") + " ones";
  if (a.kind == b.kind && a.shard_count != b.shard_count)
    return against(a.kind == PartKind::kPhotons ? "shard count" : "range count", b.shard_count, a.shard_count);
  if (a.kind == b.kind && a.direct_target != b.direct_target)
    return against("target error", b.direct_target, a.direct_target);
  if (a.kind == b.kind && a.gathered != b.gathered) return "final gather (another version of the scene?)";
  if (a.layout.batch_count != b.layout.batch_count || a.layout.texel_count != b.layout.texel_count ||
      a.layout.covered != b.layout.covered ||
      a.layout.mesh_count != b.layout.mesh_count || a.layout.caustics != b.layout.caustics ||
      a.layout.quantum.q != b.layout.quantum.q || a.layout.quantum.q2 != b.layout.quantum.q2 ||
      a.layout.split.layers != b.layout.split.layers || a.layout.split.directional != b.layout.split.directional ||
      a.layout.judged_groups != b.layout.judged_groups)
    return "sizes (batches, texels, meshes, judged groups, light-group layers, directional lightmaps or flux quantum)";
  return "";
}

}  // namespace plm

namespace plm {

namespace {

// What the parts of `kind` are called in messages.
const char* unit_name(PartKind kind) {
  return kind == PartKind::kPhotons ? "shard" : kind == PartKind::kDirect ? "direct range" : "gather range";
}

// Checks that the parts `members` (indices into paths, all of one kind and
// count) hold every shard or range exactly once; returns them in that order.
// Works on the parts given, not on the count, which a damaged header may make
// huge: the missing ones are listed up to kMissingListed.
std::vector<size_t> in_order(const std::vector<std::string>& paths, const std::vector<PartHeader>& headers,
                             const std::vector<size_t>& members) {
  constexpr size_t kMissingListed = 32;
  const PartHeader& lead = headers[members[0]];
  const char* unit = unit_name(lead.kind);
  std::vector<size_t> sorted = members;
  std::stable_sort(sorted.begin(), sorted.end(),
                   [&](size_t a, size_t b) { return headers[a].shard_index < headers[b].shard_index; });
  for (size_t j = 1; j < sorted.size(); ++j)
    if (headers[sorted[j]].shard_index == headers[sorted[j - 1]].shard_index)
      fail(PLM_ERROR_INVALID_ARGUMENT, paths[sorted[j]], ": ", unit, " ", headers[sorted[j]].shard_index + 1, " of ",
           lead.shard_count, " is also ", paths[sorted[j - 1]]);
  std::string missing;
  size_t listed = 0;
  uint32_t next = 0;  // the first index not yet accounted for
  auto gap = [&](uint32_t end) {  // indices [next, end) are missing
    for (uint32_t k = next; k < end && listed <= kMissingListed; ++k, ++listed)
      missing += listed == kMissingListed ? ", ..." : (missing.empty() ? "" : ", ") + std::to_string(k + 1);
  };
  for (size_t i : sorted) {
    gap(headers[i].shard_index);
    next = headers[i].shard_index + 1;
  }
  gap(lead.shard_count);
  if (!missing.empty())
    fail(PLM_ERROR_INVALID_ARGUMENT, unit, "(s) ", missing, " of ", lead.shard_count, " missing: ", members.size(),
         " ", part_kind_name(lead.kind), " file(s) given");
  return sorted;
}

}  // namespace

PartHeader load_parts(const std::vector<std::string>& paths, const std::string& engine_version, uint64_t hash,
                      ShardJob& job) {
  if (paths.empty()) fail(PLM_ERROR_INVALID_ARGUMENT, "no part files to merge");
  std::vector<PartHeader> headers;
  for (const std::string& p : paths) headers.push_back(read_part_header(p));
  // The parts by kind; a range's gather passes over gather parts (its
  // siblings may share its folder).
  std::vector<size_t> of[3];
  for (size_t i = 0; i < headers.size(); ++i)
    if (!(job.mode == ShardJob::kGather && headers[i].kind == PartKind::kGather))
      of[size_t(headers[i].kind)].push_back(i);
  std::vector<size_t>& photon_parts = of[size_t(PartKind::kPhotons)];
  if (photon_parts.empty())
    fail(PLM_ERROR_INVALID_ARGUMENT, "no photon parts (part-K-of-N.plmpart) among the ", paths.size(),
         " part file(s) given, the first ", paths[0], " (a ", part_kind_name(headers[0].kind),
         "): every shard's photons are needed");
  const size_t ref = photon_parts[0];
  const PartHeader& first = headers[ref];
  if (first.engine_version != engine_version)
    fail(PLM_ERROR_INVALID_ARGUMENT, paths[ref], ": written by photonlm ", first.engine_version, ", this is ",
         engine_version, "; bake the shards and merge with one version");
  if (first.scene_hash != hash)
    fail(PLM_ERROR_INVALID_ARGUMENT, paths[ref], ": its shard baked another scene (or another version of '",
         first.scene_path, "') than the one given to the merge");
  for (const std::vector<size_t>& group : of) {
    if (group.empty()) continue;
    const size_t lead = group[0];
    for (size_t i : group) {
      const PartHeader& h = headers[i];
      std::string why = part_mismatch(first, h);
      size_t against = ref;
      if (why.empty() && h.kind != PartKind::kPhotons) why = part_mismatch(headers[lead], h), against = lead;
      if (!why.empty())
        fail(PLM_ERROR_INVALID_ARGUMENT, paths[i], ": does not belong with ", paths[against], ": its ", why);
      if (h.kind != PartKind::kPhotons) {
        const CoveredSlice want = texel_range(h.layout.covered, h.shard_index, h.shard_count);
        if (h.range_begin != want.begin || h.range_end != want.end)
          fail(PLM_ERROR_INVALID_ARGUMENT, paths[i], ": holds covered texels ", h.range_begin, "-", h.range_end,
               " where ", unit_name(h.kind), " ", h.shard_index + 1, " of ", h.shard_count, " is ", want.begin, "-",
               want.end);
      }
    }
  }
  const std::vector<size_t> owner = in_order(paths, headers, photon_parts);
  const std::vector<size_t> direct_parts =
      of[1].empty() ? std::vector<size_t>() : in_order(paths, headers, of[size_t(PartKind::kDirect)]);
  const std::vector<size_t> gather_parts =
      of[2].empty() ? std::vector<size_t>() : in_order(paths, headers, of[size_t(PartKind::kGather)]);
  // The gathers looked up an estimate made with the direct passes given here
  // (or, with no direct parts, with the merge's own: no target).
  const double direct_target = direct_parts.empty() ? 0.0 : headers[direct_parts[0]].direct_target;
  if (!gather_parts.empty() && headers[gather_parts[0]].direct_target != direct_target)
    fail(PLM_ERROR_INVALID_ARGUMENT, paths[gather_parts[0]], ": its gather looked up direct light baked to the "
         "target error ", headers[gather_parts[0]].direct_target, " where the direct ",
         direct_parts.empty() ? "pass of the merge has none" : "parts given have " + std::to_string(direct_target),
         "; give the merge the direct parts its gather stage read");

  const ShardLayout& L = first.layout;
  const uint64_t cut = std::min<uint64_t>(kCheckBatches, L.batch_count);
  PhotonSegment early, late;
  early.end = cut;
  late.begin = cut;
  late.end = L.batch_count;
  early.acc = late.acc = Accumulators(L.texel_count, L.mesh_count, L.caustics, L.quantum, L.split);
  // Parts in shard order; their segments must follow each other without gaps.
  // A range's gather looks up the first `cut` batches only: it reads the
  // shards that hold them and passes over the rest (the merge reads all).
  const bool early_only = job.mode == ShardJob::kGather;
  uint64_t next = 0;
  for (uint32_t k = 0; k < first.shard_count; ++k) {
    if (early_only && shard_batches(L.batch_count, k, first.shard_count).first >= cut) break;
    const std::string& path = paths[owner[k]];
    std::vector<PhotonSegment> segments;
    read_part_file(path, segments);
    for (const PhotonSegment& s : segments) {
      if (s.begin != next || s.end <= s.begin || s.end > L.batch_count || (s.begin < cut && s.end > cut))
        fail(PLM_ERROR_INVALID_ARGUMENT, path, ": holds photon batches ", s.begin, "-", s.end, " where batch ", next,
             " was expected next");
      if (early_only && s.begin >= cut) {
        next = s.end;
        continue;
      }
      PhotonSegment& into = s.end <= cut ? early : late;
      into.acc.add(s.acc);
      into.rays += s.rays;
      into.truncated += s.truncated;
      into.truncated_flux += s.truncated_flux;
      next = s.end;
    }
  }
  if (early_only ? next < cut : next != L.batch_count)
    fail(PLM_ERROR_INVALID_ARGUMENT, "the parts hold photon batches up to ", next, " of ", L.batch_count);
  if (job.mode != ShardJob::kGather) {
    job.mode = ShardJob::kMerge;
    job.count = first.shard_count;
  }
  job.direct_target = direct_target;
  job.direct.assign(direct_parts.size(), DirectResult());
  for (size_t k = 0; k < direct_parts.size(); ++k) read_direct_part(paths[direct_parts[k]], job.direct[k]);
  job.gather.clear();
  if (!gather_parts.empty() && headers[gather_parts[0]].gathered) {
    job.gather.assign(gather_parts.size(), GatherResult());
    for (size_t k = 0; k < gather_parts.size(); ++k) read_gather_part(paths[gather_parts[k]], job.gather[k]);
  }
  job.segments.clear();
  job.sources.clear();
  job.segments.push_back(std::move(early));
  job.sources.push_back("the parts' batches 0-" + std::to_string(cut));
  if (late.end > late.begin && !early_only) {
    job.segments.push_back(std::move(late));
    job.sources.push_back("the parts' batches " + std::to_string(cut) + "-" + std::to_string(L.batch_count));
  }
  job.layout = L;
  job.layout.scene_hash = hash;
  return first;
}

}  // namespace plm
