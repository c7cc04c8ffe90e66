#include "lightmap/stitch.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>
#include <unordered_map>

#include <tbb/parallel_for.h>

namespace plm {
namespace {

// How strongly a texel outside the islands is held to its dilated value (its
// own value is only an extrapolation), relative to a covered texel of typical error.
constexpr double kHoldFree = 1e-3;
// A covered texel of typical error: held so that it moves by about its error at
// most (towards the other side's estimate of the same points).
constexpr double kHoldCovered = 0.25;
constexpr double kPull = 0.5;  // the pull on a texel beside one seam
constexpr int kMaxIterations = 200;

// One point compared along a seam: the bilinear weights of the two sides'
// texels (0-3 in image[0], 4-7 in image[1]), side B's negative, so that the
// row times the texels is the jump.
struct Row {
  uint32_t image[2];
  uint32_t texel[8];
  double weight[8];
};

void bilinear(const float uv[2], uint32_t w, uint32_t h, double sign, uint32_t* texel, double* weight) {
  const double x = double(uv[0]) * w - 0.5, y = double(uv[1]) * h - 0.5;
  const double fx0 = std::floor(x), fy0 = std::floor(y);
  const double fx = x - fx0, fy = y - fy0;
  auto clampi = [](double v, uint32_t n) { return uint32_t(std::clamp(v, 0.0, double(n - 1))); };
  const uint32_t x0 = clampi(fx0, w), x1 = clampi(fx0 + 1.0, w), y0 = clampi(fy0, h), y1 = clampi(fy0 + 1.0, h);
  texel[0] = y0 * w + x0;
  texel[1] = y0 * w + x1;
  texel[2] = y1 * w + x0;
  texel[3] = y1 * w + x1;
  weight[0] = sign * (1 - fx) * (1 - fy);
  weight[1] = sign * fx * (1 - fy);
  weight[2] = sign * (1 - fx) * fy;
  weight[3] = sign * fx * fy;
}

Vec3 triangle_normal(const Mesh& mesh, uint32_t t) {
  const Vec3 n = cross(mesh.vertex(t, 1) - mesh.vertex(t, 0), mesh.vertex(t, 2) - mesh.vertex(t, 0));
  const float len = length(n);
  return len > 0.0f ? n * (1.0f / len) : Vec3{0, 0, 0};
}

// A triangle whose area is below 1e-10 of its squared edge lengths: its
// normal cannot be trusted.
bool degenerate(const Mesh& mesh, uint32_t t) {
  const Vec3 p0 = mesh.vertex(t, 0), p1 = mesh.vertex(t, 1), p2 = mesh.vertex(t, 2);
  const double area = 0.5 * double(length(cross(p1 - p0, p2 - p0)));
  const double edges = double(dot(p1 - p0, p1 - p0)) + double(dot(p2 - p0, p2 - p0)) + double(dot(p2 - p1, p2 - p1));
  return !(area > 1e-10 * edges);
}

// Keeps triangle t's edge from corner lo to corner hi as an open edge, unless
// the triangle is smaller than kMinSeamTexels or degenerate.
void add_open(const Mesh& mesh, uint32_t t, uint8_t lo, uint8_t hi, double texels, std::vector<OpenEdge>& open) {
  if (!(texels >= kMinSeamTexels)) return;
  const Vec3 p0 = mesh.vertex(t, lo), p1 = mesh.vertex(t, hi), p2 = mesh.vertex(t, 3 - lo - hi);
  const Vec3 d = p1 - p0, v = p2 - p0;
  if (degenerate(mesh, t) || !(dot(d, d) > 0.0f)) return;
  const Vec3 across = v - d * (dot(v, d) / dot(d, d));
  const float across_len = length(across);
  if (!(across_len > 0.0f)) return;
  OpenEdge e;
  e.p0 = p0;
  e.p1 = p1;
  e.inward = across * (1.0f / across_len);
  e.flat = !mesh.smooth();
  if (e.flat) {
    e.n0 = e.n1 = triangle_normal(mesh, t);
  } else {
    e.n0 = mesh.normals[3 * size_t(t) + lo];
    e.n1 = mesh.normals[3 * size_t(t) + hi];
  }
  std::memcpy(e.uv0, &mesh.uv[6 * size_t(t) + 2 * lo], sizeof e.uv0);
  std::memcpy(e.uv1, &mesh.uv[6 * size_t(t) + 2 * hi], sizeof e.uv1);
  open.push_back(e);
}

uint32_t image_of(const Row& r, int k) { return r.image[k >> 2]; }
uint64_t texel_key(uint32_t image, uint32_t t) { return (uint64_t(image) << 32) | t; }
bool is_covered(const std::vector<SeamImage>& images, uint32_t image, uint32_t t) {
  return images[image].covered[t] != 0;
}
double value(const std::vector<SeamImage>& images, uint32_t image, uint32_t t, int c) {
  const SeamImage& im = images[image];
  return double(im.colour[size_t(t) * im.stride + c]);
}
// A texel's squared error (the error channel), 0 without one.
double sigma2(const std::vector<SeamImage>& images, uint32_t image, uint32_t t) {
  const SeamImage& im = images[image];
  const double e = im.error ? double(im.error[size_t(t) * im.error_stride]) : 0.0;
  return std::isfinite(e) ? e * e : 0.0;
}

// The points compared along the seams between images with texels: two per
// texel along the longer side (2 to 4096 per seam); stats.edges counts the seams.
std::vector<Row> seam_rows(const std::vector<LinkedSeam>& seams, const std::vector<SeamImage>& images,
                           SeamStats& stats) {
  std::vector<Row> rows;
  for (const LinkedSeam& link : seams) {
    const SeamEdge& s = link.edge;
    const SeamImage &A = images[link.a], &B = images[link.b];
    if (A.width == 0 || A.height == 0 || B.width == 0 || B.height == 0) continue;
    auto texels = [&](const float* p, const float* q, const SeamImage& im) {
      return std::hypot(double(q[0] - p[0]) * im.width, double(q[1] - p[1]) * im.height);
    };
    const double len = std::max(texels(s.a0, s.a1, A), texels(s.b0, s.b1, B));
    if (!std::isfinite(len)) continue;
    const int n = int(std::clamp(std::ceil(2.0 * len), 2.0, 4096.0));
    // Rows weigh sqrt(texels per sample): an edge pulls as hard as it is long,
    // however finely it is sampled.
    const double scale = std::sqrt(std::max(len, 0.5) / n);
    for (int k = 0; k < n; ++k) {
      const float t = (float(k) + 0.5f) / float(n);
      const float a[2] = {s.a0[0] + t * (s.a1[0] - s.a0[0]), s.a0[1] + t * (s.a1[1] - s.a0[1])};
      const float b[2] = {s.b0[0] + t * (s.b1[0] - s.b0[0]), s.b0[1] + t * (s.b1[1] - s.b0[1])};
      Row r;
      r.image[0] = link.a;
      r.image[1] = link.b;
      bilinear(a, A.width, A.height, scale, r.texel, r.weight);
      bilinear(b, B.width, B.height, -scale, r.texel + 4, r.weight + 4);
      rows.push_back(r);
    }
    ++stats.edges;
  }
  return rows;
}

// The seams as a least-squares system over the texels the rows read. A
// covered texel is held to its value in proportion to 1 / its error (the
// error channel), so it moves by about its own noise at most; one without
// error (exact) stays fixed and enters the rows as a constant. Texels outside
// the islands hold only an extrapolation and move freely.
struct SeamSystem {
  const std::vector<Row>& rows;
  const std::vector<SeamImage>& images;
  std::vector<uint64_t> free_texel;  // the texels that may move, numbered locally: texel_key(image, texel)
  std::vector<double> hold;          // how strongly each is held to its value
  std::vector<int32_t> slot;         // local index of each row entry (row * 8 + k), -1 if fixed
};

// The mean squared error of the covered texels the rows read (each read counted).
double mean_covered_sigma2(const std::vector<Row>& rows, const std::vector<SeamImage>& images) {
  double ref = 0.0;
  size_t ref_count = 0;
  for (const Row& r : rows)
    for (int k = 0; k < 8; ++k)
      if (is_covered(images, image_of(r, k), r.texel[k]))
        ref += sigma2(images, image_of(r, k), r.texel[k]), ++ref_count;
  return ref_count ? ref / double(ref_count) : 0.0;
}

// How hard the rows pull on each texel (sum of squared weights): a texel
// pulled by many seam points is held harder, so that none moves by more
// than about its error however many seams pass it.
std::unordered_map<uint64_t, double> row_pulls(const std::vector<Row>& rows) {
  std::unordered_map<uint64_t, double> pull;
  for (const Row& r : rows)
    for (int k = 0; k < 8; ++k) pull[texel_key(image_of(r, k), r.texel[k])] += r.weight[k] * r.weight[k];
  return pull;
}

SeamSystem seam_system(const std::vector<Row>& rows, const std::vector<SeamImage>& images) {
  SeamSystem sys{rows, images, {}, {}, std::vector<int32_t>(rows.size() * 8, -1)};
  const double ref = mean_covered_sigma2(rows, images);
  std::unordered_map<uint64_t, double> pull = row_pulls(rows);
  std::unordered_map<uint64_t, uint32_t> local;
  for (size_t r = 0; r < rows.size(); ++r)
    for (int k = 0; k < 8; ++k) {
      const uint32_t im = image_of(rows[r], k), t = rows[r].texel[k];
      const double s2 = sigma2(images, im, t);
      const double h = !is_covered(images, im, t) ? kHoldFree
                       : s2 > 1e-6 * ref ? kHoldCovered * ref / s2 * std::max(1.0, pull[texel_key(im, t)] / kPull)
                                         : -1.0;
      if (h < 0.0) continue;
      auto [it, added] = local.emplace(texel_key(im, t), uint32_t(sys.free_texel.size()));
      if (added) sys.free_texel.push_back(texel_key(im, t)), sys.hold.push_back(h);
      sys.slot[r * 8 + k] = int32_t(it->second);
    }
  return sys;
}

// out = (A^T A + H) x over the free texels; ax: A x, one value per row.
void apply(const SeamSystem& sys, const std::vector<double>& x, std::vector<double>& ax, std::vector<double>& out) {
  const std::vector<Row>& rows = sys.rows;
  for (size_t r = 0; r < rows.size(); ++r) {
    double s = 0.0;
    for (int k = 0; k < 8; ++k)
      if (sys.slot[r * 8 + k] >= 0) s += rows[r].weight[k] * x[size_t(sys.slot[r * 8 + k])];
    ax[r] = s;
  }
  for (size_t i = 0; i < sys.hold.size(); ++i) out[i] = sys.hold[i] * x[i];
  for (size_t r = 0; r < rows.size(); ++r)
    for (int k = 0; k < 8; ++k)
      if (sys.slot[r * 8 + k] >= 0) out[size_t(sys.slot[r * 8 + k])] += rows[r].weight[k] * ax[r];
}

// Adds channel c's squared jumps across the rows to sq, and their mean level to level.
void jump(const SeamSystem& sys, int c, double& sq, double& level) {
  for (const Row& r : sys.rows) {
    double d = 0.0, a = 0.0, b = 0.0;
    for (int k = 0; k < 8; ++k) {
      const double v = value(sys.images, image_of(r, k), r.texel[k], c);
      d += r.weight[k] * v;
      (k < 4 ? a : b) += std::fabs(r.weight[k]) * v;
    }
    sq += d * d;
    level += 0.5 * (a + b);
  }
}

// Channel c's free texels (x0) and the right-hand side H x0 - A^T fixed.
void start_channel(const SeamSystem& sys, int c, std::vector<double>& x, std::vector<double>& rhs) {
  const std::vector<Row>& rows = sys.rows;
  std::vector<double> fixed(rows.size());
  for (size_t r = 0; r < rows.size(); ++r) {
    double s = 0.0;
    for (int k = 0; k < 8; ++k)
      if (sys.slot[r * 8 + k] < 0)
        s += rows[r].weight[k] * value(sys.images, image_of(rows[r], k), rows[r].texel[k], c);
    fixed[r] = s;
  }
  for (size_t i = 0; i < x.size(); ++i) {
    x[i] = value(sys.images, uint32_t(sys.free_texel[i] >> 32), uint32_t(sys.free_texel[i]), c);
    rhs[i] = sys.hold[i] * x[i];
  }
  for (size_t r = 0; r < rows.size(); ++r)
    for (int k = 0; k < 8; ++k)
      if (sys.slot[r * 8 + k] >= 0) rhs[size_t(sys.slot[r * 8 + k])] -= rows[r].weight[k] * fixed[r];
}

// Solves (A^T A + H) x = rhs by conjugate gradients from x.
void conjugate_gradients(const SeamSystem& sys, const std::vector<double>& rhs, std::vector<double>& x) {
  const size_t m = x.size();
  std::vector<double> res(m), dir(m), kd(m), ax(sys.rows.size());
  apply(sys, x, ax, kd);
  double rr = 0.0, bb = 0.0;
  for (size_t i = 0; i < m; ++i) {
    res[i] = dir[i] = rhs[i] - kd[i];
    rr += res[i] * res[i];
    bb += rhs[i] * rhs[i];
  }
  for (int it = 0; it < kMaxIterations && rr > 1e-20 * bb && rr > 0.0; ++it) {
    apply(sys, dir, ax, kd);
    double dkd = 0.0;
    for (size_t i = 0; i < m; ++i) dkd += dir[i] * kd[i];
    if (!(dkd > 0.0)) break;
    const double alpha = rr / dkd;
    double rr_next = 0.0;
    for (size_t i = 0; i < m; ++i) {
      x[i] += alpha * dir[i];
      res[i] -= alpha * kd[i];
      rr_next += res[i] * res[i];
    }
    for (size_t i = 0; i < m; ++i) dir[i] = res[i] + (rr_next / rr) * dir[i];
    rr = rr_next;
  }
}

struct ChannelJumps {
  double before = 0, after = 0, level = 0;
};

// Channel c: minimises sum_r (row . texels)^2 + sum_i hold_i (x_i - x0_i)^2
// over the texels that may move, (A^T A + H) x = H x0 - A^T fixed, and
// writes the result back; the jumps before and after.
void solve_channel(const SeamSystem& sys, int c, ChannelJumps& jumps) {
  double unused = 0.0;
  jump(sys, c, jumps.before, jumps.level);
  const size_t m = sys.free_texel.size();
  if (m == 0) {
    jump(sys, c, jumps.after, unused);
    return;
  }
  std::vector<double> x(m), rhs(m);
  start_channel(sys, c, x, rhs);
  conjugate_gradients(sys, rhs, x);
  for (size_t i = 0; i < m; ++i)
    if (std::isfinite(x[i])) {
      const SeamImage& im = sys.images[size_t(sys.free_texel[i] >> 32)];
      im.colour[size_t(uint32_t(sys.free_texel[i])) * im.stride + c] = float(std::max(x[i], 0.0));
    }
  jump(sys, c, jumps.after, unused);
}

}  // namespace

std::vector<SeamEdge> find_seams(const Mesh& mesh, std::vector<OpenEdge>* open) {
  std::vector<SeamEdge> seams;
  const uint32_t tris = mesh.triangle_count();
  if (mesh.uv.empty() || tris == 0) return seams;
  // Vertices by position: indices of equal positions share one id.
  std::vector<uint32_t> order(mesh.vertex_count), id(mesh.vertex_count);
  for (uint32_t i = 0; i < mesh.vertex_count; ++i) order[i] = i;
  auto key = [&](uint32_t i) {
    const Vec3& p = mesh.positions[i];
    return std::make_tuple(p.x, p.y, p.z);
  };
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key(a) < key(b); });
  for (uint32_t k = 0, next = 0; k < order.size(); ++k) {
    if (k > 0 && key(order[k]) != key(order[k - 1])) ++next;
    id[order[k]] = next;
  }
  // Edges by their end points' ids: (low id, high id, triangle, corner of the low end, of the high end).
  struct Edge {
    uint64_t key;
    uint32_t tri;
    uint8_t lo, hi;
  };
  std::vector<Edge> edges;
  edges.reserve(size_t(tris) * 3);
  for (uint32_t t = 0; t < tris; ++t)
    for (uint8_t e = 0; e < 3; ++e) {
      const uint8_t f = uint8_t((e + 1) % 3);
      uint32_t a = id[mesh.indices[3 * t + e]], b = id[mesh.indices[3 * t + f]];
      if (a == b) continue;
      const bool swap = a > b;
      if (swap) std::swap(a, b);
      edges.push_back({(uint64_t(a) << 32) | b, t, swap ? f : e, swap ? e : f});
    }
  std::sort(edges.begin(), edges.end(), [](const Edge& x, const Edge& y) {
    return x.key < y.key || (x.key == y.key && x.tri < y.tri);
  });
  auto uv_of = [&](uint32_t t, uint8_t corner) { return &mesh.uv[6 * size_t(t) + 2 * corner]; };
  // A triangle's area in texels: lookups along an edge of a triangle smaller
  // than a few texels read mostly other triangles' texels.
  auto texels = [&](uint32_t t) {
    const float* q = &mesh.uv[6 * size_t(t)];
    return 0.5 * std::fabs(double(q[2] - q[0]) * (q[5] - q[1]) - double(q[4] - q[0]) * (q[3] - q[1])) *
           double(mesh.lightmap_width) * double(mesh.lightmap_height);
  };
  for (size_t i = 0; i < edges.size();) {
    size_t j = i + 1;
    while (j < edges.size() && edges[j].key == edges[i].key) ++j;
    if (open) {  // a border: one triangle along the edge, not counting degenerate ones
      size_t solid = 0, last = i;
      for (size_t k = i; k < j; ++k)
        if (!degenerate(mesh, edges[k].tri)) ++solid, last = k;
      if (solid == 1) add_open(mesh, edges[last].tri, edges[last].lo, edges[last].hi, texels(edges[last].tri), *open);
    }
    if (j - i == 2 && edges[i].tri != edges[i + 1].tri) {  // a manifold edge
      const Edge& A = edges[i];
      const Edge& B = edges[i + 1];
      const float *a0 = uv_of(A.tri, A.lo), *a1 = uv_of(A.tri, A.hi);
      const float *b0 = uv_of(B.tri, B.lo), *b1 = uv_of(B.tri, B.hi);
      const bool cut = a0[0] != b0[0] || a0[1] != b0[1] || a1[0] != b1[0] || a1[1] != b1[1];
      bool smooth;
      if (mesh.smooth()) {
        const Vec3* nA = &mesh.normals[3 * size_t(A.tri)];
        const Vec3* nB = &mesh.normals[3 * size_t(B.tri)];
        smooth = dot(nA[A.lo], nB[B.lo]) > kSmoothNormalCos && dot(nA[A.hi], nB[B.hi]) > kSmoothNormalCos;
      } else {
        smooth = dot(triangle_normal(mesh, A.tri), triangle_normal(mesh, B.tri)) > kFlatCos;
      }
      if (cut && smooth && texels(A.tri) >= kMinSeamTexels && texels(B.tri) >= kMinSeamTexels) {
        SeamEdge s;
        std::memcpy(s.a0, a0, sizeof s.a0);
        std::memcpy(s.a1, a1, sizeof s.a1);
        std::memcpy(s.b0, b0, sizeof s.b0);
        std::memcpy(s.b1, b1, sizeof s.b1);
        seams.push_back(s);
      }
    }
    i = j;
  }
  return seams;
}

SeamStats stitch_seams(const std::vector<SeamEdge>& seams, const std::vector<uint8_t>& covered,
                       std::vector<float>& values, int channels, uint32_t width, uint32_t height) {
  if (seams.empty() || width == 0 || height == 0) return SeamStats{};
  SeamImage image;
  image.colour = values.data();
  image.stride = channels;
  image.error = channels >= 4 ? values.data() + 3 : nullptr;
  image.error_stride = channels;
  image.covered = covered.data();
  image.width = width;
  image.height = height;
  std::vector<LinkedSeam> linked;
  linked.reserve(seams.size());
  for (const SeamEdge& s : seams) linked.push_back({0, 0, s});
  return stitch_images(linked, {image}, std::min(channels, 3));
}

SeamStats stitch_images(const std::vector<LinkedSeam>& seams, const std::vector<SeamImage>& images, int colour) {
  SeamStats stats;
  colour = std::clamp(colour, 0, 3);
  const std::vector<Row> rows = seam_rows(seams, images, stats);
  stats.samples = rows.size();
  if (rows.empty()) return stats;
  const SeamSystem sys = seam_system(rows, images);
  // Per channel, each on its own buffers. Small systems are solved in turn;
  // larger ones (seams between many objects) one channel per thread. The
  // channels are independent: the same texels either way.
  ChannelJumps jumps[3];
  auto solve = [&](int c) { solve_channel(sys, c, jumps[c]); };
  if (rows.size() * size_t(colour) < 20000) {
    for (int c = 0; c < colour; ++c) solve(c);
  } else {
    tbb::parallel_for(0, colour, solve);
  }
  const double before = jumps[0].before + jumps[1].before + jumps[2].before,
               after = jumps[0].after + jumps[1].after + jumps[2].after,
               level = jumps[0].level + jumps[1].level + jumps[2].level;
  if (level > 0.0) {
    const double count = double(rows.size()) * colour;
    const double mean = level / count;
    stats.jump_before = std::sqrt(before / count) / mean;
    stats.jump_after = std::sqrt(after / count) / mean;
  }
  return stats;
}

}  // namespace plm
