#include "ol/orientation_lightmap.h"

#include <algorithm>

#include "ol/area_estimation.h"
#include "util/error.h"

namespace plm::ol {

OrientationLightmap::OrientationLightmap(uint32_t resolution, uint32_t batches)
    : grid_(resolution), batches_(batches) {
  if (batches < 2 || batches > 256)
    fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap batches ", batches, " is out of range: must be 2..256");
  area_.assign(bins(), 0.0);
  area_var_.assign(bins(), 0.0);
  flux_.assign(3 * bins(), 0.0);
  hits_.assign(bins(), 0);
  batch_flux_.assign(bins() * batches_, 0.0);
}

void OrientationLightmap::set_area(const AreaEstimate& estimate) { set_area(estimate.area, estimate.variance); }

void OrientationLightmap::set_area(std::vector<double> area, std::vector<double> variance) {
  if (area.size() != bins() || variance.size() != bins())
    fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap area: ", area.size(), " areas and ", variance.size(),
         " variances for ", bins(), " bins");
  for (size_t b = 0; b < bins(); ++b)
    if (!(area[b] >= 0.0) || !std::isfinite(area[b]) || !(variance[b] >= 0.0) || !std::isfinite(variance[b]))
      fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap area: bin ", b, " has area ", area[b], " and variance ",
           variance[b], ", both must be finite and >= 0");
  area_ = std::move(area);
  area_var_ = std::move(variance);
  radiosity_.clear();
}

void OrientationLightmap::add_area(const OrientationLightmap& child) {
  if (child.resolution() != resolution())
    fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap: cannot add the area of a ", child.resolution(),
         "^2 OL to a ", resolution(), "^2 one");
  for (size_t b = 0; b < bins(); ++b) {
    area_[b] += child.area_[b];
    area_var_[b] += child.area_var_[b];  // children's estimates are independent
  }
  radiosity_.clear();
}

double OrientationLightmap::total_area() const {
  double a = 0.0;
  for (double x : area_) a += x;
  return a;
}

Vec3d OrientationLightmap::unit_normal(Vec3 normal) const {
  const Vec3d d = to_double(normal);
  if (!is_finite(d))
    fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap: normal (", normal.x, ", ", normal.y, ", ", normal.z,
         ") is not finite");
  const double l2 = dot(d, d);
  if (!(l2 > 0.0)) fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap: normal is the zero vector");
  return d * (1.0 / std::sqrt(l2));
}

uint32_t OrientationLightmap::bin_of(Vec3 normal) const { return grid_.bin(unit_normal(normal)); }

void OrientationLightmap::add_hit(Vec3 normal, Vec3 rgb, uint32_t batch) {
  if (batch >= batches_)
    fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap: batch ", batch, " is out of range 0..", batches_ - 1);
  if (!is_finite(rgb)) fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap: hit flux is not finite");
  const uint32_t b = bin_of(normal);
  flux_[3 * size_t(b)] += rgb.x;
  flux_[3 * size_t(b) + 1] += rgb.y;
  flux_[3 * size_t(b) + 2] += rgb.z;
  ++hits_[b];
  batch_flux_[size_t(b) * batches_ + batch] += (double(rgb.x) + rgb.y + rgb.z) / 3.0;
}

void OrientationLightmap::add_splat_hit(const Splat& splat, Vec3 rgb, uint32_t batch) {
  if (batch >= batches_)
    fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap: batch ", batch, " is out of range 0..", batches_ - 1);
  if (!is_finite(rgb)) fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap: hit flux is not finite");
  if (splat.nearest >= bins())
    fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap: bin ", splat.nearest, " is out of range 0..", bins() - 1);
  const double mean = (double(rgb.x) + rgb.y + rgb.z) / 3.0;
  for (int k = 0; k < 4; ++k) {
    const double w = splat.weight[k];
    if (w == 0.0) continue;  // a nearest-bin splat touches one bin only
    const size_t b = splat.bin[k];
    flux_[3 * b] += w * rgb.x;
    flux_[3 * b + 1] += w * rgb.y;
    flux_[3 * b + 2] += w * rgb.z;
    batch_flux_[b * batches_ + batch] += w * mean;
  }
  ++hits_[splat.nearest];
}

OrientationLightmap OrientationLightmap::empty_copy() const {
  OrientationLightmap o(resolution(), batches_);
  o.area_ = area_;
  o.area_var_ = area_var_;
  return o;
}

void OrientationLightmap::merge(const OrientationLightmap& other) {
  if (other.resolution() != resolution() || other.batches_ != batches_)
    fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap merge: ", other.resolution(), "^2 with ", other.batches_,
         " batches into ", resolution(), "^2 with ", batches_);
  for (size_t i = 0; i < flux_.size(); ++i) flux_[i] += other.flux_[i];
  for (size_t i = 0; i < hits_.size(); ++i) hits_[i] += other.hits_[i];
  for (size_t i = 0; i < batch_flux_.size(); ++i) batch_flux_[i] += other.batch_flux_[i];
  radiosity_.clear();
}

// Hits in a bin without area would be lost: the area estimate saw no surface
// with that normal (too rare for its samples, or a normal the geometry only
// nearly has). Their flux goes to the 8 neighbouring bins that have area,
// in proportion to area, or, with no such neighbour, to all bins by area.
void OrientationLightmap::spread_orphans(std::vector<double>& flux, std::vector<double>& batch_flux) {
  const int64_t n = resolution();
  std::vector<double> pool(3 + batches_, 0.0);  // flux with nowhere near to go
  orphan_flux_ = 0.0;
  for (uint32_t b = 0; b < bins(); ++b) {
    if (area_[b] > 0.0 || hits_[b] == 0) continue;
    orphan_flux_ += (flux[3 * b] + flux[3 * b + 1] + flux[3 * b + 2]) / 3.0;
    uint32_t nb[8];
    double w[8], wsum = 0.0;
    int k = 0;
    for (int64_t dj = -1; dj <= 1; ++dj)
      for (int64_t di = -1; di <= 1; ++di) {
        if (di == 0 && dj == 0) continue;
        nb[k] = grid_.wrap(int64_t(b % n) + di, int64_t(b / n) + dj);
        w[k] = area_[nb[k]];
        wsum += w[k++];
      }
    for (int i = 0; i < 8; ++i) {
      const double f = wsum > 0.0 ? w[i] / wsum : 0.0;
      for (int c = 0; c < 3; ++c) flux[3 * nb[i] + c] += f * flux[3 * b + c];
      for (uint32_t t = 0; t < batches_; ++t)
        batch_flux[size_t(nb[i]) * batches_ + t] += f * batch_flux[size_t(b) * batches_ + t];
    }
    if (!(wsum > 0.0)) {
      for (int c = 0; c < 3; ++c) pool[c] += flux[3 * b + c];
      for (uint32_t t = 0; t < batches_; ++t) pool[3 + t] += batch_flux[size_t(b) * batches_ + t];
    }
    for (int c = 0; c < 3; ++c) flux[3 * b + c] = 0.0;
    for (uint32_t t = 0; t < batches_; ++t) batch_flux[size_t(b) * batches_ + t] = 0.0;
  }
  if (pool[0] == 0.0 && pool[1] == 0.0 && pool[2] == 0.0) return;
  const double total = total_area();
  if (!(total > 0.0))
    fail(PLM_ERROR_INVALID_SCENE, "orientation lightmap received photon hits but covers no area (set its area first)");
  for (uint32_t b = 0; b < bins(); ++b) {
    const double f = area_[b] / total;
    for (int c = 0; c < 3; ++c) flux[3 * b + c] += f * pool[c];
    for (uint32_t t = 0; t < batches_; ++t) batch_flux[size_t(b) * batches_ + t] += f * pool[3 + t];
  }
}

void OrientationLightmap::finalize(uint64_t photon_count, uint64_t batch_photons) {
  if (photon_count == 0) fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap finalize: photon_count must be > 0");
  std::vector<double> flux = flux_, batch_flux = batch_flux_;
  spread_orphans(flux, batch_flux);
  radiosity_.assign(3 * bins(), 0.0);
  error_.assign(bins(), 0.0);
  const double photons = double(photon_count);
  // Each group's photons; groups that got none take no part.
  std::vector<double> group(batches_, photons / batches_);
  if (batch_photons > 0) {  // full batches dealt round-robin, then the short one
    const uint64_t full = photon_count / batch_photons, rest = photon_count % batch_photons;
    for (uint32_t t = 0; t < batches_; ++t)
      group[t] = double((full / batches_ + (t < full % batches_ ? 1 : 0)) * batch_photons);
    group[full % batches_] += double(rest);
  }
  const double used = double(std::count_if(group.begin(), group.end(), [](double n) { return n > 0.0; }));
  double sum[3] = {0, 0, 0};
  for (uint32_t b = 0; b < bins(); ++b) {
    for (int c = 0; c < 3; ++c) sum[c] += flux[3 * b + c];
    if (!(area_[b] > 0.0)) continue;
    const double scale = 1.0 / (photons * kPiD * area_[b]);
    for (int c = 0; c < 3; ++c) radiosity_[3 * b + c] = flux[3 * b + c] * scale;
    // Group t's n_t photons hold n_t mu of the mean flux a photon brings, mu,
    // give or take n_t s^2: s^2 = sum_t (f_t - n_t mu)^2 / n_t / (groups - 1),
    // and the bin's mean over all photons varies by s^2 / photons.
    const double* bf = &batch_flux[size_t(b) * batches_];
    double mu = 0.0, sq = 0.0;
    for (uint32_t t = 0; t < batches_; ++t) mu += bf[t];
    mu /= photons;
    for (uint32_t t = 0; t < batches_; ++t)
      if (group[t] > 0.0) sq += (bf[t] - group[t] * mu) * (bf[t] - group[t] * mu) / group[t];
    const double mean = mu * photons * scale;
    const double photon_var = used > 1.0 ? sq / (used - 1.0) * photons * scale * scale : mean * mean;
    const double area_rel_var = area_var_[b] / (area_[b] * area_[b]);
    error_[b] = std::sqrt(photon_var + mean * mean * area_rel_var);
  }
  const double total = total_area();
  for (int c = 0; c < 3; ++c) mean_[c] = total > 0.0 ? float(sum[c] / (photons * kPiD * total)) : 0.0f;
}

Vec3 OrientationLightmap::lookup(Vec3 normal) const {
  if (!finalized()) fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap lookup before finalize");
  const Taps taps = grid_.taps(unit_normal(normal));
  double acc[3] = {0, 0, 0}, wsum = 0.0;
  for (int k = 0; k < 4; ++k) {
    const double w = taps.weight[k];
    const uint32_t b = taps.bin[k];
    if (!(area_[b] > 0.0) || w == 0.0) continue;
    for (int c = 0; c < 3; ++c) acc[c] += w * radiosity_[3 * b + c];
    wsum += w;
  }
  if (!(wsum > 0.0)) return mean_;
  return {float(acc[0] / wsum), float(acc[1] / wsum), float(acc[2] / wsum)};
}

// ---- OlTree ----

uint32_t OlTree::add_node(OrientationLightmap ol, int32_t parent) {
  if (parent < -1 || parent >= int64_t(nodes_.size()))
    fail(PLM_ERROR_INVALID_ARGUMENT, "OL tree: parent ", parent, " does not exist (", nodes_.size(), " nodes)");
  nodes_.push_back(std::move(ol));
  parent_.push_back(parent);
  return uint32_t(nodes_.size() - 1);
}

void OlTree::check_node(uint32_t node) const {
  if (node >= nodes_.size()) fail(PLM_ERROR_INVALID_ARGUMENT, "OL tree: node ", node, " does not exist");
}

void OlTree::sum_areas_from_children() {
  // Parents come before their children, so backwards is leaves first.
  for (size_t i = nodes_.size(); i-- > 0;)
    if (parent_[i] >= 0) nodes_[parent_[i]].add_area(nodes_[i]);
}

void OlTree::add_hit(uint32_t node, Vec3 normal, Vec3 rgb, uint32_t batch) {
  check_node(node);
  for (int32_t i = int32_t(node); i >= 0; i = parent_[i]) nodes_[i].add_hit(normal, rgb, batch);
}

void OlTree::merge(const OlTree& other) {
  if (other.parent_ != parent_) fail(PLM_ERROR_INVALID_ARGUMENT, "OL tree merge: the trees differ in shape");
  for (size_t i = 0; i < nodes_.size(); ++i) nodes_[i].merge(other.nodes_[i]);
}

void OlTree::finalize(uint64_t photon_count, uint64_t batch_photons) {
  for (OrientationLightmap& ol : nodes_) ol.finalize(photon_count, batch_photons);
}

uint32_t OlTree::choose(uint32_t node, Vec3 normal, uint64_t min_hits) const {
  check_node(node);
  uint32_t i = node;
  while (parent_[i] >= 0 && nodes_[i].hits(nodes_[i].bin_of(normal)) < min_hits) i = uint32_t(parent_[i]);
  return i;
}

}  // namespace plm::ol
