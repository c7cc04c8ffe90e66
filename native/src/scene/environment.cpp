#include "scene/environment.h"


#include <algorithm>
#include <cmath>

#include "util/error.h"
#include "util/image_file.h"

namespace plm {

namespace {

// The two pixel rows that dual-grid cell row k blends, and the nearer one's
// weight: interior rows blend their two rows equally; the half rows at the
// poles weigh their own row 3/4 and the wrapped one 1/4.
void cell_rows(uint32_t k, uint32_t height, uint32_t& near_row, uint32_t& far_row, double& near_w) {
  if (k == 0) near_row = 0, far_row = height - 1, near_w = 0.75;
  else if (k == height) near_row = height - 1, far_row = 0, near_w = 0.75;
  else near_row = k, far_row = k - 1, near_w = 0.5;
}



constexpr double kMaxRadiance = 1e30;  // as for every other radiance the scene takes

float srgb_to_linear(float c) {
  return c <= 0.04045f ? c * (1.0f / 12.92f) : std::pow((c + 0.055f) * (1.0f / 1.055f), 2.4f);
}

// One axis of Cycles' bilinear lookup with REPEAT: s in [0, 1] over n pixels
// whose centres lie at (i + 0.5) / n. The lower pixel i0, the upper i1, the
// weight f of i1.
inline void repeat_axis(float s, uint32_t n, uint32_t& i0, uint32_t& i1, float& f) {
  const float p = s * float(n) - 0.5f;
  const float below = std::floor(p);
  f = p - below;
  int64_t k = int64_t(below) % int64_t(n);
  if (k < 0) k += int64_t(n);
  i0 = uint32_t(k);
  i1 = i0 + 1 == n ? 0 : i0 + 1;
}

// The first index whose cumulative value exceeds u (zero-width entries are
// never chosen), and u's place inside that entry's interval, in [0, 1).
inline size_t invert_cdf(const double* cdf, size_t n, double u, float& rest) {
  size_t i = size_t(std::upper_bound(cdf, cdf + n, u) - cdf);
  if (i >= n) {  // rounding past the end: the last entry with width
    i = n - 1;
    while (i > 0 && cdf[i] == cdf[i - 1]) --i;
  }
  const double lo = i > 0 ? cdf[i - 1] : 0.0, width = cdf[i] - lo;
  rest = width > 0.0 ? float(std::min((u - lo) / width, 0.99999994)) : 0.5f;
  return i;
}

// A number in [0, 1) with density proportional to (1 - x) a + x b (a, b >= 0,
// not both 0) from a uniform u in [0, 1).
inline float sample_linear(float u, float a, float b) {
  if (a == b) return u;
  const float x = u * (a + b) / (a + std::sqrt((1.0f - u) * a * a + u * b * b));
  return std::fmin(x, 0.99999994f);
}

// sin and cos of the azimuth atan2(d.y, d.x) = 2 pi (0.5 - u) of map coordinate u in [0, 1].
inline void azimuth_of(float u, float& s, float& c) {
  float f = 0.5f - u;
  if (f < 0.0f) f += 1.0f;  // sincos_2pi takes a fraction of a turn in [0, 1)
  sincos_2pi(f, s, c);
}

}  // namespace

EnvironmentMap::EnvironmentMap(const float* rgb, uint32_t width, uint32_t height, const float rotation[9],
                               float strength, const std::string& owner) {
  if (width == 0 || height == 0 || double(width) * double(height) > double(1u << 28))
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": size ", width, " x ", height,
         " is invalid (both must be > 0, at most 2^28 pixels)");
  if (!rgb) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": rgb must not be NULL");
  if (!std::isfinite(strength) || strength < 0.0f || strength > kMaxRadiance)
    fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": strength ", strength, " is not in [0, 1e30]");
  static const float identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const float* r = rotation ? rotation : identity;
  for (int i = 0; i < 9; ++i)
    if (!std::isfinite(r[i])) fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": rotation[", i, "] = ", r[i], " is not finite");
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {  // rows orthonormal: R R^T = I
      const double d = double(r[3 * i]) * r[3 * j] + double(r[3 * i + 1]) * r[3 * j + 1] +
                       double(r[3 * i + 2]) * r[3 * j + 2];
      if (std::fabs(d - (i == j ? 1.0 : 0.0)) > 1e-3)
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": rotation is not a rotation (rows ", i, " and ", j,
             " have dot product ", d, "; a rotation's rows are orthonormal)");
    }
  std::copy(r, r + 9, rot_);
  width_ = width;
  height_ = height;
  const size_t pixels = size_t(width) * height;
  rgb_.resize(pixels * 3);
  for (size_t p = 0; p < pixels; ++p)
    for (size_t c = 0; c < 3; ++c) {
      const float v = rgb[p * 3 + c];
      if (!std::isfinite(v) || v < 0.0f || double(v) * strength > kMaxRadiance)
        fail(PLM_ERROR_INVALID_ARGUMENT, owner, ": pixel at row ", p / width, ", column ", p % width, " (row 0 = top) has ",
             "RGB"[c], " = ", v, (std::isfinite(v) && v >= 0.0f ? " (times strength beyond 1e30)" : ""),
             "; radiance must be finite and >= 0");
      rgb_[p * 3 + c] = v * strength;
    }

  // Row boundaries of the dual grid in v (1 at the top), then in z = sin(elevation).
  const uint32_t rows = height + 1;
  row_z_.resize(rows + 1);
  for (uint32_t k = 0; k <= rows; ++k) {
    const double v = k == 0 ? 1.0 : k == rows ? 0.0 : 1.0 - (double(k) - 0.5) / height;
    row_z_[k] = k == 0 ? 1.0f : k == rows ? -1.0f : float(std::sin(kPiD * (v - 0.5)));
  }
  // Cell means: interior rows blend their two pixel rows equally; the half
  // rows at the poles weigh their own pixel row 3/4 and the wrapped one 1/4.
  auto pixel = [&](uint32_t row, uint32_t col) { return &rgb_[(size_t(row) * width + col) * 3]; };
  const size_t cells = size_t(rows) * width;
  std::vector<float> mean(cells * 3);
  for (uint32_t k = 0; k < rows; ++k) {
    uint32_t near_row, far_row;
    double near_w;
    cell_rows(k, height, near_row, far_row, near_w);
    for (uint32_t c = 0; c < width; ++c) {
      const uint32_t c1 = c + 1 == width ? 0 : c + 1;
      for (int ch = 0; ch < 3; ++ch)
        mean[(size_t(k) * width + c) * 3 + size_t(ch)] =
            float(0.5 * (near_w * (double(pixel(near_row, c)[ch]) + pixel(near_row, c1)[ch]) +
                         (1.0 - near_w) * (double(pixel(far_row, c)[ch]) + pixel(far_row, c1)[ch])));
    }
  }
  // The brightest cells that hold 1 % of the sphere's solid angle: where they
  // hold at least kSplitConcentration of the light (a sun), they and the rest
  // get distributions of their own.
  std::vector<uint8_t> bright;
  concentration_ = bright_cells(mean, bright);
  if (concentration_ >= kSplitConcentration) {
    bright_ = std::move(bright);
    build(parts_[1], mean, 1);
    build(parts_[2], mean, 2);
  } else {
    build(parts_[0], mean, 0);
  }
}

bool EnvironmentMap::in_part(int part, size_t cell) const {
  return part == 0 || (bright_[cell] != 0) == (part == 1);
}

void EnvironmentMap::build(Distribution& d, const std::vector<float>& mean, int part) {
  const uint32_t rows = height_ + 1;
  d.row_cdf.assign(rows, 0.0);
  d.row_density.assign(rows, 0.0);
  d.cell_cdf.assign(size_t(rows) * width_, 0.0);
  double integral[3] = {0, 0, 0}, dir[3] = {0, 0, 0};
  std::vector<double> row_weight(rows, 0.0);
  for (uint32_t k = 0; k < rows; ++k) {
    const double omega = 2.0 * kPiD / width_ * (double(row_z_[k]) - double(row_z_[k + 1]));
    const float z = 0.5f * (row_z_[k] + row_z_[k + 1]), rho = std::sqrt(std::fmax(0.0f, 1.0f - z * z));
    double running = 0.0;
    double* cdf = &d.cell_cdf[size_t(k) * width_];
    for (uint32_t c = 0; c < width_; ++c) {
      const size_t cell = size_t(k) * width_ + c;
      if (in_part(part, cell)) {
        const float* m = &mean[cell * 3];
        for (int ch = 0; ch < 3; ++ch) integral[ch] += double(m[ch]) * omega;
        const double w = (double(m[0]) + m[1] + m[2]) / 3.0;
        running += w;
        if (part == 1) {  // the bright part's mean direction (a guess of where its light comes from)
          float sn, cs;
          azimuth_of((float(c) + 1.0f) / float(width_), sn, cs);
          const Vec3 dw = to_world({rho * cs, rho * sn, z});
          dir[0] += w * omega * dw.x, dir[1] += w * omega * dw.y, dir[2] += w * omega * dw.z;
        }
      }
      cdf[c] = running;
    }
    row_weight[k] = running * omega;
    if (running > 0.0)
      for (uint32_t c = 0; c < width_; ++c) cdf[c] /= running;
    cdf[width_ - 1] = running > 0.0 ? 1.0 : 0.0;
  }
  double sum = 0.0;
  for (uint32_t k = 0; k < rows; ++k) sum += row_weight[k];
  d.total = sum;
  double running = 0.0;
  for (uint32_t k = 0; k < rows; ++k) {
    running += row_weight[k];
    d.row_cdf[k] = sum > 0.0 ? running / sum : 0.0;
    const double omega = 2.0 * kPiD / width_ * (double(row_z_[k]) - double(row_z_[k + 1]));
    // A cell's density in solid angle: P(row) P(cell | row) / omega, the second factor from the CDF.
    d.row_density[k] = sum > 0.0 && omega > 0.0 ? (row_weight[k] / sum) / omega : 0.0;
  }
  if (sum > 0.0) d.row_cdf[rows - 1] = 1.0;
  d.integral = {float(integral[0]), float(integral[1]), float(integral[2])};
  const double len = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  if (len > 0.0) d.direction = {float(dir[0] / len), float(dir[1] / len), float(dir[2] / len)};
}

float EnvironmentMap::bright_cells(const std::vector<float>& mean, std::vector<uint8_t>& bright) const {
  // A histogram of the cells' mean radiance (mean of RGB) in eighths of an
  // octave below the brightest, filled from the top until it holds 1 % of the
  // sphere's solid angle; the cells of the bins taken are the bright ones.
  const uint32_t rows = height_ + 1;
  const size_t cells = size_t(rows) * width_;
  bright.assign(cells, 0);
  constexpr int kBins = 8 * 48;
  std::vector<double> omega(kBins, 0.0), weight(kBins, 0.0);
  double top = 0.0, total = 0.0;
  for (size_t cell = 0; cell < cells; ++cell)
    top = std::max(top, (double(mean[cell * 3]) + mean[cell * 3 + 1] + mean[cell * 3 + 2]) / 3.0);
  if (!(top > 0.0)) return 0.0f;
  auto bin_of = [&](double m) { return std::min(kBins - 1, int(std::floor(-8.0 * std::log2(m / top)))); };
  for (uint32_t k = 0; k < rows; ++k) {
    const double cell_omega = 2.0 * kPiD / width_ * (double(row_z_[k]) - double(row_z_[k + 1]));
    for (uint32_t c = 0; c < width_; ++c) {
      const size_t cell = size_t(k) * width_ + c;
      const double m = (double(mean[cell * 3]) + mean[cell * 3 + 1] + mean[cell * 3 + 2]) / 3.0;
      if (!(m > 0.0)) continue;
      omega[size_t(bin_of(m))] += cell_omega;
      weight[size_t(bin_of(m))] += m * cell_omega;
      total += m * cell_omega;
    }
  }
  const double want = 0.01 * 4.0 * kPiD;
  double o = 0.0, w = 0.0;
  int last = -1;  // the last bin wholly within the 1 %
  for (int b = 0; b < kBins && o < want; ++b) {
    if (!(omega[size_t(b)] > 0.0)) continue;
    const double part = std::min(1.0, (want - o) / omega[size_t(b)]);  // a bin of equal cells, in part
    if (part >= 1.0) last = b;
    o += part * omega[size_t(b)];
    w += part * weight[size_t(b)];
  }
  for (size_t cell = 0; cell < cells; ++cell) {
    const double m = (double(mean[cell * 3]) + mean[cell * 3 + 1] + mean[cell * 3 + 2]) / 3.0;
    if (m > 0.0 && bin_of(m) <= last) bright[cell] = 1;
  }
  return float(std::min(1.0, w / total));
}

EnvironmentMap EnvironmentMap::from_file(const std::string& path, const float rotation[9], float strength) {
  const std::string owner = "world map '" + path + "'";
  const ImageFile img = read_image_file(path, "world", "environment map");
  const uint32_t w = img.width, h = img.height, nch = img.channels;
  const bool srgb = img.integer_bits > 0;  // Blender's default colour space for such files
  const size_t pixels = size_t(w) * size_t(h);
  const std::vector<float>& in = img.pixels;
  std::vector<float> rgb(pixels * 3);
  for (size_t p = 0; p < pixels; ++p)
    for (size_t c = 0; c < 3; ++c) {
      const float v = in[p * size_t(nch) + (nch >= 3 ? c : 0)];  // grey (+ alpha): R = G = B
      rgb[p * 3 + c] = srgb ? srgb_to_linear(v) : v;
    }
  return EnvironmentMap(rgb.data(), w, h, rotation, strength, owner);
}

Vec3 EnvironmentMap::to_map(Vec3 w) const {
  const Vec3 d{rot_[0] * w.x + rot_[3] * w.y + rot_[6] * w.z, rot_[1] * w.x + rot_[4] * w.y + rot_[7] * w.z,
               rot_[2] * w.x + rot_[5] * w.y + rot_[8] * w.z};
  return d;
}

Vec3 EnvironmentMap::to_world(Vec3 d) const {
  return {rot_[0] * d.x + rot_[1] * d.y + rot_[2] * d.z, rot_[3] * d.x + rot_[4] * d.y + rot_[5] * d.z,
          rot_[6] * d.x + rot_[7] * d.y + rot_[8] * d.z};
}

Vec3 EnvironmentMap::lookup(float u, float v) const {
  uint32_t x0, x1, y0, y1;
  float fx, fy;
  repeat_axis(u, width_, x0, x1, fx);
  repeat_axis(v, height_, y0, y1, fy);  // y counts from the bottom row, as Cycles' image rows
  const float* r0 = &rgb_[size_t(height_ - 1 - y0) * width_ * 3];
  const float* r1 = &rgb_[size_t(height_ - 1 - y1) * width_ * 3];
  const float w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
  return {w00 * r0[x0 * 3] + w10 * r0[x1 * 3] + w01 * r1[x0 * 3] + w11 * r1[x1 * 3],
          w00 * r0[x0 * 3 + 1] + w10 * r0[x1 * 3 + 1] + w01 * r1[x0 * 3 + 1] + w11 * r1[x1 * 3 + 1],
          w00 * r0[x0 * 3 + 2] + w10 * r0[x1 * 3 + 2] + w01 * r1[x0 * 3 + 2] + w11 * r1[x1 * 3 + 2]};
}

Vec3 EnvironmentMap::radiance(Vec3 w) const {
  const Vec3 d = to_map(w);
  const float len = length(d);
  if (!(len > 0.0f) || !std::isfinite(len)) return {0, 0, 0};
  const float z = std::fmax(-1.0f, std::fmin(1.0f, d.z / len));
  const float u = 0.5f - std::atan2(d.y, d.x) * (0.5f / kPi);
  const float v = 0.5f + std::asin(z) * (1.0f / kPi);
  return lookup(u, v);
}

void EnvironmentMap::corners(uint32_t row, uint32_t column, float g[4]) const {
  const uint32_t c1 = column + 1 == width_ ? 0 : column + 1;
  auto grey = [&](uint32_t r, uint32_t c) {
    const float* p = &rgb_[(size_t(r) * width_ + c) * 3];
    return (p[0] + p[1] + p[2]) * (1.0f / 3.0f);
  };
  if (row > 0 && row < height_) {  // between pixel rows row - 1 (upper) and row
    g[0] = grey(row - 1, column), g[1] = grey(row - 1, c1), g[2] = grey(row, column), g[3] = grey(row, c1);
  } else if (row == 0) {  // the pole's edge: REPEAT blends the top row with the bottom one half and half
    g[2] = grey(0, column), g[3] = grey(0, c1);
    g[0] = 0.5f * (g[2] + grey(height_ - 1, column)), g[1] = 0.5f * (g[3] + grey(height_ - 1, c1));
  } else {
    g[0] = grey(height_ - 1, column), g[1] = grey(height_ - 1, c1);
    g[2] = 0.5f * (g[0] + grey(0, column)), g[3] = 0.5f * (g[1] + grey(0, c1));
  }
}

void EnvironmentMap::cell_of(Vec3 d, uint32_t& row, uint32_t& column, float& s, float& t) const {
  const float len = length(d);
  const float z = std::fmax(-1.0f, std::fmin(1.0f, d.z / len));
  // Row: the boundaries are monotone in z; the first guess from v is exact but for rounding.
  const float v = 0.5f + std::asin(z) * (1.0f / kPi);
  int64_t k = int64_t(std::floor((1.0f - v) * float(height_) + 0.5f));
  k = std::clamp<int64_t>(k, 0, height_);
  while (k > 0 && z > row_z_[size_t(k)]) --k;
  while (k < int64_t(height_) && z < row_z_[size_t(k) + 1]) ++k;
  row = uint32_t(k);
  const float top = row_z_[size_t(k)], bottom = row_z_[size_t(k) + 1];
  t = std::fmin(1.0f, std::fmax(0.0f, (top - z) / (top - bottom)));
  const float u = 0.5f - std::atan2(d.y, d.x) * (0.5f / kPi);
  const float x = u * float(width_) - 0.5f, below = std::floor(x);
  s = x - below;
  int64_t c = int64_t(below) % int64_t(width_);
  if (c < 0) c += width_;
  column = uint32_t(c);
}

float EnvironmentMap::pdf(int part, Vec3 w) const {
  const Distribution& dist = parts_[part];
  const Vec3 d = to_map(w);
  if (!(dist.total > 0.0) || !is_finite(d) || !(dot(d, d) > 0.0f)) return 0.0f;
  uint32_t row, column;
  float s, t, g[4];
  cell_of(d, row, column, s, t);
  const double* cdf = &dist.cell_cdf[size_t(row) * width_];
  const double p = cdf[column] - (column > 0 ? cdf[column - 1] : 0.0);
  if (!(p > 0.0)) return 0.0f;
  corners(row, column, g);
  const float blend = (1 - t) * ((1 - s) * g[0] + s * g[1]) + t * ((1 - s) * g[2] + s * g[3]);
  const float mean = 0.25f * (g[0] + g[1] + g[2] + g[3]);
  return float(dist.row_density[row] * p) * (mean > 0.0f ? blend / mean : 1.0f);
}

Vec3 EnvironmentMap::sample(int part, float u0, float u1, float& pdf) const {
  const Distribution& dist = parts_[part];
  float f0, f1, g[4];
  const size_t rows = size_t(height_) + 1;
  const size_t row = invert_cdf(dist.row_cdf.data(), rows, double(u0), f0);
  const double* cdf = &dist.cell_cdf[row * width_];
  const size_t column = invert_cdf(cdf, width_, double(u1), f1);
  const double p = cdf[column] - (column > 0 ? cdf[column - 1] : 0.0);
  // Inside the cell in proportion to the blend of its corners: t (down the
  // row, in z) from the marginal, then s (along the azimuth) given t.
  corners(uint32_t(row), uint32_t(column), g);
  if (!(g[0] + g[1] + g[2] + g[3] > 0.0f)) g[0] = g[1] = g[2] = g[3] = 1.0f;  // underflow: uniform
  const float t = sample_linear(f0, g[0] + g[1], g[2] + g[3]);
  const float a = (1 - t) * g[0] + t * g[2], b = (1 - t) * g[1] + t * g[3];
  const float s = sample_linear(f1, a, b);
  const float mean = 0.25f * (g[0] + g[1] + g[2] + g[3]);
  pdf = float(dist.row_density[row] * p) * (mean > 0.0f ? ((1 - s) * a + s * b) / mean : 1.0f);
  const float z = row_z_[row] + t * (row_z_[row + 1] - row_z_[row]);
  const float rho = std::sqrt(std::fmax(0.0f, 1.0f - z * z));
  float u = (float(column) + s + 0.5f) / float(width_);  // past 1 for the wrapping column
  if (u >= 1.0f) u -= 1.0f;
  float sn, cs;
  azimuth_of(u, sn, cs);
  return normalize(to_world({rho * cs, rho * sn, z}));
}

Vec3 EnvironmentMap::radiance(int part, Vec3 w) const {
  if (part == 0) return radiance(w);
  const Vec3 d = to_map(w);
  if (!is_finite(d) || !(dot(d, d) > 0.0f)) return {0, 0, 0};
  uint32_t row, column;
  float s, t;
  cell_of(d, row, column, s, t);
  return in_part(part, size_t(row) * width_ + column) ? radiance(w) : Vec3{0, 0, 0};
}

Vec3 EnvironmentMap::irradiance(int part, Vec3 n) const {
  // Per dual-grid cell: its mean radiance (the blend of its corners) x its
  // solid angle x the mean cosine over s x s points of it (s so that the
  // points lie within about a degree on coarse maps).
  const uint32_t sub = std::max(1u, 128u / height_);
  const uint32_t rows = height_ + 1;
  double sum[3] = {0, 0, 0};
  auto pixel = [&](uint32_t row, uint32_t col) { return &rgb_[(size_t(row) * width_ + col) * 3]; };
  for (uint32_t k = 0; k < rows; ++k) {
    uint32_t near_row, far_row;
    double near_w;
    cell_rows(k, height_, near_row, far_row, near_w);
    const double omega = 2.0 * kPiD / width_ * (double(row_z_[k]) - double(row_z_[k + 1]));
    for (uint32_t c = 0; c < width_; ++c) {
      if (!in_part(part, size_t(k) * width_ + c)) continue;
      double cosine = 0.0;
      for (uint32_t i = 0; i < sub; ++i) {
        const float z = row_z_[k] + (float(i) + 0.5f) / float(sub) * (row_z_[k + 1] - row_z_[k]);
        const float rho = std::sqrt(std::fmax(0.0f, 1.0f - z * z));
        for (uint32_t j = 0; j < sub; ++j) {
          float sn, cs;
          azimuth_of((float(c) + 0.5f + (float(j) + 0.5f) / float(sub)) / float(width_), sn, cs);
          cosine += std::fmax(0.0f, dot(to_world({rho * cs, rho * sn, z}), n));
        }
      }
      if (cosine <= 0.0) continue;
      const double weight = cosine / (double(sub) * sub) * omega;
      const uint32_t c1 = c + 1 == width_ ? 0 : c + 1;
      for (int ch = 0; ch < 3; ++ch)
        sum[ch] += weight * 0.5 * (near_w * (double(pixel(near_row, c)[ch]) + pixel(near_row, c1)[ch]) +
                                   (1.0 - near_w) * (double(pixel(far_row, c)[ch]) + pixel(far_row, c1)[ch]));
    }
  }
  return {float(sum[0]), float(sum[1]), float(sum[2])};
}

}  // namespace plm
