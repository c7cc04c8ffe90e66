#include "lightmap/object_seams.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>

namespace plm {
namespace {

// Float steps of a coordinate that two copies of one point may differ by
// (each object's vertices went through its own transform).
constexpr double kFloatSteps = 4.0 * FLT_EPSILON;

double max_abs(const Vec3& p) {
  return std::max({std::fabs(double(p.x)), std::fabs(double(p.y)), std::fabs(double(p.z))});
}

bool finite(const Vec3& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

// Whether a and b are one point: every coordinate within the tolerance plus
// a few float steps of the larger of the two.
bool near(const Vec3& a, const Vec3& b, double tolerance) {
  const double tol = tolerance + kFloatSteps * std::max(max_abs(a), max_abs(b));
  return std::fabs(double(a.x) - double(b.x)) <= tol && std::fabs(double(a.y) - double(b.y)) <= tol &&
         std::fabs(double(a.z) - double(b.z)) <= tol;
}

uint64_t cell_hash(int64_t x, int64_t y, int64_t z) {
  uint64_t h = uint64_t(x) * 0x9E3779B97F4A7C15ull;
  h ^= uint64_t(y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
  h ^= uint64_t(z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
  return h;
}

}  // namespace

std::vector<ObjectSeam> match_open_edges(const std::vector<std::vector<OpenEdge>>& open, double tolerance) {
  std::vector<ObjectSeam> seams;
  struct Ref {
    uint32_t mesh, index;
  };
  std::vector<Ref> refs;
  size_t meshes_with_edges = 0;
  for (uint32_t m = 0; m < open.size(); ++m) {
    meshes_with_edges += !open[m].empty();
    for (uint32_t k = 0; k < open[m].size(); ++k)
      if (finite(open[m][k].p0) && finite(open[m][k].p1)) refs.push_back({m, k});
  }
  if (meshes_with_edges < 2 || !(tolerance >= 0.0)) return seams;
  auto edge = [&](size_t r) -> const OpenEdge& { return open[refs[r].mesh][refs[r].index]; };
  // Cells of the hash grid: eight times the largest tolerance, so that the
  // points matching a point lie in its cell, or also in the neighbour across
  // a face it lies within a tolerance of (on average 2 cells to look in);
  // counted from the lower corner of all end points, in double.
  double lo[3] = {INFINITY, INFINITY, INFINITY}, largest = 0.0;
  for (size_t r = 0; r < refs.size(); ++r)
    for (const Vec3* p : {&edge(r).p0, &edge(r).p1}) {
      lo[0] = std::min(lo[0], double(p->x)), lo[1] = std::min(lo[1], double(p->y)), lo[2] = std::min(lo[2], double(p->z));
      largest = std::max(largest, max_abs(*p));
    }
  const double reach = tolerance + kFloatSteps * largest, cell = 8.0 * reach;
  if (!(cell > 0.0) || !std::isfinite(cell)) return seams;
  // A point's cell, and per axis the neighbour it lies within `reach` of (0: none).
  auto position = [&](const Vec3& p, int64_t index[3], int64_t side[3]) {
    const double c[3] = {double(p.x), double(p.y), double(p.z)};
    for (int a = 0; a < 3; ++a) {
      const double q = std::min((c[a] - lo[a]) / cell, 9.0e15), f = std::floor(q);
      index[a] = int64_t(f);
      side[a] = q - f < 0.125 ? -1 : q - f > 0.875 ? 1 : 0;
    }
  };
  // Each edge filed under the cells of both its end points; a cell's edges
  // are one run of the sorted list, found through an open-addressing table.
  std::vector<std::pair<uint64_t, uint32_t>> grid;
  grid.reserve(2 * refs.size());
  for (size_t r = 0; r < refs.size(); ++r)
    for (const Vec3* p : {&edge(r).p0, &edge(r).p1}) {
      int64_t i[3], side[3];
      position(*p, i, side);
      grid.push_back({cell_hash(i[0], i[1], i[2]), uint32_t(r)});
    }
  std::sort(grid.begin(), grid.end());
  struct Run {
    uint64_t hash;
    uint32_t begin = 0, end = 0;  // empty slot: begin == end
  };
  size_t cells = 0;
  for (size_t k = 0; k < grid.size(); ++k) cells += k == 0 || grid[k].first != grid[k - 1].first;
  size_t slots = 16;
  while (slots < 2 * cells) slots *= 2;
  std::vector<Run> table(slots);
  for (size_t k = 0; k < grid.size();) {
    size_t end = k + 1;
    while (end < grid.size() && grid[end].first == grid[k].first) ++end;
    size_t at = size_t(grid[k].first >> 7) & (slots - 1);
    while (table[at].end != table[at].begin) at = (at + 1) & (slots - 1);
    table[at] = {grid[k].first, uint32_t(k), uint32_t(end)};
    k = end;
  }
  auto find = [&](uint64_t hash) -> const Run* {
    for (size_t at = size_t(hash >> 7) & (slots - 1);; at = (at + 1) & (slots - 1)) {
      if (table[at].end == table[at].begin) return nullptr;
      if (table[at].hash == hash) return &table[at];
    }
  };
  struct Match {
    uint32_t e, f;
    bool swapped;
  };
  std::vector<Match> matches;
  for (size_t r = 0; r < refs.size(); ++r) {
    const OpenEdge& e = edge(r);
    // An edge shorter than the tolerance could match either way round.
    if (near(e.p0, e.p1, 2.0 * tolerance)) continue;
    // An edge matching e has an end point near e's first: in its cell or a
    // neighbour it lies near.
    int64_t i[3], side[3];
    position(e.p0, i, side);
    for (int corner = 0; corner < 8; ++corner) {
      if (((corner & 1) && !side[0]) || ((corner & 2) && !side[1]) || ((corner & 4) && !side[2])) continue;
      const Run* run = find(cell_hash(i[0] + (corner & 1 ? side[0] : 0), i[1] + (corner & 2 ? side[1] : 0),
                                      i[2] + (corner & 4 ? side[2] : 0)));
      if (!run) continue;
      for (uint32_t k = run->begin; k < run->end; ++k) {
        const size_t s = grid[k].second;
        if (s <= r || refs[s].mesh == refs[r].mesh) continue;
        const OpenEdge& f = edge(s);
        const bool forward = near(e.p0, f.p0, tolerance) && near(e.p1, f.p1, tolerance);
        const bool backward = near(e.p0, f.p1, tolerance) && near(e.p1, f.p0, tolerance);
        if (forward == backward) continue;  // no match, or a degenerate edge
        // The surfaces continue each other: the normals agree at both
        // ends, and the triangles lie on opposite sides of the edge.
        const Vec3& f0 = forward ? f.n0 : f.n1;
        const Vec3& f1 = forward ? f.n1 : f.n0;
        const bool smooth = e.flat && f.flat ? dot(e.n0, f0) > kFlatCos
                                             : dot(e.n0, f0) > kSmoothNormalCos && dot(e.n1, f1) > kSmoothNormalCos;
        if (smooth && dot(e.inward, f.inward) < 0.0f) matches.push_back({uint32_t(r), uint32_t(s), backward});
      }
    }
  }
  // An edge filed under two of the cells is found twice.
  std::sort(matches.begin(), matches.end(),
            [](const Match& a, const Match& b) { return a.e < b.e || (a.e == b.e && a.f < b.f); });
  matches.erase(std::unique(matches.begin(), matches.end(),
                            [](const Match& a, const Match& b) { return a.e == b.e && a.f == b.f; }),
                matches.end());
  std::vector<uint32_t> count(refs.size(), 0);
  for (const Match& m : matches) ++count[m.e], ++count[m.f];
  for (const Match& m : matches) {
    if (count[m.e] != 1 || count[m.f] != 1) continue;
    const OpenEdge &e = edge(m.e), &f = edge(m.f);
    ObjectSeam s;
    s.mesh_a = refs[m.e].mesh;
    s.mesh_b = refs[m.f].mesh;
    std::memcpy(s.edge.a0, e.uv0, sizeof s.edge.a0);
    std::memcpy(s.edge.a1, e.uv1, sizeof s.edge.a1);
    std::memcpy(s.edge.b0, m.swapped ? f.uv1 : f.uv0, sizeof s.edge.b0);
    std::memcpy(s.edge.b1, m.swapped ? f.uv0 : f.uv1, sizeof s.edge.b1);
    seams.push_back(s);
  }
  return seams;
}

SceneSeams find_scene_seams(const Scene& scene) {
  SceneSeams seams;
  const size_t n = scene.meshes.size();
  seams.within.resize(n);
  seams.joint.assign(n, 0);
  std::vector<std::vector<OpenEdge>> open(n);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  size_t taking_part = 0;
  for (size_t i = 0; i < n; ++i) {
    const Mesh& mesh = scene.meshes[i];
    if (!mesh.has_lightmap()) continue;
    const bool eligible = mesh.csg_carrier < 0 &&
                          (mesh.ol_group < 0 || scene.ol_groups[size_t(mesh.ol_group)].backup);
    seams.within[i] = find_seams(mesh, eligible ? &open[i] : nullptr);
    taking_part += !open[i].empty();
  }
  if (taking_part < 2) return seams;
  for (const Mesh& mesh : scene.meshes)
    for (uint32_t v = 0; v < mesh.vertex_count; ++v) {
      const Vec3& p = mesh.positions[v];
      if (!finite(p)) continue;
      const double c[3] = {double(p.x), double(p.y), double(p.z)};
      for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], c[a]), hi[a] = std::max(hi[a], c[a]);
    }
  const double diagonal = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                    (hi[2] - lo[2]) * (hi[2] - lo[2]));
  seams.between = match_open_edges(open, 1e-5 * diagonal);
  for (const ObjectSeam& s : seams.between) seams.joint[s.mesh_a] = seams.joint[s.mesh_b] = 1;
  return seams;
}

SeamStats stitch_scene_seams(const SceneSeams& seams, const std::vector<SeamImage>& images) {
  if (seams.between.empty()) return SeamStats{};
  std::vector<uint32_t> slot(images.size(), 0);
  std::vector<SeamImage> joint;
  std::vector<LinkedSeam> linked;
  for (size_t i = 0; i < images.size(); ++i) {
    if (!seams.joint[i]) continue;
    slot[i] = uint32_t(joint.size());
    joint.push_back(images[i]);
    for (const SeamEdge& s : seams.within[i]) linked.push_back({slot[i], slot[i], s});
  }
  for (const ObjectSeam& s : seams.between) linked.push_back({slot[s.mesh_a], slot[s.mesh_b], s.edge});
  return stitch_images(linked, joint, 3);
}

}  // namespace plm
