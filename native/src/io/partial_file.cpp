#include "io/partial_file.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>

#include "transport/scheduler.h"
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

uint64_t segment_bytes(uint64_t texels, uint32_t meshes, bool caustics) {
  const uint64_t sums = texels * (3 * 8 + 8 + 4);
  return 9 * 8 + sums + meshes + (caustics ? sums : 0);
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
  const plm_bake_settings& s = h.settings;
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
  c.put(uint32_t(0));
  c.put(payload_bytes);
  c.put(payload_sum);
  c.put_chars(h.scene_path, kPathChars);
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
  plm_bake_settings& s = h.settings;
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
  c.get<uint32_t>();
  payload_bytes = c.get<uint64_t>();
  payload_sum = c.get<uint64_t>();
  h.scene_path = c.get_chars(kPathChars);
  if (h.shard_count == 0 || h.shard_index >= h.shard_count || h.segment_count > 2)
    fail(PLM_ERROR_INVALID_ARGUMENT, path, ": shard ", h.shard_index, " of ", h.shard_count, " with ",
         h.segment_count, " segments is not a valid part");
  const uint64_t want = h.segment_count * segment_bytes(h.layout.texel_count, h.layout.mesh_count, h.layout.caustics);
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

}  // namespace

void write_part_file(const std::string& path, const PartHeader& header, const std::vector<PhotonSegment>& segments) {
  char host[64] = {0};
  gethostname(host, sizeof host - 1);
  const std::string tmp = path + ".tmp-" + host + "-" + std::to_string(getpid());
  File f(std::fopen(tmp.c_str(), "wb"));
  if (!f) fail(PLM_ERROR_IO, tmp, ": cannot create the part file: ", std::strerror(errno));
  const ShardLayout& L = header.layout;
  const uint64_t payload = segments.size() * segment_bytes(L.texel_count, L.mesh_count, L.caustics);
  unsigned char buf[kPartHeaderBytes];
  // The header first with a zero checksum (space), then again once the payload's is known.
  encode_header(header, payload, 0, buf);
  Writer w{f.get()};
  w.ok = std::fwrite(buf, 1, kPartHeaderBytes, f.get()) == kPartHeaderBytes;
  w.sum = 0;
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
    if (L.caustics) {
      w.array(a.caustic.sum);
      w.array(a.caustic.sum_sq);
      w.array(a.caustic.hits);
    }
  }
  PartHeader h = header;
  h.segment_count = uint32_t(segments.size());
  encode_header(h, payload, w.sum, buf);
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

PartHeader read_part_header(const std::string& path) {
  unsigned char buf[kPartHeaderBytes];
  uint64_t bytes = 0, sum = 0;
  PartHeader h;
  open_part(path, buf, bytes, sum, h);
  return h;
}

PartHeader read_part_file(const std::string& path, std::vector<PhotonSegment>& segments) {
  unsigned char buf[kPartHeaderBytes];
  uint64_t bytes = 0, want_sum = 0;
  PartHeader h;
  File f = open_part(path, buf, bytes, want_sum, h);
  const ShardLayout& L = h.layout;
  Reader r{f.get(), path};
  segments.clear();
  for (uint32_t i = 0; i < h.segment_count; ++i) {
    PhotonSegment s;
    s.acc = Accumulators(L.texel_count, L.mesh_count, L.caustics, L.quantum);
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
    a.total_sq = double(a.total_sq_q) * L.quantum.q2;
    a.caustic.total_sq = double(a.caustic.total_sq_q) * L.quantum.q2;
    segments.push_back(std::move(s));
  }
  if (r.sum != want_sum) fail(PLM_ERROR_INVALID_ARGUMENT, path, ": the part file's sums are damaged (checksum)");
  return h;
}

std::string part_mismatch(const PartHeader& a, const PartHeader& b) {
  // b's value first: the message is about b ("its seed 8 against 7").
  const plm_bake_settings &s = a.settings, &t = b.settings;
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
  if (a.shard_count != b.shard_count) return against("shard count", b.shard_count, a.shard_count);
  if (a.layout.batch_count != b.layout.batch_count || a.layout.texel_count != b.layout.texel_count ||
      a.layout.mesh_count != b.layout.mesh_count || a.layout.caustics != b.layout.caustics ||
      a.layout.quantum.q != b.layout.quantum.q || a.layout.quantum.q2 != b.layout.quantum.q2)
    return "sizes (batches, texels, meshes or flux quantum)";
  return "";
}

}  // namespace plm

namespace plm {

PartHeader load_parts(const std::vector<std::string>& paths, const std::string& engine_version, uint64_t hash,
                      ShardJob& job) {
  if (paths.empty()) fail(PLM_ERROR_INVALID_ARGUMENT, "no part files to merge");
  std::vector<PartHeader> headers;
  for (const std::string& p : paths) headers.push_back(read_part_header(p));
  const PartHeader& first = headers[0];
  if (first.engine_version != engine_version)
    fail(PLM_ERROR_INVALID_ARGUMENT, paths[0], ": written by photonlm ", first.engine_version, ", this is ",
         engine_version, "; bake the shards and merge with one version");
  if (first.scene_hash != hash)
    fail(PLM_ERROR_INVALID_ARGUMENT, paths[0], ": its shard baked another scene (or another version of '",
         first.scene_path, "') than the one given to the merge");
  std::vector<int> owner(first.shard_count, -1);
  for (size_t i = 0; i < headers.size(); ++i) {
    const std::string why = part_mismatch(first, headers[i]);
    if (!why.empty())
      fail(PLM_ERROR_INVALID_ARGUMENT, paths[i], ": does not belong with ", paths[0], ": its ", why);
    int& o = owner[headers[i].shard_index];
    if (o >= 0)
      fail(PLM_ERROR_INVALID_ARGUMENT, paths[i], ": shard ", headers[i].shard_index + 1, " of ", first.shard_count,
           " is also ", paths[size_t(o)]);
    o = int(i);
  }
  std::string missing;
  for (uint32_t k = 0; k < first.shard_count; ++k)
    if (owner[k] < 0) missing += (missing.empty() ? "" : ", ") + std::to_string(k + 1);
  if (!missing.empty())
    fail(PLM_ERROR_INVALID_ARGUMENT, "shard(s) ", missing, " of ", first.shard_count, " missing: ", paths.size(),
         " part file(s) given");

  const ShardLayout& L = first.layout;
  const uint64_t cut = std::min<uint64_t>(kCheckBatches, L.batch_count);
  PhotonSegment early, late;
  early.end = cut;
  late.begin = cut;
  late.end = L.batch_count;
  early.acc = late.acc = Accumulators(L.texel_count, L.mesh_count, L.caustics, L.quantum);
  // Parts in shard order; their segments must follow each other without gaps.
  uint64_t next = 0;
  for (uint32_t k = 0; k < first.shard_count; ++k) {
    const std::string& path = paths[size_t(owner[k])];
    std::vector<PhotonSegment> segments;
    read_part_file(path, segments);
    for (const PhotonSegment& s : segments) {
      if (s.begin != next || s.end <= s.begin || s.end > L.batch_count || (s.begin < cut && s.end > cut))
        fail(PLM_ERROR_INVALID_ARGUMENT, path, ": holds photon batches ", s.begin, "-", s.end, " where batch ", next,
             " was expected next");
      PhotonSegment& into = s.end <= cut ? early : late;
      into.acc.add(s.acc);
      into.rays += s.rays;
      into.truncated += s.truncated;
      into.truncated_flux += s.truncated_flux;
      next = s.end;
    }
  }
  if (next != L.batch_count)
    fail(PLM_ERROR_INVALID_ARGUMENT, "the parts hold photon batches up to ", next, " of ", L.batch_count);
  job.mode = ShardJob::kMerge;
  job.count = first.shard_count;
  job.segments.clear();
  job.sources.clear();
  job.segments.push_back(std::move(early));
  job.sources.push_back("the parts' batches 0-" + std::to_string(cut));
  if (late.end > late.begin) {
    job.segments.push_back(std::move(late));
    job.sources.push_back("the parts' batches " + std::to_string(cut) + "-" + std::to_string(L.batch_count));
  }
  job.layout = L;
  job.layout.scene_hash = hash;
  return first;
}

}  // namespace plm
