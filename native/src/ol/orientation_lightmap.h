// Orientation lightmaps (OL, [Thesis §6.2]): one lightmap over the sphere of
// surface normals covers a group of geometry (an object, a part of one, a
// whole collection). Photons still hit and bounce off the real geometry; only
// where a hit is stored changes: bin b of the OL sums the flux of all hits
// whose surface normal falls in b, and divides it by the area of the covered
// surface whose normal falls in b (from area_estimation.h). Every point with
// the same normal then shows the same lighting. Energy is neither lost nor
// made: sum over bins of radiosity * pi * area = flux / photon count.
//
// Triangles of known normal (the meshes of an OL group,
// transport/output/ol_film.h) are splatted instead (add_splat_hit):
// a triangle's area and each hit on it go to the four bins lookup() reads at
// its normal, with lookup's weights (Splat). Then sum over triangles of
// area * lookup(normal) is the flux the OL received / (pi * photon count)
// exactly, and a uniform field stays uniform. With each triangle in its
// nearest bin alone, a lookup between bins of unequal area (a coarse mesh's
// differ by 1.6x) does not give back the light the bins received: a 32 x 16
// UV sphere in a 16 x 16 OL under a tilted sun reads 2.3 % too bright that
// way, whatever the photon count (ol_bake_test). Hits by normal (add_hit:
// L-system OLs, OlTree) and estimated areas stay in the nearest bin.
//
// Values are irradiance / pi, like every texel of the engine
// (docs/design/texels.md, "Irradiance / pi, as a Cycles DIFFUSE bake").
#pragma once

#include <cstdint>
#include <vector>

#include "ol/octahedral.h"
#include "util/math.h"

namespace plm::ol {

struct AreaEstimate;

// Where the hits and area of a triangle with a given unit normal go: the taps
// of lookup() at that normal (OctGrid::taps, weights rounded to float: area
// and hits share them, so the rounding cancels in their ratio) and the
// nearest bin, which counts the hits (hits(), OlTree::choose). 36 bytes.
struct Splat {
  uint32_t nearest;
  uint32_t bin[4];
  float weight[4];

  // The taps at a unit normal.
  static Splat bilinear(const OctGrid& grid, Vec3d normal) {
    const Taps t = grid.taps(normal);
    return {grid.bin(normal),
            {t.bin[0], t.bin[1], t.bin[2], t.bin[3]},
            {float(t.weight[0]), float(t.weight[1]), float(t.weight[2]), float(t.weight[3])}};
  }
  // All weight on one bin, for areas that are known per bin only (estimates).
  static Splat nearest_only(uint32_t bin) { return {bin, {bin, bin, bin, bin}, {1.0f, 0.0f, 0.0f, 0.0f}}; }
  // Adds `value` (an area) to per-bin sums with the weights.
  void add_to(std::vector<double>& bins, double value) const {
    for (int k = 0; k < 4; ++k) bins[bin[k]] += double(weight[k]) * value;
  }
};

class OrientationLightmap {
 public:
  // batches: independent photon groups (2..256) whose spread gives the error.
  explicit OrientationLightmap(uint32_t resolution, uint32_t batches = 16);

  const OctGrid& grid() const { return grid_; }
  uint32_t resolution() const { return grid_.resolution(); }
  size_t bins() const { return grid_.bins(); }
  uint32_t batches() const { return batches_; }

  // Covered area per bin (m^2) and the variance of that estimate (m^4): the
  // area each bin's flux is divided by, nearest-bin (an estimate) or
  // splatted (Splat::add_to), as the hits are.
  void set_area(const AreaEstimate& estimate);
  void set_area(std::vector<double> area, std::vector<double> variance);
  // Adds another OL's area: a parent covering the union of its children.
  void add_area(const OrientationLightmap& child);

  // A photon hit with surface normal `normal` (any length > 0) and flux `rgb`
  // (flux / pick probability, divided by the photon count in finalize), from
  // photon batch `batch`. No allocation; not thread-safe: give each thread an
  // empty copy (empty_copy) and merge them once, in a fixed order.
  void add_hit(Vec3 normal, Vec3 rgb, uint32_t batch);
  // A hit on a triangle whose area was splatted with `splat`: its flux goes
  // to the taps by weight, the hit is counted in the nearest bin.
  void add_splat_hit(const Splat& splat, Vec3 rgb, uint32_t batch);
  // Bin of a surface normal; throws plm::Error for zero or non-finite normals.
  uint32_t bin_of(Vec3 normal) const;
  // Same grid, batches and area; no hits.
  OrientationLightmap empty_copy() const;
  void merge(const OrientationLightmap& other);

  // Radiosity (irradiance / pi) and its standard error per bin. photon_count
  // photons were traced, in `batches` groups: of equal size, or with
  // batch_photons > 0 dealt out in batches of that many photons (the last one
  // short), batch b to group b % batches, as the bake deals them. Hits that landed
  // in bins without area (the estimate found no surface with that normal)
  // are moved to the neighbouring bins with area, area-weighted, or to the
  // whole OL if none has area, so no energy is lost (orphan_flux counts it).
  void finalize(uint64_t photon_count, uint64_t batch_photons = 0);
  bool finalized() const { return !radiosity_.empty(); }

  // Bilinear interpolation of the bins' radiosity at a normal, across the
  // octahedral fold. Bins without area have no value: their taps are
  // dropped and the other taps' weights renormalised; if all four taps lack
  // area, the OL's mean radiosity (total flux / total area) is returned.
  // The result is continuous on the whole sphere, but the map itself is only
  // continuous (not smooth) along its axes, the diamond's edges and the fold,
  // so there a smooth field is interpolated to first order in the bin size
  // (a field of slope ~0.6: max error 0.095 at 12^2 bins, RMS 0.017),
  // elsewhere to second order.
  Vec3 lookup(Vec3 normal) const;

  // Per bin: the area set (set_area), the hits whose nearest bin it is, and
  // the flux it received (splatted hits: their share).
  double area(uint32_t b) const { return area_[b]; }
  double area_variance(uint32_t b) const { return area_var_[b]; }
  uint64_t hits(uint32_t b) const { return hits_[b]; }
  Vec3 flux(uint32_t b) const { return {float(flux_[3 * b]), float(flux_[3 * b + 1]), float(flux_[3 * b + 2])}; }
  // After finalize: radiosity (irradiance / pi) per channel, and the standard
  // error of its channel mean, from the spread of the batches combined with
  // the area estimate's own error (relative errors added in quadrature).
  double radiosity(uint32_t b, int channel) const { return radiosity_[3 * b + channel]; }
  double radiosity_error(uint32_t b) const { return error_[b]; }
  Vec3 mean_radiosity() const { return mean_; }
  double orphan_flux() const { return orphan_flux_; }
  double total_area() const;

 private:
  Vec3d unit_normal(Vec3 normal) const;
  void spread_orphans(std::vector<double>& flux, std::vector<double>& batch_flux);

  OctGrid grid_;
  uint32_t batches_;
  std::vector<double> area_, area_var_;
  std::vector<double> flux_;        // 3 per bin: sum of hit flux (not divided by the photon count)
  std::vector<uint64_t> hits_;
  std::vector<double> batch_flux_;  // bins x batches: channel mean of the flux per batch
  // finalize's output
  std::vector<double> radiosity_;   // 3 per bin
  std::vector<double> error_;
  Vec3 mean_;
  double orphan_flux_ = 0.0;
};

// A hierarchy of OLs ([Thesis fig. 6.3]): a node covers the union of its
// children's geometry. A hit on geometry of a node is stored in that node and
// all its ancestors; a lookup uses the lowest level whose bin for the normal
// has at least min_hits hits, so detail shows where photons suffice and the
// coarser parent steps in where they do not.
class OlTree {
 public:
  // Returns the node's index; parent -1 for a root. Parents come first.
  uint32_t add_node(OrientationLightmap ol, int32_t parent);
  size_t size() const { return nodes_.size(); }
  OrientationLightmap& node(uint32_t i) { return nodes_[i]; }
  const OrientationLightmap& node(uint32_t i) const { return nodes_[i]; }
  int32_t parent(uint32_t i) const { return parent_[i]; }

  // Adds each node's area to its parent's, leaves first: call once after the
  // leaves' areas are set, when parents cover exactly their children.
  void sum_areas_from_children();
  void add_hit(uint32_t node, Vec3 normal, Vec3 rgb, uint32_t batch);
  void merge(const OlTree& other);
  void finalize(uint64_t photon_count, uint64_t batch_photons = 0);

  // The node used at `normal` for geometry of `node`: the first one on the
  // path to the root whose bin holds >= min_hits hits, else the root.
  uint32_t choose(uint32_t node, Vec3 normal, uint64_t min_hits) const;
  Vec3 lookup(uint32_t node, Vec3 normal, uint64_t min_hits) const {
    return nodes_[choose(node, normal, min_hits)].lookup(normal);
  }

 private:
  void check_node(uint32_t node) const;

  std::vector<OrientationLightmap> nodes_;
  std::vector<int32_t> parent_;
};

}  // namespace plm::ol
