// libFuzzer target for the part files of sharded bakes (transport/farm/partial_file.h):
// a damaged, truncated, extended or forged part goes through plm_part_info
// and plm_bake_merge of the scene it claims to belong to. The library must
// never crash, hang, leak or trip a sanitizer, and every refusal must leave a
// message.
//
// At start-up a small scene (a quad under a point light) is baked as one
// shard, one direct range and one gather range: three valid parts to start
// from. Input format: a byte choosing the start (% 4: the photon part, the
// direct part, the gather part, or none: the rest of the input is the file),
// a flags byte, then edits of 3 bytes each (a little-endian offset into the
// file, modulo its size, and the byte to put there). Flags: 2 recomputes the
// header checksum after the edits (so that forged counts, kinds and ranges
// get past it), 4 resizes the file first (a 16-bit length from the input,
// modulo the size + 64), 1 recomputes the payload checksum too, only with
// PHOTONLM_FUZZ_FORGE=1: the reader checks a payload's size and checksum, not
// the values of its sums, so forged sums reach the estimator (a negative
// gather hit distance is converted to an out-of-range integer there, UBSan);
// exploration, not the test command's run. A direct or gather part is merged
// together with the valid photon part.
//
// Build and run: scripts/fuzz.sh [seconds]. Seeds: native/fuzz/corpus/part_file/
// (native/fuzz/make_corpus.py).
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "photonlm/photonlm.h"
#include "transport/farm/shard.h"

namespace {

// Header fields the checksums depend on (byte offsets: transport/farm/partial_file.cpp's
// encode_header; checked against the valid parts at start-up).
constexpr size_t kHeaderBytes = 512, kTexelCount = 92, kMeshCount = 100, kCaustics = 104, kSegmentCount = 124,
                 kPayloadSum = 140, kKind = 404, kGathered = 408, kRangeBegin = 420, kRangeEnd = 428,
                 kCalibrationCount = 448, kJudgedGroups = 456, kHeaderSum = kHeaderBytes - 8;
constexpr size_t kChunk = 4096;  // texel records are checksummed this many at a time

std::string g_dir;
bool g_forge = false;  // PHOTONLM_FUZZ_FORGE=1: flag 1 recomputes payload checksums
plm_scene* g_scene = nullptr;
std::string g_parts[3];  // photon, direct and gather part
std::vector<unsigned char> g_bytes[3];

void check(bool ok, const char* what) {
  if (!ok) {
    fprintf(stderr, "fuzz_part_file: %s (last error: %s)\n", what, plm_last_error());
    abort();
  }
}

template <typename T>
T field(const std::vector<unsigned char>& f, size_t at) {
  T v{};
  if (at + sizeof v <= f.size()) std::memcpy(&v, f.data() + at, sizeof v);
  return v;
}

// The payload checksum as the reader chains it: piece by piece in the order it reads them.
uint64_t payload_sum(const std::vector<unsigned char>& f) {
  uint64_t sum = 0;
  size_t at = kHeaderBytes;
  bool inside = true;
  auto piece = [&](uint64_t n) {
    if (n == 0 || !inside) return;
    if (n > f.size() - at) {
      inside = false;
      return;
    }
    sum = plm::hash_bytes(f.data() + at, n, sum);
    at += n;
  };
  auto records = [&](uint64_t count, uint64_t bytes) {
    for (uint64_t i = 0; i < count && inside; i += kChunk) piece(std::min<uint64_t>(kChunk, count - i) * bytes);
  };
  const uint64_t texels = field<uint64_t>(f, kTexelCount);
  const uint64_t range = field<uint64_t>(f, kRangeEnd) - field<uint64_t>(f, kRangeBegin);
  switch (field<uint32_t>(f, kKind)) {
    case 0:
      for (uint32_t s = 0; s < std::min(field<uint32_t>(f, kSegmentCount), 2u); ++s) {
        for (int i = 0; i < 9; ++i) piece(8);
        for (int k = 0; k < (field<uint32_t>(f, kCaustics) ? 2 : 1); ++k) {
          piece(texels * 24);
          piece(texels * 8);
          piece(texels * 4);
          if (k == 0) piece(field<uint32_t>(f, kMeshCount));
        }
        for (int i = 0; i < 2; ++i) piece(uint64_t(field<uint32_t>(f, kJudgedGroups)) * 8);  // group hits, squared
      }
      break;
    case 1:
      records(range, 88);
      records(field<uint32_t>(f, kCalibrationCount), 80);
      break;
    case 2:
      if (field<uint32_t>(f, kGathered)) records(range, 100);
      break;
  }
  return sum;
}

void reseal_header(std::vector<unsigned char>& f) {
  if (f.size() < kHeaderBytes) return;
  const uint64_t h = plm::hash_bytes(f.data(), kHeaderSum);
  std::memcpy(f.data() + kHeaderSum, &h, sizeof h);
}

std::vector<unsigned char> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<unsigned char>(std::istreambuf_iterator<char>(in), {});
}

void write_file(const std::string& path, const std::vector<unsigned char>& bytes) {
  FILE* f = fopen(path.c_str(), "wb");
  check(f != nullptr, "cannot write the input part");
  check(fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size() && fclose(f) == 0, "cannot write the input part");
}

void make_parts() {
  check(plm_scene_create(&g_scene) == PLM_OK, "create the scene");
  const float albedo[3] = {0.7f, 0.7f, 0.7f}, black[3] = {0, 0, 0};
  check(plm_scene_add_material(g_scene, "grey", albedo, black, nullptr) == PLM_OK, "add a material");
  const float pos[12] = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  check(plm_scene_add_mesh(g_scene, "floor", pos, 4, idx, 2, uv, nullptr, 4, 4, nullptr) == PLM_OK, "add a mesh");
  const float wall[12] = {-1, 1, 0, 1, 1, 0, 1, 1, 2, -1, 1, 2};
  check(plm_scene_add_mesh(g_scene, "wall", wall, 4, idx, 2, uv, nullptr, 4, 4, nullptr) == PLM_OK, "add a mesh");
  plm_light light;
  plm_light_default(&light, PLM_LIGHT_POINT);
  light.power = 50.0f;
  light.matrix[11] = 1.0f;
  check(plm_scene_add_light(g_scene, "lamp", &light, nullptr) == PLM_OK, "add a light");
  plm_bake_settings s;
  plm_bake_settings_default(&s);
  s.photon_count = 8192;
  s.direct_samples = 1;
  s.thread_count = 1;
  const char* names[3] = {"/photons.part", "/direct.part", "/gather.part"};
  for (int i = 0; i < 3; ++i) g_parts[i] = g_dir + names[i];
  check(plm_bake_shard(g_scene, &s, 0, 1, "scene.json", g_parts[0].c_str(), nullptr, nullptr) == PLM_OK,
        "bake the photon part");
  check(plm_bake_texels(g_scene, &s, PLM_TEXELS_DIRECT, 0, 1, nullptr, 0, "scene.json", g_parts[1].c_str(), nullptr,
                        nullptr) == PLM_OK,
        "bake the direct part");
  const char* inputs[2] = {g_parts[0].c_str(), g_parts[1].c_str()};
  check(plm_bake_texels(g_scene, &s, PLM_TEXELS_GATHER, 0, 1, inputs, 2, "scene.json", g_parts[2].c_str(), nullptr,
                        nullptr) == PLM_OK,
        "bake the gather part");
  for (int i = 0; i < 3; ++i) {
    g_bytes[i] = read_file(g_parts[i]);
    std::vector<unsigned char> resealed = g_bytes[i];
    const uint64_t sum = payload_sum(resealed);
    std::memcpy(resealed.data() + kPayloadSum, &sum, sizeof sum);
    reseal_header(resealed);
    check(resealed == g_bytes[i], "resealing a valid part changes it: the part format moved (update the offsets)");
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* forge = getenv("PHOTONLM_FUZZ_FORGE");
  g_forge = forge && *forge && *forge != '0';
  char tmpl[] = "/tmp/photonlm_fuzz_part_XXXXXX";
  const char* dir = mkdtemp(tmpl);
  if (!dir) abort();
  g_dir = dir;
  make_parts();
  atexit([] {
    plm_scene_release(g_scene);
    for (const std::string& p : g_parts) unlink(p.c_str());
    unlink((g_dir + "/input.part").c_str());
    rmdir(g_dir.c_str());
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const unsigned start = data[0] % 4, flags = data[1];
  size_t at = 2;
  std::vector<unsigned char> f;
  if (start == 3) {
    f.assign(data + at, data + size);
  } else {
    f = g_bytes[start];
    if ((flags & 4) && at + 2 <= size) {
      f.resize((data[at] | data[at + 1] << 8) % (f.size() + 64), 0);
      at += 2;
    }
    for (; at + 3 <= size && !f.empty(); at += 3) f[(data[at] | data[at + 1] << 8) % f.size()] = data[at + 2];
    if (g_forge && (flags & 1) && f.size() >= kHeaderBytes) {
      const uint64_t sum = payload_sum(f);
      std::memcpy(f.data() + kPayloadSum, &sum, sizeof sum);
    }
    if (flags & 2) reseal_header(f);
  }
  const std::string path = g_dir + "/input.part";
  write_file(path, f);

  plm_bake_settings s;
  plm_bake_settings_default(&s);
  uint32_t shard = 0, count = 0;
  char scene_path[64];
  const plm_status info = plm_part_info(path.c_str(), &s, &shard, &count, scene_path, sizeof scene_path);
  check(info == PLM_OK || plm_last_error()[0] != '\0', "a refused part left no message");
  if (info == PLM_OK) check(shard < count && std::strlen(scene_path) < sizeof scene_path, "part info in range");

  const char* parts[2] = {g_parts[0].c_str(), path.c_str()};
  const bool with_photons = start == 1 || start == 2;
  plm_result* result = nullptr;
  const plm_status merged =
      plm_bake_merge(g_scene, with_photons ? parts : parts + 1, with_photons ? 2 : 1, 1, nullptr, nullptr, &result);
  check(merged == PLM_OK || plm_last_error()[0] != '\0', "a refused merge left no message");
  check((merged == PLM_OK) == (result != nullptr), "a result exactly when the merge succeeds");
  plm_result_release(result);
  return 0;
}
