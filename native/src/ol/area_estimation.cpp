#include "ol/area_estimation.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>

#include "util/error.h"
#include "util/rng.h"

namespace plm::ol {

Patch Patch::triangle(Vec3d a, Vec3d b, Vec3d c) {
  Patch p;
  p.kind = PatchKind::kTriangle;
  p.p0 = a, p.p1 = b, p.p2 = c;
  return p;
}

Patch Patch::sphere(Vec3d centre, double radius) {
  Patch p;
  p.kind = PatchKind::kSphere;
  p.p0 = centre;
  p.radius = radius;
  return p;
}

Patch Patch::torus(double major, double minor, const Affine3d& to_world) {
  Patch p;
  p.kind = PatchKind::kTorus;
  p.radius = major;
  p.minor_radius = minor;
  p.to_world = to_world;
  return p;
}

Patch Patch::custom(double u0, double u1, double v0, double v1, SurfaceEval eval, SurfaceKeep keep) {
  Patch p;
  p.kind = PatchKind::kCustom;
  p.u0 = u0;
  p.u1 = u1;
  p.v0 = v0;
  p.v1 = v1;
  p.eval = std::move(eval);
  p.keep = std::move(keep);
  return p;
}

double Patch::domain_measure() const {
  switch (kind) {
    case PatchKind::kTriangle: return 0.5;
    case PatchKind::kSphere: return 2.0 * kPiD * kPiD;
    case PatchKind::kTorus: return 4.0 * kPiD * kPiD;
    case PatchKind::kCustom: return (u1 - u0) * (v1 - v0);
  }
  return 0.0;
}

void Patch::evaluate(double s, double t, SurfacePoint& out) const {
  switch (kind) {
    case PatchKind::kTriangle: {
      if (s + t > 1.0) {  // fold the square's upper half onto the triangle: still uniform
        s = 1.0 - s;
        t = 1.0 - t;
      }
      out.dpdu = p1 - p0;
      out.dpdv = p2 - p0;
      out.p = p0 + out.dpdu * s + out.dpdv * t;
      return;
    }
    case PatchKind::kSphere: {
      const double th = kPiD * s, ph = 2.0 * kPiD * t;
      const double st = std::sin(th), ct = std::cos(th), sp = std::sin(ph), cp = std::cos(ph);
      out.p = p0 + Vec3d{st * cp, st * sp, ct} * radius;
      out.dpdu = Vec3d{ct * cp, ct * sp, -st} * radius;
      out.dpdv = Vec3d{-st * sp, st * cp, 0.0} * radius;
      return;
    }
    case PatchKind::kTorus: {
      const double ph = 2.0 * kPiD * s, ps = 2.0 * kPiD * t;
      const double sf = std::sin(ph), cf = std::cos(ph), sq = std::sin(ps), cq = std::cos(ps);
      const double ring = radius + minor_radius * cq;
      out.p = to_world.point({ring * cf, ring * sf, minor_radius * sq});
      out.dpdu = to_world.vector({-ring * sf, ring * cf, 0.0});
      out.dpdv = to_world.vector(Vec3d{-sq * cf, -sq * sf, cq} * minor_radius);
      return;
    }
    case PatchKind::kCustom:
      eval(u0 + (u1 - u0) * s, v0 + (v1 - v0) * t, out);
      return;
  }
}

namespace {

void check_patch(const Patch& p, size_t i) {
  const auto bad = [&](const char* what) { fail(PLM_ERROR_INVALID_ARGUMENT, "area estimation: part ", i, ": ", what); };
  switch (p.kind) {
    case PatchKind::kTriangle:
      if (!is_finite(p.p0) || !is_finite(p.p1) || !is_finite(p.p2)) bad("triangle corner is not finite");
      break;
    case PatchKind::kSphere:
      if (!is_finite(p.p0) || !(p.radius > 0.0) || !std::isfinite(p.radius))
        bad("sphere needs a finite centre and a finite radius > 0");
      break;
    case PatchKind::kTorus:
      if (!(p.radius > 0.0) || !(p.minor_radius > 0.0) || !std::isfinite(p.radius) || !std::isfinite(p.minor_radius))
        bad("torus needs finite radii > 0");
      for (double m : p.to_world.m)
        if (!std::isfinite(m)) bad("torus transform is not finite");
      break;
    case PatchKind::kCustom:
      if (!p.eval) bad("custom patch has no eval function");
      if (!(p.u1 > p.u0) || !(p.v1 > p.v0) || !std::isfinite(p.u1 - p.u0) || !std::isfinite(p.v1 - p.v0))
        bad("custom patch needs a finite parameter rectangle with u1 > u0 and v1 > v0");
      break;
  }
}

// Uniform double in [0, 1) with 53 random bits (a float's 24 bits would
// bias the choice among millions of parts).
double next_double(Rng& rng) {
  const uint64_t hi = rng.next_u32() >> 5, lo = rng.next_u32() >> 6;
  return double((hi << 26) | lo) * (1.0 / 9007199254740992.0);
}

struct Sampler {
  const OctGrid& grid;
  const std::vector<const Patch*>& parts;
  const std::vector<double>& cdf;  // running sum of domain measures, cdf.back() = total
  uint64_t samples, seed, blocks;

  uint64_t block_begin(uint64_t b) const { return samples / blocks * b + std::min(b, samples % blocks); }
};

// Per-bin sums of the sample contributions and their squares over a range of
// blocks; tbb::parallel_deterministic_reduce splits and joins these the same
// way whatever the thread count.
class SampleSums {
  const Sampler& s_;

 public:
  explicit SampleSums(const Sampler& s) : s_(s), sum(s.grid.bins(), 0.0), sum_sq(s.grid.bins(), 0.0) {}
  SampleSums(SampleSums& other, tbb::split) : SampleSums(other.s_) {}

  void operator()(const tbb::blocked_range<uint64_t>& r) {
    for (uint64_t k = s_.block_begin(r.begin()); k < s_.block_begin(r.end()); ++k) sample(k);
  }
  void join(const SampleSums& o) {
    for (size_t b = 0; b < sum.size(); ++b) {
      sum[b] += o.sum[b];
      sum_sq[b] += o.sum_sq[b];
    }
    total += o.total;
    total_sq += o.total_sq;
  }

  std::vector<double> sum, sum_sq;
  double total = 0.0, total_sq = 0.0;

 private:
  void sample(uint64_t k) {
    Rng rng(s_.seed, k);
    const double measure = s_.cdf.back();
    const double pick = next_double(rng) * measure;
    const size_t i = std::min<size_t>(std::upper_bound(s_.cdf.begin(), s_.cdf.end(), pick) - s_.cdf.begin(),
                                       s_.parts.size() - 1);
    const Patch& part = *s_.parts[i];
    SurfacePoint sp;
    part.evaluate(next_double(rng), next_double(rng), sp);
    const Vec3d n = cross(sp.dpdu, sp.dpdv);
    const double len = length(n);
    // A pole of the parametrisation (zero area element) or a trimmed point
    // adds nothing; the sample still counts in the mean.
    if (!(len > 0.0) || !std::isfinite(len) || (part.keep && !part.keep(sp.p))) return;
    // Part i was picked with probability measure_i / measure and its point
    // has density 1 / measure_i: the area element over the density is len * measure.
    const double x = len * measure;
    const uint32_t b = s_.grid.bin(n * (1.0 / len));
    sum[b] += x;
    sum_sq[b] += x * x;
    total += x;
    total_sq += x * x;
  }
};

// Variance of a mean of n samples from their sum and sum of squares.
double variance_of_mean(double sum, double sum_sq, uint64_t n) {
  if (n < 2) return 0.0;
  const double mean = sum / double(n);
  return std::fmax(0.0, (sum_sq / double(n) - mean * mean) / double(n - 1));
}

}  // namespace

AreaEstimate estimate_area(const OctGrid& grid, const std::vector<Patch>& parts, const AreaSettings& settings) {
  if (parts.empty()) fail(PLM_ERROR_INVALID_ARGUMENT, "area estimation: no parts to estimate");
  AreaEstimate est;
  est.area.assign(grid.bins(), 0.0);
  est.variance.assign(grid.bins(), 0.0);
  std::vector<const Patch*> sampled;
  std::vector<double> cdf;
  double measure = 0.0;
  for (size_t i = 0; i < parts.size(); ++i) {
    const Patch& p = parts[i];
    check_patch(p, i);
    if (settings.exact_triangles && p.kind == PatchKind::kTriangle && !p.keep) {
      const Vec3d n = cross(p.p1 - p.p0, p.p2 - p.p0);
      const double len = length(n);
      if (len > 0.0) est.area[grid.bin(n * (1.0 / len))] += 0.5 * len;
      continue;
    }
    measure += p.domain_measure();
    sampled.push_back(&p);
    cdf.push_back(measure);
  }
  for (double a : est.area) est.total += a;
  if (sampled.empty()) return est;
  if (settings.samples == 0)
    fail(PLM_ERROR_INVALID_ARGUMENT, "area estimation: samples must be > 0 (", sampled.size(), " parts to sample)");

  // A fixed number of blocks (not of threads) bounds the per-body bin arrays.
  const uint64_t blocks = std::clamp<uint64_t>(settings.samples / 4096, 1, 32);
  const Sampler sampler{grid, sampled, cdf, settings.samples, settings.seed, blocks};
  SampleSums sums(sampler);
  tbb::parallel_deterministic_reduce(tbb::blocked_range<uint64_t>(0, blocks, 1), sums);

  const uint64_t n = settings.samples;
  for (size_t b = 0; b < est.area.size(); ++b) {
    est.area[b] += sums.sum[b] / double(n);
    est.variance[b] = variance_of_mean(sums.sum[b], sums.sum_sq[b], n);
  }
  est.total += sums.total / double(n);
  est.total_variance = variance_of_mean(sums.total, sums.total_sq, n);
  est.samples = n;
  return est;
}

}  // namespace plm::ol
