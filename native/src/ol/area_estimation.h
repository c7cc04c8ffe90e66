// Stochastic area estimation ([Thesis §6.3]): an OL bin needs the area of the
// covered surface whose normal falls in it. Summing exact areas of every
// primitive of a complex object is what OLs avoid; instead, points are drawn
// in the (u, v) domains of the object's parts and each point adds the area
// element |dP/du x dP/dv| times the sampled domain measure to the bin of its
// normal. The estimate is unbiased for each bin and for the total.
//
// Compound objects (6.3.2): s samples are spread over the m parts in
// proportion to each part's parameter-domain measure; s may be far below m
// (a tree's 10^5 leaves are alike: each sample picks a part at random).
// [Thesis §8.2] used 20000 samples per OL.
//
// Parts are a closed set dispatched on a tag (triangle, sphere, torus) plus a
// custom kind for faces defined elsewhere (CSG primitives): a function
// (u, v) -> point and tangents, and an optional keep(point) predicate for
// trimmed faces (a discarded sample adds nothing but still counts).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "ol/octahedral.h"

namespace plm::ol {

enum class PatchKind : uint8_t { kTriangle, kSphere, kTorus, kCustom };

// A point of a parametric surface and its tangents wrt the patch's own
// parameters; dP/du x dP/dv must point out of the surface (it gives the normal).
struct SurfacePoint {
  Vec3d p, dpdu, dpdv;
};
using SurfaceEval = std::function<void(double u, double v, SurfacePoint& out)>;
using SurfaceKeep = std::function<bool(Vec3d p)>;

struct Patch {
  PatchKind kind = PatchKind::kTriangle;
  Vec3d p0, p1, p2;          // triangle corners (counter-clockwise seen from outside); sphere: p0 = centre
  double radius = 0.0;       // sphere radius; torus: major radius R (ring centre to tube centre)
  double minor_radius = 0.0; // torus: tube radius r
  Affine3d to_world = Affine3d::identity();  // torus: object to world (any affine map; areas follow it)
  double u0 = 0, u1 = 1, v0 = 0, v1 = 1;  // custom: parameter rectangle
  SurfaceEval eval;          // custom
  SurfaceKeep keep;          // optional for every kind: false = point trimmed away

  // Triangle: P(a, b) = p0 + a (p1 - p0) + b (p2 - p0), a, b >= 0, a + b <= 1.
  static Patch triangle(Vec3d a, Vec3d b, Vec3d c);
  // Sphere: P(theta, phi) = c + r (sin t cos p, sin t sin p, cos t), t in [0, pi], p in [0, 2 pi].
  static Patch sphere(Vec3d centre, double radius);
  // Torus around its z axis: P(phi, psi) = ((R + r cos psi) cos phi, (R + r cos psi) sin phi,
  // r sin psi), both angles in [0, 2 pi], then to_world.
  static Patch torus(double major, double minor, const Affine3d& to_world = Affine3d::identity());
  static Patch custom(double u0, double u1, double v0, double v1, SurfaceEval eval, SurfaceKeep keep = {});

  // Measure of the parameter domain (1/2 for triangles, 2 pi^2 spheres, 4 pi^2 tori).
  double domain_measure() const;
  // The surface at (s, t) uniform in [0,1)^2, mapped uniformly onto the domain.
  void evaluate(double s, double t, SurfacePoint& out) const;
};

struct AreaSettings {
  uint64_t samples = 20000;    // over all sampled parts together
  uint64_t seed = 1;
  bool exact_triangles = true; // untrimmed triangles: exact area, one normal, no sampling
};

struct AreaEstimate {
  std::vector<double> area;      // per bin (m^2)
  std::vector<double> variance;  // per bin: variance of the estimate (m^4), 0 where exact
  double total = 0.0, total_variance = 0.0;
  uint64_t samples = 0;          // samples drawn (0 when every part was exact)
  double error(uint32_t bin) const { return std::sqrt(variance[bin]); }
  double total_error() const { return std::sqrt(total_variance); }
};

// Deterministic for a given seed and independent of the thread count: sample k
// draws from the stream (seed, k), and sums are reduced over a fixed split.
// Throws plm::Error for no parts, bad parts, or samples == 0 with parts to sample.
AreaEstimate estimate_area(const OctGrid& grid, const std::vector<Patch>& parts, const AreaSettings& settings = {});

}  // namespace plm::ol
