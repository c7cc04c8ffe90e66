// 3D turtle interpretation of derived L-system strings (Prusinkiewicz &
// Lindenmayer, "The Algorithmic Beauty of Plants", ch. 1.5) into primitive
// records for the bake. The turtle state is a position and a right-handed
// frame H (heading), L (left), U (up) with H x L = U; it starts at the origin
// with H = +Z, L = -X, U = -Y, so a 2D system draws in the XZ plane (Blender's
// front view) growing up, and '+' turns counter-clockwise in that view.
//
//   symbol   parameters (default)        action
//   F        (l = step)                  draw a cylinder of the current width from p to p + l H, move there
//   f        (l = step)                  move to p + l H without drawing
//   + -      (a = angle)                 turn left / right: rotate H, L about U by +a / -a degrees
//   & ^      (a = angle)                 pitch down / up: rotate H, U about L by +a / -a
//   \ /      (a = angle)                 roll left / right: rotate L, U about H by +a / -a
//   |                                    turn around (yaw 180 degrees)
//   [ ]                                  push / pop the whole state (']' without '[' is an error)
//   !        (w)                         set the width (a diameter, >= 0); no parameter: unchanged
//   '        (i)                         set the material index (a whole number >= 0); no parameter: +1
//   @O       (r = width / 2)             sphere of radius r at p
//   @C       (l = step, r = width / 2)   cone with its base (radius r) at p and its apex at p + l H
//   @L       (l = step, w = l / 2)       leaf: a thin box of length l along H, width w along L,
//                                        thickness l / 50 along U, starting at p
//   @B       (x, y = x, z = x)           box of edge lengths x, y, z along L, U, H centred at p
//   others                               ignored
//
// Emitters (@O @C @L @B) do not move the turtle. Elements of zero length,
// width or radius are skipped. Angles whose value in degrees is a multiple of
// 90 use exact sines and cosines, so a square closes exactly.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "lsystem/language/lsystem.h"

namespace plm::lsystem {

// sin and cos of an angle in degrees, exact at multiples of 90 (the turtle and
// the scene graph turn alike).
inline void sincos_degrees(double degrees, double* s, double* c) {
  double r = std::fmod(degrees, 360.0);
  if (r < 0) r += 360.0;
  if (r == 0) { *s = 0; *c = 1; return; }
  if (r == 90) { *s = 1; *c = 0; return; }
  if (r == 180) { *s = 0; *c = -1; return; }
  if (r == 270) { *s = -1; *c = 0; return; }
  const double rad = degrees * (3.14159265358979323846 / 180.0);
  *s = std::sin(rad);
  *c = std::cos(rad);
}

// The canonical shapes are those of csg/primitive.h (Blender's defaults):
// cylinder radius 1 with z in [-1,1]; cone base radius 1 at z=-1, apex z=+1;
// box [-1,1]^3; sphere radius 1 at the origin.
enum class ShapeKind : uint8_t { Cylinder, Sphere, Cone, Box };
constexpr int kShapeKinds = 4;

struct TurtlePrimitive {
  ShapeKind shape;
  int32_t material;
  double to_world[12];  // row-major 3x4: world = M * (local, 1)
};

// Half-extent along world axis `row` of a canonical shape placed by the
// row-major 3x4 map `m` (world = M * (local, 1)): the shape spans
// m[4*row+3] +- this. Exact for spheres, cylinders and boxes; tight for cones.
inline double primitive_extent(ShapeKind shape, const double* m, int row) {
  const double* a = m + 4 * row;
  switch (shape) {
    case ShapeKind::Sphere: return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    case ShapeKind::Cylinder:
    case ShapeKind::Cone: return std::sqrt(a[0] * a[0] + a[1] * a[1]) + std::fabs(a[2]);
    default: return std::fabs(a[0]) + std::fabs(a[1]) + std::fabs(a[2]);
  }
}

struct TurtleOptions {
  double step = -1;     // < 0: the system's `step:`
  double angle = -1;    // degrees; < 0: the system's `angle:`
  double width = -1;    // < 0: the system's `width:`
  int32_t material = 0;
  size_t max_primitives = 10'000'000;
};

struct TurtleResult {
  std::vector<TurtlePrimitive> primitives;
  double lo[3], hi[3];             // world bounds of all primitives; lo > hi when there are none
  size_t count[kShapeKinds] = {};  // primitives per ShapeKind
  size_t max_stack_depth = 0;
  double end_position[3] = {};     // where the turtle stopped
};

// Throws plm::Error (PLM_ERROR_INVALID_ARGUMENT) naming the module's index
// and symbol on a bad parameter (negative width, non-integral material),
// an unmatched ']', a position that overflows, or too many primitives.
TurtleResult interpret(const LSystem& system, const ModuleString& string, const TurtleOptions& options = {});

}  // namespace plm::lsystem
