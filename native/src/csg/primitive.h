// Analytic CSG primitives: a canonical solid in local space plus an affine
// local->world map. The canonical shapes are Blender's add-primitive operators
// at their default size, so an exporter sends the object matrix and the solid
// follows ([Thesis §4.1]: transforms are pushed down into the leaves, and a ray
// is mapped into primitive space once).
//
//   Sphere      radius 1 at the origin                 faces: 0 surface
//   Box         [-1,1]^3                               faces: 0..5 = -X,+X,-Y,+Y,-Z,+Z
//   Cylinder    radius 1, z in [-1,1]                  faces: 0 side, 1 bottom (z=-1), 2 top (z=+1)
//   Cone        base radius 1 at z=-1, apex at z=+1    faces: 0 side, 1 base (z=-1)
//   Torus       major radius R, minor r, axis z        faces: 0 surface
//   Paraboloid  z >= x^2+y^2, z <= 1                   faces: 0 bowl, 1 cap (z=1)
//   HalfSpace   z <= 0, unbounded                      faces: 0 the plane z=0
//
// Everything is computed in double precision in local space. The local ray
// direction is not normalised, so a ray parameter t is the same in world and
// local space.
#pragma once

#include <cstdint>
#include <string>

#include "util/math.h"
#include "util/rng.h"

namespace plm::csg {

enum class Shape : uint8_t { Sphere, Box, Cylinder, Cone, Torus, Paraboloid, HalfSpace };

constexpr int kMaxFaces = 6;
// A primitive meets a line in at most this many crossings (the torus: 2 intervals).
constexpr int kMaxPrimitiveCrossings = 4;

// Tolerances, relative to a primitive's (or CSG object's) size and, for double
// rounding, to the distance from the world origin. Features thinner than
// kRelativeTolerance * size are treated as zero thickness.
constexpr double kRelativeTolerance = 1e-7;
constexpr double kRoundingTolerance = 4e-15;

// One end of a hit interval: the ray crosses face `face` of primitive `prim`
// at t. Crossing lists alternate entry, exit, entry... starting outside.
struct Crossing {
  double t;
  int32_t prim;  // index in the CSG object (0 for a lone primitive)
  uint8_t face;
  uint8_t flip;  // 1: the solid's outward normal is minus the primitive's (subtracted primitive)
};

struct PrimitiveDesc {
  Shape shape = Shape::Sphere;
  double to_world[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};  // row-major 3x4
  double major_radius = 1.0, minor_radius = 0.25;             // torus only
};

struct Primitive {
  Shape shape;
  double major, minor;        // torus radii
  Affine3d to_world, to_local;
  Vec3d lo, hi;               // world bounds; +-inf on the unbounded axes of a half-space
  double size;                // world length scale: longest mapped local semi-axis
  double stretch;             // bound on how much to_local lengthens a vector (||M^-1||_F)
  bool similarity;            // rotation * uniform scale (+ translation): closed-form areas
  double area[kMaxFaces];     // world area per face (inf for the half-space plane)
  double area_weight_max;     // bound on the world/local area ratio, for rejection sampling
};

int face_count(Shape shape);
// The point of Box face `face` (at -1 or +1 on axis face / 2) at (s, t) in
// [0, 1]^2, s and t along the next two axes in cyclic order.
inline Vec3d box_face_point(int face, double s, double t) {
  const int a = face / 2;
  Vec3d q;
  q[a] = (face & 1) ? 1.0 : -1.0;
  q[(a + 1) % 3] = 2 * s - 1;
  q[(a + 2) % 3] = 2 * t - 1;
  return q;
}
const char* shape_name(Shape shape);

// "" if desc describes a valid primitive, otherwise what is wrong with it.
std::string check_primitive(const PrimitiveDesc& desc);
// Throws plm::Error (PLM_ERROR_INVALID_ARGUMENT) with check_primitive's message.
Primitive make_primitive(const PrimitiveDesc& desc);
// make_primitive without the check and without the face areas (left NaN; they
// are integrated numerically and cost most of the time): for primitives made
// again and again from descriptions already checked, whose areas nobody
// reads (an L-system graph's cached expansions).
Primitive make_primitive_without_areas(const PrimitiveDesc& desc);

// World-space t tolerance for a ray from o with direction d near prim.
double ray_tolerance(const Primitive& prim, Vec3d o, Vec3d d);

// All hit intervals of the whole line o + t d (t over all reals), as
// alternating entry/exit crossings sorted by t; returns their number (even,
// at most kMaxPrimitiveCrossings). Ends may be +-inf (half-space). Intervals
// no longer than eps_t are dropped, gaps no longer than eps_t closed.
// Crossings get prim = 0 and flip = 0.
int intersect(const Primitive& prim, Vec3d o, Vec3d d, double eps_t, Crossing* out);

// Outward unit world normal of face `face` at (or near) the world point p.
Vec3d normal(const Primitive& prim, int face, Vec3d p);

// The face of prim nearest to p (p on or near the surface).
int face_at(const Primitive& prim, Vec3d p);

enum class Side : uint8_t { Outside, Boundary, Inside };
// Against a band of kRelativeTolerance * size (+ rounding) around the surface.
Side classify(const Primitive& prim, Vec3d p);
// Strict test without a band, for points known to be off the surface.
bool inside_strict(const Primitive& prim, Vec3d p);

struct FaceSample {
  Vec3d p, n;    // world point and outward unit normal
  double u, v;   // face parameters in [0,1]^2 (see sample_face)
  double pdf;    // per unit world area: 1 / area
};

// A point uniformly distributed by world area on a face. Parameters:
// sphere, cylinder/cone side, paraboloid bowl: u = angle / 2pi about local z,
// v = (z+1)/2 (sphere, cylinder, cone) or z (bowl); torus: u = angle about z,
// v = angle about the tube, both / 2pi; planar faces: the two local in-plane
// coordinates mapped from [-1,1] to [0,1]. Half-space planes have infinite
// area and cannot be sampled: returns false.
bool sample_face(const Primitive& prim, int face, Rng& rng, FaceSample& out);

// Uniform double in [0, 1) from the 32-bit stream (53 bits).
inline double next_double(Rng& rng) {
  const uint64_t hi = rng.next_u32() >> 5, lo = rng.next_u32() >> 6;
  return double((hi << 26) | lo) * (1.0 / 9007199254740992.0);
}

}  // namespace plm::csg
