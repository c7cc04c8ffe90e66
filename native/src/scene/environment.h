// An environment map as the world (Cycles' Environment Texture in the world's
// Background): an equirectangular image of radiance, looked up as Cycles looks
// it up, and a distribution over directions in proportion to it for the
// direct pass's sky samples and for photon emission.
//
// Lookup: Blender's equirectangular mapping of a map-frame direction d,
// u = 0.5 - atan2(d.y, d.x) / (2 pi), v = 0.5 + asin(d.z) / pi, read bilinearly
// with pixel centres at ((i + 0.5) / W, (j + 0.5) / H) and periodic wrapping in
// both axes: Cycles' Linear interpolation with the REPEAT extension that its
// Environment Texture always uses (so within half a row of a pole the top and
// bottom rows blend, as in Cycles).
//
// Sampling: the sphere is cut into the cells of the dual grid, whose corners
// are pixel centres (W columns between neighbouring centres, wrapping; H - 1
// rows between neighbouring rows' centres plus a half row at each pole, whose
// pole edge holds the blend REPEAT gives there), so that inside a cell the
// radiance blends exactly its four corner values. A cell's weight is the mean
// of its corners (mean of RGB) times its solid angle; a cell is chosen by a
// marginal distribution over rows and a conditional one within the row
// (pbrt's Distribution2D), and a direction inside it in proportion to the
// bilinear blend of its corners over (azimuth, z = sin(elevation)), which is
// uniform in solid angle up to that blend. So the density follows the lookup
// inside each cell too (a one-pixel sun is sampled in proportion to its
// bilinear footprint: L / pdf stays nearly constant over it), is positive
// wherever the looked-up radiance is, and is exactly 1 / (4 pi) for a
// uniform map. A map with a sun is split into the sun's cells and the rest,
// each with a distribution of its own (see split()).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "util/math.h"

namespace plm {

class EnvironmentMap {
 public:
  // rgb: width x height linear RGB floats, the top row (+Z) first; rotation:
  // row-major 3x3 taking map-frame directions into the world (NULL: identity);
  // radiance = pixel x strength. Throws plm::Error (PLM_ERROR_INVALID_ARGUMENT)
  // naming `owner` and the row and column of a bad pixel, bad sizes, a
  // rotation that is not orthonormal or a bad strength.
  EnvironmentMap(const float* rgb, uint32_t width, uint32_t height, const float rotation[9], float strength,
                 const std::string& owner);

  // Reads an image file (util/image_file.h: EXR, HDR, PNG, ...; integer images are
  // sRGB-decoded, float images linear; grey images give R = G = B). Throws
  // plm::Error (PLM_ERROR_IO) naming the file when it cannot be read, and as
  // the constructor for bad pixels.
  static EnvironmentMap from_file(const std::string& path, const float rotation[9], float strength);

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }

  // A map whose brightest 1 % of directions hold at least kSplitConcentration
  // of its light (a sun) is split in two parts, each with a distribution of its
  // own: 1, those bright cells; 2, the rest. The engine treats them as two
  // lights, so every direct-light sample aims at the sun, as at a sun lamp,
  // and the sky gets its own. Otherwise the map is one part, 0.
  static constexpr float kSplitConcentration = 0.25f;
  bool split() const { return !bright_.empty(); }

  // Radiance arriving from world direction w (unit: looking towards w): all of
  // it, or (part 1, 2) only where w's dual-grid cell belongs to the part.
  Vec3 radiance(Vec3 w) const;
  Vec3 radiance(int part, Vec3 w) const;
  // A world direction drawn with part `part`'s distribution from two uniform
  // numbers in [0, 1), and its density in solid angle (> 0).
  Vec3 sample(int part, float u0, float u1, float& pdf) const;
  // The density of sample(part) at world direction w (unit).
  float pdf(int part, Vec3 w) const;
  // Integral of the part's radiance over the sphere (RGB): a uniform map of
  // radiance L gives 4 pi L.
  Vec3 integral(int part) const { return parts_[part].integral; }
  Vec3 integral() const { return split() ? parts_[1].integral + parts_[2].integral : parts_[0].integral; }
  // Integral of the part's radiance x max(0, w . n) over the sphere: the
  // irradiance on an unoccluded surface facing n (the light a window facing n
  // lets in, per m^2).
  Vec3 irradiance(int part, Vec3 n) const;
  // The bright part's mean direction (world), weighted by its light.
  Vec3 bright_direction() const { return parts_[1].direction; }
  // The share of the map's light (mean of RGB x solid angle) in its brightest
  // 1 % of directions: about 0.01 for an even sky, near 1 where a sun holds
  // most of it.
  float concentration() const { return concentration_; }

 private:
  struct Distribution {
    std::vector<double> row_cdf;      // height + 1: cumulative row weights, last = 1
    std::vector<double> row_density;  // height + 1: P(row) / (solid angle of one of its cells)
    // (height + 1) x width: cumulative cell weights (mean of RGB of the blend
    // over the cell, 0 outside the part) within each row, last = 1 (all 0 in a
    // black row). A cell's probability is taken from these differences, so
    // sampling and pdf() agree to the last bit.
    std::vector<double> cell_cdf;
    double total = 0.0;  // sum of mean x solid angle over the part's cells
    Vec3 integral, direction;
  };

  Vec3 to_map(Vec3 w) const;
  Vec3 to_world(Vec3 d) const;
  Vec3 lookup(float u, float v) const;  // bilinear, REPEAT
  // The dual-grid cell of map direction d and d's place (s, t) in it (s
  // along the azimuth from column centre c, t from the row's upper edge).
  void cell_of(Vec3 d, uint32_t& row, uint32_t& column, float& s, float& t) const;
  // Mean of RGB at cell (row, column)'s corners: g[0] upper edge at column c,
  // g[1] upper at c + 1, g[2] lower at c, g[3] lower at c + 1.
  void corners(uint32_t row, uint32_t column, float g[4]) const;
  // Marks the brightest cells holding 1 % of the solid angle; returns their share of the light.
  float bright_cells(const std::vector<float>& mean, std::vector<uint8_t>& bright) const;
  bool in_part(int part, size_t cell) const;
  void build(Distribution& d, const std::vector<float>& mean, int part);

  uint32_t width_ = 0, height_ = 0;
  std::vector<float> rgb_;        // width x height x 3, top row first, times strength
  float rot_[9];                  // map -> world, row-major
  // Dual grid: (height + 1) rows from the top (+Z) of width cells each.
  std::vector<float> row_z_;      // height + 2 boundaries in z = sin(elevation), from +1 down to -1
  std::vector<uint8_t> bright_;   // per cell: 1 in the bright part (empty: not split)
  Distribution parts_[3];         // 0: the whole map (not split); 1, 2: bright, rest (split)
  float concentration_ = 0.0f;
};

}  // namespace plm
