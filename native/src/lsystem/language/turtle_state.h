// The turtle's state and its moves (the symbol table of lsystem/language/turtle.h),
// shared by interpret() and by the scene graph, which runs the same turtle
// over one successor at a time in a node's local frame.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "lsystem/language/lsystem.h"
#include "lsystem/language/turtle.h"
#include "util/math.h"

namespace plm::lsystem {

// Position and right-handed frame H (heading), L (left), U (up), H x L = U;
// the start state is the origin with H = +Z, L = -X, U = -Y.
struct TurtleState {
  Vec3d p{0, 0, 0};
  Vec3d h{0, 0, 1}, l{-1, 0, 0}, u{0, -1, 0};
  double width = 0.1;
  int32_t material = 0;

  // Rotates a towards b by the angle: a' = a c + b s, b' = b c - a s.
  static void rotate(Vec3d& a, Vec3d& b, double degrees) {
    double s, c;
    sincos_degrees(degrees, &s, &c);
    const Vec3d na = c * a + s * b, nb = c * b - s * a;
    a = na;
    b = nb;
  }
  // Re-orthonormalises the frame against drift.
  void orthonormalize() {
    h = normalize(h);
    l = normalize(l - dot(l, h) * h);
    u = cross(h, l);
  }
  // The map from the start frame (a child's local frame) to this frame.
  Affine3d frame() const;
  bool same(const TurtleState& o) const {
    return p.x == o.p.x && p.y == o.p.y && p.z == o.p.z && h.x == o.h.x && h.y == o.h.y && h.z == o.h.z &&
           l.x == o.l.x && l.y == o.l.y && l.z == o.l.z && u.x == o.u.x && u.y == o.u.y && u.z == o.u.z &&
           width == o.width && material == o.material;
  }
};

// The row-major 3x4 map whose columns are cols (local x, y, z axes and the
// translation) into m.
inline void set_columns(const Vec3d (&cols)[4], double* m) {
  for (int c = 0; c < 4; ++c) {
    m[c] = cols[c].x;
    m[4 + c] = cols[c].y;
    m[8 + c] = cols[c].z;
  }
}

inline Affine3d TurtleState::frame() const {
  const Vec3d cols[4] = {-l, -u, h, p};
  Affine3d a;
  set_columns(cols, a.m);
  return a;
}

// set_columns; false if an element of m is not finite.
inline bool turtle_map(const Vec3d (&cols)[4], double* m) {
  set_columns(cols, m);
  for (int i = 0; i < 12; ++i)
    if (!std::isfinite(m[i])) return false;
  return true;
}

// Applies module op with its parameters (params[0, count)) to st. '[' and
// ']' are left to the caller, which keeps the stack. A primitive goes to
// emit(shape, cols, st), cols its local->frame map's columns (see
// turtle_map); a bad parameter or an overflow to error(message parts...),
// which must not return.
template <typename Emit, typename Error>
inline void turtle_move(TurtleOp op, const double* params, size_t count, double step, double angle, TurtleState& st,
                        Emit&& emit, Error&& error) {
  auto param = [&](size_t k, double fallback) { return k < count ? params[k] : fallback; };
  auto move = [&](double len) {
    st.p = st.p + len * st.h;
    if (!is_finite(st.p)) error("the turtle's position overflowed");
  };
  // An element along H from st.p with length len and radius r (right-handed:
  // L x U = H; a negative length flips H and L).
  auto along = [&](ShapeKind shape, double len, double r) {
    Vec3d h = st.h, l = st.l;
    if (len < 0) {
      h = -h;
      l = -l;
    }
    const double half = 0.5 * std::fabs(len);
    const Vec3d cols[4] = {r * l, r * st.u, half * h, st.p + half * h};
    emit(shape, cols, st);
  };
  switch (op) {
    case TurtleOp::Other:
    case TurtleOp::Push:
    case TurtleOp::Pop: break;
    case TurtleOp::Forward: {
      const double len = param(0, step);
      if (len != 0 && st.width > 0) along(ShapeKind::Cylinder, len, 0.5 * st.width);
      move(len);
      break;
    }
    case TurtleOp::Move: move(param(0, step)); break;
    case TurtleOp::Left: TurtleState::rotate(st.h, st.l, param(0, angle)); st.orthonormalize(); break;
    case TurtleOp::Right: TurtleState::rotate(st.h, st.l, -param(0, angle)); st.orthonormalize(); break;
    case TurtleOp::PitchDown: TurtleState::rotate(st.h, st.u, -param(0, angle)); st.orthonormalize(); break;
    case TurtleOp::PitchUp: TurtleState::rotate(st.h, st.u, param(0, angle)); st.orthonormalize(); break;
    case TurtleOp::RollLeft: TurtleState::rotate(st.l, st.u, param(0, angle)); st.orthonormalize(); break;
    case TurtleOp::RollRight: TurtleState::rotate(st.l, st.u, -param(0, angle)); st.orthonormalize(); break;
    case TurtleOp::TurnAround: TurtleState::rotate(st.h, st.l, 180.0); st.orthonormalize(); break;
    case TurtleOp::Width: {
      const double w = param(0, st.width);
      if (!(w >= 0)) error("the width must be >= 0, got ", w);
      st.width = w;
      break;
    }
    case TurtleOp::Material: {
      const double i = count ? param(0, 0) : double(st.material) + 1.0;
      if (!(i >= 0 && i <= 2147483647.0 && i == std::floor(i)))
        error("the material index must be a whole number in [0, 2^31), got ", i);
      st.material = int32_t(i);
      break;
    }
    case TurtleOp::Sphere: {
      const double r = std::fabs(param(0, 0.5 * st.width));
      if (r > 0) {
        const Vec3d cols[4] = {r * st.l, r * st.u, r * st.h, st.p};
        emit(ShapeKind::Sphere, cols, st);
      }
      break;
    }
    case TurtleOp::Cone: {
      const double len = param(0, step), r = std::fabs(param(1, 0.5 * st.width));
      if (len != 0 && r > 0) along(ShapeKind::Cone, len, r);
      break;
    }
    case TurtleOp::Leaf: {
      const double len = param(0, step), w = std::fabs(param(1, 0.5 * len));
      if (len != 0 && w > 0) {
        const double half = 0.5 * len;
        const Vec3d cols[4] = {0.5 * w * st.l, (std::fabs(len) / 100.0) * st.u, half * st.h, st.p + half * st.h};
        emit(ShapeKind::Box, cols, st);
      }
      break;
    }
    case TurtleOp::Box: {
      const double x = std::fabs(param(0, step));
      const double y = std::fabs(param(1, x)), z = std::fabs(param(2, x));
      if (x > 0 && y > 0 && z > 0) {
        const Vec3d cols[4] = {0.5 * x * st.l, 0.5 * y * st.u, 0.5 * z * st.h, st.p};
        emit(ShapeKind::Box, cols, st);
      }
      break;
    }
  }
}

}  // namespace plm::lsystem
