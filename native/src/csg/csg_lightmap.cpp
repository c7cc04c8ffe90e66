#include "csg/csg_lightmap.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <limits>

#include "util/error.h"

namespace plm::csg {
namespace {

constexpr int kMaxGrid = 32;
constexpr uint16_t kUnvisited = 0xFFFEu;

// Local chart point: point, outward unit normal, area per unit (s, t) area.
struct LocalPoint {
  Vec3d q, n;
  double area;
};

double wrap01(double a) {
  const double w = a - std::floor(a);
  return w >= 1.0 ? 0.0 : w;
}

double clamp01(double a) { return std::fmin(1.0, std::fmax(0.0, a)); }

FaceCoord disk_to_square(double x, double y) {
  double r = std::hypot(x, y);
  if (r > 1) {
    x /= r;
    y /= r;
    r = 1;
  }
  double a = 0, b = 0;
  if (r > 0) {
    if (std::fabs(x) >= std::fabs(y)) {
      a = std::copysign(r, x);
      b = a * std::atan(y / x) * (4 / kPiD);
    } else {
      b = std::copysign(r, y);
      a = b * std::atan(x / y) * (4 / kPiD);
    }
  }
  return {clamp01(0.5 * (a + 1)), clamp01(0.5 * (b + 1))};
}

// Clarberg's equal-area octahedral map of [0,1]^2 onto the unit sphere (4 pi per unit square).
Vec3d square_to_sphere(double s, double t) {
  const double u = 2 * s - 1, v = 2 * t - 1;
  const double up = std::fabs(u), vp = std::fabs(v);
  const double sd = 1 - (up + vp), r = 1 - std::fabs(sd);
  const double phi = (r == 0 ? 1 : (vp - up) / r + 1) * (kPiD / 4);
  const double z = std::copysign(1 - r * r, sd);
  const double k = r * std::sqrt(std::fmax(0.0, 2 - r * r));
  return {std::copysign(std::cos(phi), u) * k, std::copysign(std::sin(phi), v) * k, z};
}

FaceCoord sphere_to_square(Vec3d q) {
  const double len = length(q);
  if (!(len > 0)) return {0.5, 0.5};
  q = q / len;
  const double x = std::fabs(q.x), y = std::fabs(q.y), z = std::fabs(q.z);
  const double r = std::sqrt((x * x + y * y) / (1 + z));  // sqrt(1 - |z|) without cancellation at the poles
  const double v0 = std::atan2(y, x) * (2 / kPiD) * r;
  double u = r - v0, v = v0;
  if (q.z < 0) {
    const double u1 = 1 - v, v1 = 1 - u;
    u = u1;
    v = v1;
  }
  u = std::copysign(u, q.x);
  v = std::copysign(v, q.y);
  return {clamp01(0.5 * (u + 1)), clamp01(0.5 * (v + 1))};
}

LocalPoint disk_point(double s, double t, double z, double nz) {
  LocalPoint lp;
  concentric_disk(s, t, lp.q.x, lp.q.y);
  lp.q.z = z;
  lp.n = {0, 0, nz};
  lp.area = kPiD;
  return lp;
}

LocalPoint local_face_point(const Primitive& prim, int face, double s, double t, const PlaneRect& rect) {
  LocalPoint lp;
  switch (prim.shape) {
    case Shape::Sphere:
      lp.q = lp.n = square_to_sphere(s, t);
      lp.area = 4 * kPiD;
      return lp;
    case Shape::Box:
      lp.q = box_face_point(face, s, t);
      lp.n[face / 2] = lp.q[face / 2];
      lp.area = 4;
      return lp;
    case Shape::Cylinder: {
      if (face > 0) return disk_point(s, t, face == 1 ? -1 : 1, face == 1 ? -1 : 1);
      const double phi = 2 * kPiD * s, c = std::cos(phi), sn = std::sin(phi);
      lp.q = {c, sn, 2 * t - 1};
      lp.n = {c, sn, 0};
      lp.area = 4 * kPiD;
      return lp;
    }
    case Shape::Cone: {
      if (face == 1) return disk_point(s, t, -1, -1);
      double x, y;
      concentric_disk(s, t, x, y);
      const double rho = std::hypot(x, y);
      lp.q = {x, y, 1 - 2 * rho};
      lp.n = rho > 0 ? Vec3d{2 * x / rho, 2 * y / rho, 1} / std::sqrt(5.0) : Vec3d{0, 0, 1};
      lp.area = kPiD * std::sqrt(5.0);
      return lp;
    }
    case Shape::Torus: {
      const double phi = 2 * kPiD * s, psi = 2 * kPiD * t;
      const double c = std::cos(phi), sn = std::sin(phi), cp = std::cos(psi), sp = std::sin(psi);
      const double R = prim.major, r = prim.minor, w = R + r * cp;
      lp.q = {w * c, w * sn, r * sp};
      lp.n = {cp * c, cp * sn, sp};
      lp.area = 4 * kPiD * kPiD * r * w;
      return lp;
    }
    case Shape::Paraboloid: {
      if (face == 1) return disk_point(s, t, 1, 1);
      double x, y;
      concentric_disk(s, t, x, y);
      const double rho2 = x * x + y * y, g = std::sqrt(1 + 4 * rho2);
      lp.q = {x, y, rho2};
      lp.n = Vec3d{2 * x, 2 * y, -1} / g;
      lp.area = kPiD * g;
      return lp;
    }
    case Shape::HalfSpace:
      break;
  }
  lp.q = {rect.x0 + s * (rect.x1 - rect.x0), rect.y0 + t * (rect.y1 - rect.y0), 0};
  lp.n = {0, 0, 1};
  lp.area = std::fabs((rect.x1 - rect.x0) * (rect.y1 - rect.y0));
  return lp;
}

// Gauss-Legendre, 4 points on [0, 1].
constexpr double kGaussX[4] = {0.5 - 0.5 * 0.8611363115940526, 0.5 - 0.5 * 0.3399810435848563,
                               0.5 + 0.5 * 0.3399810435848563, 0.5 + 0.5 * 0.8611363115940526};
constexpr double kGaussW[4] = {0.5 * 0.3478548451374538, 0.5 * 0.6521451548625461, 0.5 * 0.6521451548625461,
                               0.5 * 0.3478548451374538};

void check_settings(const CsgObject& obj, const CsgLightmapSettings& settings) {
  if (!(settings.texel_size > 0) || !std::isfinite(settings.texel_size))
    fail(PLM_ERROR_INVALID_ARGUMENT, "CSG lightmap of '", obj.name(), "': texel_size must be positive and finite (got ",
         settings.texel_size, ")");
  if (settings.grid < 2 || settings.grid > kMaxGrid)
    fail(PLM_ERROR_INVALID_ARGUMENT, "CSG lightmap of '", obj.name(), "': grid must be in 2..", kMaxGrid, " (got ",
         settings.grid, ")");
  if (settings.max_resolution < 1 || settings.max_resolution > 4096)
    fail(PLM_ERROR_INVALID_ARGUMENT, "CSG lightmap of '", obj.name(), "': max_resolution must be in 1..4096 (got ",
         settings.max_resolution, ")");
}

}  // namespace

bool plane_rect(const Primitive& half_space, Vec3d lo, Vec3d hi, PlaneRect& out) {
  if (!is_finite(lo) || !is_finite(hi)) return false;
  out = {std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
         std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  const Vec3d origin = half_space.to_world.column(3);
  for (int i = 0; i < 8; ++i) {
    const Vec3d c{(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z};
    const Vec3d q = half_space.to_local.vector(c - origin);
    out.x0 = std::fmin(out.x0, q.x);
    out.x1 = std::fmax(out.x1, q.x);
    out.y0 = std::fmin(out.y0, q.y);
    out.y1 = std::fmax(out.y1, q.y);
  }
  return out.x1 > out.x0 && out.y1 > out.y0;
}

FacePoint face_point(const Primitive& prim, int face, double s, double t, const PlaneRect& rect) {
  const LocalPoint lp = local_face_point(prim, face, s, t, rect);
  const Vec3d nw = prim.to_local.transpose_vector(lp.n);
  const double len = length(nw);
  FacePoint fp;
  fp.p = prim.to_world.point(lp.q);
  fp.n = nw / len;
  fp.area = lp.area * std::fabs(prim.to_world.det()) * len;  // Nanson's formula
  return fp;
}

FaceCoord face_param(const Primitive& prim, int face, Vec3d p, const PlaneRect& rect) {
  const Vec3d q = prim.to_local.vector(p - prim.to_world.column(3));
  switch (prim.shape) {
    case Shape::Sphere:
      return sphere_to_square(q);
    case Shape::Box: {
      const int a = face / 2, b = (a + 1) % 3, e = (a + 2) % 3;
      return {clamp01(0.5 * (q[b] + 1)), clamp01(0.5 * (q[e] + 1))};
    }
    case Shape::Cylinder:
      if (face > 0) return disk_to_square(q.x, q.y);
      return {wrap01(std::atan2(q.y, q.x) / (2 * kPiD)), clamp01(0.5 * (q.z + 1))};
    case Shape::Cone:
    case Shape::Paraboloid:
      return disk_to_square(q.x, q.y);
    case Shape::Torus: {
      const double rho = std::hypot(q.x, q.y);
      return {wrap01(std::atan2(q.y, q.x) / (2 * kPiD)), wrap01(std::atan2(q.z, rho - prim.major) / (2 * kPiD))};
    }
    case Shape::HalfSpace:
      break;
  }
  return {clamp01((q.x - rect.x0) / (rect.x1 - rect.x0)), clamp01((q.y - rect.y0) / (rect.y1 - rect.y0))};
}

namespace {

// A chart's W / H: the mean length of its s lines over that of its t lines.
double chart_aspect(const Primitive& prim, int f, const PlaneRect& rect) {
  constexpr int kLines = 5, kSegments = 32;
  double ls = 0, lt = 0;
  for (int k = 0; k < kLines; ++k) {
    const double c = (k + 0.5) / kLines;
    Vec3d ps = face_point(prim, f, 0, c, rect).p, pt = face_point(prim, f, c, 0, rect).p;
    for (int j = 1; j <= kSegments; ++j) {
      const Vec3d qs = face_point(prim, f, double(j) / kSegments, c, rect).p;
      const Vec3d qt = face_point(prim, f, c, double(j) / kSegments, rect).p;
      ls += length(qs - ps);
      lt += length(qt - pt);
      ps = qs;
      pt = qt;
    }
  }
  return ls > 0 && lt > 0 ? ls / lt : 1.0;
}

}  // namespace

// ---- CsgLightmap ----

CsgLightmap::CsgLightmap(const CsgObject& obj, const CsgLightmapSettings& settings) : obj_(&obj), g_(settings.grid) {
  const auto start = std::chrono::steady_clock::now();
  check_settings(obj, settings);
  const uint64_t total = add_faces(settings);
  stats_.faces = faces_.size();
  stats_.texels = total;
  std::vector<uint16_t> counts(total, 1);
  std::vector<uint8_t> cut(total, 0);
  if (settings.split) count_sub_texels(counts, cut);
  place_sub_texels(counts, cut);
  // Areas, representative points, label grids (in parallel).
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, uint32_t(total), 16), [&](const tbb::blocked_range<uint32_t>& r) {
    for (uint32_t i = r.begin(); i != r.end(); ++i) fill_texel(i, settings.split);
  });
  stats_.sub_texels = subs_.size();
  stats_.bytes = sizeof(*this) + faces_.capacity() * sizeof(Face) + prim_first_face_.capacity() * sizeof(uint32_t) +
                 texels_.capacity() * sizeof(Texel) + subs_.capacity() * sizeof(SubTexel) +
                 cut_counts_.capacity() * sizeof(uint16_t) + labels_.capacity() * sizeof(uint16_t) +
                 weights_.capacity() * sizeof(float);
  stats_.setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Faces and their resolutions: W H ~ area / texel^2 with W / H the chart's
// aspect. Returns the number of texels.
uint64_t CsgLightmap::add_faces(const CsgLightmapSettings& settings) {
  const CsgObject& obj = *obj_;
  uint64_t total = 0;
  prim_first_face_.resize(obj.primitive_count());
  for (uint32_t i = 0; i < obj.primitive_count(); ++i) {
    const Primitive& prim = obj.primitive(i);
    prim_first_face_[i] = uint32_t(faces_.size());
    for (int f = 0; f < csg::face_count(prim.shape); ++f) {
      Face face{i, uint32_t(f), 0, 0, uint32_t(total), PlaneRect{}};
      double area = prim.area[f];
      if (prim.shape == Shape::HalfSpace) {
        if (!plane_rect(prim, obj.bounds_lo(), obj.bounds_hi(), face.rect)) {
          ++stats_.unbounded_faces;
          faces_.push_back(face);
          continue;
        }
        area = face_point(prim, f, 0.5, 0.5, face.rect).area;
      }
      const double aspect = chart_aspect(prim, f, face.rect);
      auto side = [&](double len) {
        const double n = std::round(len / settings.texel_size);
        return uint32_t(std::clamp(std::isfinite(n) ? n : 1.0, 1.0, double(settings.max_resolution)));
      };
      face.width = side(std::sqrt(area * aspect));
      face.height = side(std::sqrt(area / aspect));
      total += uint64_t(face.width) * face.height;
      if (total >= uint64_t(kNone / 2))
        fail(PLM_ERROR_INVALID_ARGUMENT, "CSG lightmap of '", obj.name(), "': more than 2^31 texels (texel_size ",
             settings.texel_size, " is too small for the object)");
      faces_.push_back(face);
    }
  }
  return total;
}

// Per texel: the number of sub-texels, and whether it is cut (in parallel).
void CsgLightmap::count_sub_texels(std::vector<uint16_t>& counts, std::vector<uint8_t>& cut) const {
  auto count = [&](const tbb::blocked_range<uint32_t>& r) {
    uint16_t labels[kMaxGrid * kMaxGrid];
    for (uint32_t i = r.begin(); i != r.end(); ++i) {
      const Face& f = faces_[face_of_texel(i)];
      const uint32_t local = i - f.first_texel;
      const int regions = classify_texel(f, local % f.width, local / f.width, labels);
      counts[i] = uint16_t(regions);
      const int cells = g_ * g_;
      cut[i] = regions > 0 && std::any_of(labels, labels + cells, [](uint16_t l) { return l == kNoLabel; });
    }
  };
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, uint32_t(counts.size()), 16), count);
}

// Each texel's first sub-texel and cut-texel index (serial prefix sums); the
// arrays sized.
void CsgLightmap::place_sub_texels(const std::vector<uint16_t>& counts, const std::vector<uint8_t>& cut) {
  const size_t total = counts.size();
  texels_.resize(total);
  uint32_t subs = 0, cuts = 0;
  for (uint32_t i = 0; i < total; ++i) {
    texels_[i].first_sub = counts[i] ? subs : kNone;
    texels_[i].cut = cut[i] ? cuts : kNone;
    subs += counts[i];
    if (cut[i]) {
      ++cuts;
      ++stats_.cut;
    } else if (counts[i]) {
      ++stats_.uncut;
    } else {
      ++stats_.inert;
    }
  }
  subs_.resize(subs);
  cut_counts_.resize(cuts);
  labels_.resize(size_t(cuts) * g_ * g_);
  weights_.resize(size_t(cuts) * g_ * g_);
}

// Texel i's sub-texels: areas, representative points and, for a cut texel,
// its label grid and cell weights.
void CsgLightmap::fill_texel(uint32_t i, bool split) {
  const Texel& tx = texels_[i];
  if (tx.first_sub == kNone) return;
  const Face& f = faces_[face_of_texel(i)];
  const uint32_t local = i - f.first_texel, x = local % f.width, y = local / f.width;
  const double texel_area = this->texel_area(f, x, y);
  if (tx.cut != kNone) {
    fill_cut_texel(i, f, x, y, texel_area);
    return;
  }
  const Primitive& prim = obj_->primitive(f.prim);
  const FacePoint fp = face_point(prim, int(f.face), (x + 0.5) / f.width, (y + 0.5) / f.height, f.rect);
  const bool flip = split && flipped_at(fp);
  subs_[tx.first_sub] = {fp.p, flip ? -fp.n : fp.n, texel_area, i, 0, uint8_t(flip)};
}

void CsgLightmap::fill_cut_texel(uint32_t i, const Face& f, uint32_t x, uint32_t y, double texel_area) {
  const int cells = g_ * g_;
  const Texel& tx = texels_[i];
  const Primitive& prim = obj_->primitive(f.prim);
  uint16_t* labels = &labels_[size_t(tx.cut) * cells];
  float* weights = &weights_[size_t(tx.cut) * cells];
  const int regions = classify_texel(f, x, y, labels);
  cut_counts_[tx.cut] = uint16_t(regions);
  double w[kMaxGrid * kMaxGrid], sum = 0;
  double region_w[kMaxGrid * kMaxGrid] = {}, cx_sum[kMaxGrid * kMaxGrid] = {}, cy_sum[kMaxGrid * kMaxGrid] = {};
  for (int c = 0; c < cells; ++c) {
    const FaceCoord st = cell_centre(f, x, y, c % g_, c / g_);
    w[c] = face_point(prim, int(f.face), st.s, st.t, f.rect).area;
    sum += w[c];
    if (labels[c] == kNoLabel) continue;
    region_w[labels[c]] += w[c];
    cx_sum[labels[c]] += w[c] * (c % g_);
    cy_sum[labels[c]] += w[c] * (c / g_);
  }
  for (int c = 0; c < cells; ++c) weights[c] = float(w[c] * cells / sum);
  for (int k = 0; k < regions; ++k) {
    // The representative: the region's cell nearest to its weighted centroid.
    const double mx = cx_sum[k] / region_w[k], my = cy_sum[k] / region_w[k];
    int best = -1;
    double best_d = 0;
    for (int c = 0; c < cells; ++c) {
      if (labels[c] != k) continue;
      const double dx = c % g_ - mx, dy = c / g_ - my, d = dx * dx + dy * dy;
      if (best < 0 || d < best_d) best = c, best_d = d;
    }
    const FaceCoord st = cell_centre(f, x, y, best % g_, best / g_);
    const FacePoint fp = face_point(prim, int(f.face), st.s, st.t, f.rect);
    const bool flip = flipped_at(fp);
    subs_[tx.first_sub + k] = {fp.p, flip ? -fp.n : fp.n, texel_area * region_w[k] / sum, i, uint16_t(k),
                               uint8_t(flip)};
  }
}

uint32_t CsgLightmap::face_index(uint32_t prim, int face) const {
  if (prim >= prim_first_face_.size() || face < 0 || face >= csg::face_count(obj_->primitive(prim).shape)) return kNone;
  return prim_first_face_[prim] + uint32_t(face);
}

uint32_t CsgLightmap::face_of_texel(uint32_t texel) const {
  // The last face starting at or before texel (faces without texels share the next one's offset).
  const auto it = std::upper_bound(faces_.begin(), faces_.end(), texel,
                                   [](uint32_t v, const Face& f) { return v < f.first_texel; });
  return uint32_t(it - faces_.begin()) - 1;
}

uint32_t CsgLightmap::texel_sub_count(uint32_t texel) const {
  const Texel& t = texels_[texel];
  if (t.first_sub == kNone) return 0;
  return t.cut == kNone ? 1 : cut_counts_[t.cut];
}

FaceCoord CsgLightmap::cell_centre(const Face& f, uint32_t x, uint32_t y, int cx, int cy) const {
  return {(x + (cx + 0.5) / g_) / f.width, (y + (cy + 0.5) / g_) / f.height};
}

// Labels the g x g cell centres of a texel: kNoLabel off the boundary, else
// the index of its 4-connected region; returns the number of regions.
int CsgLightmap::classify_texel(const Face& f, uint32_t x, uint32_t y, uint16_t* labels) const {
  const int cells = g_ * g_;
  const Primitive& prim = obj_->primitive(f.prim);
  for (int c = 0; c < cells; ++c) {
    const FaceCoord st = cell_centre(f, x, y, c % g_, c / g_);
    const Vec3d p = face_point(prim, int(f.face), st.s, st.t, f.rect).p;
    labels[c] = obj_->on_boundary(f.prim, int(f.face), p) ? kUnvisited : kNoLabel;
  }
  uint16_t queue[kMaxGrid * kMaxGrid];
  int regions = 0;
  for (int c = 0; c < cells; ++c) {
    if (labels[c] != kUnvisited) continue;
    int head = 0, tail = 0;
    queue[tail++] = uint16_t(c);
    labels[c] = uint16_t(regions);
    while (head < tail) {
      const int k = queue[head++], cx = k % g_, cy = k / g_;
      const int next[4] = {cx > 0 ? k - 1 : -1, cx + 1 < g_ ? k + 1 : -1, cy > 0 ? k - g_ : -1,
                           cy + 1 < g_ ? k + g_ : -1};
      for (int n : next) {
        if (n < 0 || labels[n] != kUnvisited) continue;
        labels[n] = uint16_t(regions);
        queue[tail++] = uint16_t(n);
      }
    }
    ++regions;
  }
  return regions;
}

double CsgLightmap::texel_area(const Face& f, uint32_t x, uint32_t y) const {
  const Primitive& prim = obj_->primitive(f.prim);
  double sum = 0;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i)
      sum += kGaussW[i] * kGaussW[j] *
             face_point(prim, int(f.face), (x + kGaussX[i]) / f.width, (y + kGaussX[j]) / f.height, f.rect).area;
  return sum / (double(f.width) * f.height);
}

// Whether the solid lies on the outer side of the face at fp (a subtracted primitive's face).
bool CsgLightmap::flipped_at(const FacePoint& fp) const {
  const double delta = 8 * (obj_->tolerance() + kRoundingTolerance * max_abs_component(fp.p));
  return obj_->inside(fp.p + fp.n * delta) && !obj_->inside(fp.p - fp.n * delta);
}

// The sub-texel of `texel` nearest to (cx, cy) (face position in texel units), with its squared distance.
int64_t CsgLightmap::nearest_in_texel(uint32_t texel, double cx, double cy, double& dist2) const {
  const Texel& t = texels_[texel];
  if (t.first_sub == kNone) return -1;
  const Face& f = faces_[face_of_texel(texel)];
  const uint32_t local = texel - f.first_texel, x = local % f.width, y = local / f.width;
  if (t.cut == kNone) {
    const double dx = std::fmax(0.0, std::fmax(x - cx, cx - (x + 1.0)));
    const double dy = std::fmax(0.0, std::fmax(y - cy, cy - (y + 1.0)));
    dist2 = dx * dx + dy * dy;
    return t.first_sub;
  }
  const uint16_t* labels = &labels_[size_t(t.cut) * g_ * g_];
  int64_t best = -1;
  for (int c = 0; c < g_ * g_; ++c) {
    if (labels[c] == kNoLabel) continue;
    const double dx = x + (c % g_ + 0.5) / g_ - cx, dy = y + (c / g_ + 0.5) / g_ - cy, d = dx * dx + dy * dy;
    if (best < 0 || d < dist2) best = int64_t(t.first_sub) + labels[c], dist2 = d;
  }
  return best;
}

double CsgLightmap::cover(uint32_t sub) const {
  const SubTexel& st = subs_[sub];
  const Texel& tx = texels_[st.texel];
  if (tx.cut == kNone) return 1.0;
  const int cells = g_ * g_;
  const uint16_t* labels = &labels_[size_t(tx.cut) * cells];
  const float* weights = &weights_[size_t(tx.cut) * cells];
  double w = 0.0;
  for (int c = 0; c < cells; ++c)
    if (labels[c] == st.label) w += weights[c];
  return w / cells;
}

int64_t CsgLightmap::sub_texel_of_hit(uint32_t prim, int face, Vec3d p) const {
  const uint32_t fi = face_index(prim, face);
  if (fi == kNone) return -1;
  const Face& f = faces_[fi];
  if (f.width == 0) return -1;
  const FaceCoord st = face_param(obj_->primitive(prim), face, p, f.rect);
  const double cx = st.s * f.width, cy = st.t * f.height;
  const int x = std::clamp(int(cx), 0, int(f.width) - 1), y = std::clamp(int(cy), 0, int(f.height) - 1);
  double d = 0;
  const int64_t own = nearest_in_texel(texel_index(fi, uint32_t(x), uint32_t(y)), cx, cy, d);
  if (own >= 0) return own;
  // An inert texel: a sliver thinner than the grid was missed; the nearest
  // boundary cell of a neighbour within half a texel takes the hit.
  int64_t best = -1;
  double best_d = 0.25;
  for (int j = std::max(0, y - 1); j <= std::min(int(f.height) - 1, y + 1); ++j)
    for (int i = std::max(0, x - 1); i <= std::min(int(f.width) - 1, x + 1); ++i) {
      const int64_t s = nearest_in_texel(texel_index(fi, uint32_t(i), uint32_t(j)), cx, cy, d);
      if (s >= 0 && d < best_d) best = s, best_d = d;
    }
  return best;
}

void CsgLightmap::sample_point(uint32_t sub, double u1, double u2, Vec3d& p, Vec3d& n) const {
  const SubTexel& st = subs_[sub];
  const Texel& tx = texels_[st.texel];
  const Face& f = faces_[face_of_texel(st.texel)];
  const Primitive& prim = obj_->primitive(f.prim);
  const uint32_t local = st.texel - f.first_texel, x = local % f.width, y = local / f.width;
  auto emit = [&](const FacePoint& fp) {
    p = fp.p;
    n = st.flipped ? -fp.n : fp.n;
  };
  if (tx.cut == kNone) {
    emit(face_point(prim, int(f.face), (x + u1) / f.width, (y + u2) / f.height, f.rect));
    return;
  }
  const int cells = g_ * g_;
  const uint16_t* labels = &labels_[size_t(tx.cut) * cells];
  const float* weights = &weights_[size_t(tx.cut) * cells];
  double total = 0;
  int last = 0;
  for (int c = 0; c < cells; ++c)
    if (labels[c] == st.label) total += weights[c], last = c;
  // The cell holding u1 * total; what is left of u1 jitters within it.
  double target = u1 * total, before = 0;
  int cell = last;
  for (int c = 0; c < cells; ++c) {
    if (labels[c] != st.label) continue;
    if (target < before + weights[c]) {
      cell = c;
      break;
    }
    before += weights[c];
  }
  double j1 = clamp01((target - before) / weights[cell]), j2 = u2;
  const int cx = cell % g_, cy = cell / g_;
  for (int attempt = 0; attempt < 5; ++attempt) {
    const FaceCoord c = attempt < 4 ? FaceCoord{(x + (cx + j1) / g_) / f.width, (y + (cy + j2) / g_) / f.height}
                                    : cell_centre(f, x, y, cx, cy);
    const FacePoint fp = face_point(prim, int(f.face), c.s, c.t, f.rect);
    if (attempt == 4 || obj_->on_boundary(f.prim, int(f.face), fp.p)) {
      emit(fp);
      return;
    }
    j1 = wrap01(j1 + 0.7548776662466927);  // R2 sequence steps: a new jitter from the same numbers
    j2 = wrap01(j2 + 0.5698402909980532);
  }
}

int64_t CsgLightmap::lookup(Vec3d p, Vec3d normal_hint, double tessellation_tolerance) const {
  const double reach = 2 * tessellation_tolerance;
  if (!(reach > 0) || !is_finite(p)) return -1;
  Crossing buffer[kMaxCrossings];
  // The crossing of the line p + u d (|u| <= reach) nearest to p, as a hit.
  auto nearest = [&](Vec3d d, CsgHit& hit, double& dist) {
    const Vec3d o = p - d * reach;
    const int n = obj_->crossings(o, d, 0, 2 * reach, buffer);
    bool found = false;
    for (int i = 0; i < n; ++i) {
      const double u = std::fabs(buffer[i].t - reach);
      if (!found || u < dist) {
        hit = obj_->make_hit(buffer[i], o, d);
        dist = u;
        found = true;
      }
    }
    return found;
  };
  CsgHit hit, best;
  double dist = 0, best_dist = 0;
  bool found = false;
  const double len = length(normal_hint);
  if (len > 0 && std::isfinite(len)) found = nearest(normal_hint / len, best, best_dist);
  if (!found) {
    const Vec3d axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (const Vec3d& a : axes)
      if (nearest(a, hit, dist) && (!found || dist < best_dist)) best = hit, best_dist = dist, found = true;
  }
  if (!found) return -1;
  return sub_texel_of_hit(best.prim, int(best.face), best.p);
}

}  // namespace plm::csg
