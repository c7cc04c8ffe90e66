// 3D turtle (lsystem/turtle.h).
#include "lsystem/turtle.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "util/error.h"

namespace plm::lsystem {
namespace {

struct V3 {
  double x, y, z;
};
V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 operator*(double s, V3 a) { return {s * a.x, s * a.y, s * a.z}; }
double dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V3 cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
V3 normalize(V3 a) { return (1.0 / std::sqrt(dot(a, a))) * a; }
bool finite(V3 a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }

struct State {
  V3 p{0, 0, 0};
  V3 h{0, 0, 1}, l{-1, 0, 0}, u{0, -1, 0};
  double width = 0.1;
  int32_t material = 0;

  // Rotates a towards b by the angle: a' = a c + b s, b' = b c - a s; then
  // re-orthonormalises the frame against drift.
  static void rotate(V3& a, V3& b, double degrees) {
    double s, c;
    sincos_degrees(degrees, &s, &c);
    const V3 na = c * a + s * b, nb = c * b - s * a;
    a = na;
    b = nb;
  }
  void orthonormalize() {
    h = normalize(h);
    l = normalize(l - dot(l, h) * h);
    u = cross(h, l);
  }
};

struct Turtle {
  const LSystem& sys;
  const ModuleString& str;
  TurtleOptions opt;
  TurtleResult out;
  size_t index = 0;  // current module

  template <typename... Args>
  [[noreturn]] void error(const Args&... args) const {
    fail(PLM_ERROR_INVALID_ARGUMENT, "turtle: module ", index + 1, " ('",
         sys.symbols[str.modules[index].symbol].name, "'): ", args...);
  }

  // Columns: local x, y, z axes (scaled) and the translation.
  void emit(ShapeKind shape, const State& st, V3 x, V3 y, V3 z, V3 t) {
    if (out.primitives.size() >= opt.max_primitives)
      error("more than ", opt.max_primitives, " primitives (TurtleOptions::max_primitives)");
    TurtlePrimitive prim;
    prim.shape = shape;
    prim.material = st.material;
    const V3 cols[4] = {x, y, z, t};
    for (int c = 0; c < 4; ++c) {
      prim.to_world[0 * 4 + c] = cols[c].x;
      prim.to_world[1 * 4 + c] = cols[c].y;
      prim.to_world[2 * 4 + c] = cols[c].z;
    }
    for (double v : prim.to_world)
      if (!std::isfinite(v)) error("the primitive's transform overflowed");
    for (int r = 0; r < 3; ++r) {
      const double c = prim.to_world[4 * r + 3], e = primitive_extent(shape, prim.to_world, r);
      out.lo[r] = std::min(out.lo[r], c - e);
      out.hi[r] = std::max(out.hi[r], c + e);
    }
    ++out.count[int(shape)];
    out.primitives.push_back(prim);
  }

  double param(size_t k, double fallback) const {
    const Module& m = str.modules[index];
    return k < m.num_params ? str.params[m.first_param + k] : fallback;
  }

  void move(State& st, double len) {
    st.p = st.p + len * st.h;
    if (!finite(st.p)) error("the turtle's position overflowed");
  }

  // Axis-aligned element along H from st.p with length len and radius r
  // (right-handed: L x U = H; a negative length flips H and L).
  void along(ShapeKind shape, const State& st, double len, double r) {
    V3 h = st.h, l = st.l;
    if (len < 0) {
      h = -1.0 * h;
      l = -1.0 * l;
    }
    const double half = 0.5 * std::fabs(len);
    emit(shape, st, r * l, r * st.u, half * h, st.p + half * h);
  }

  TurtleResult run() {
    State st;
    st.width = opt.width;
    st.material = opt.material;
    std::vector<State> stack;
    for (int r = 0; r < 3; ++r) {
      out.lo[r] = std::numeric_limits<double>::infinity();
      out.hi[r] = -std::numeric_limits<double>::infinity();
    }
    const double step = opt.step, angle = opt.angle;
    for (index = 0; index < str.modules.size(); ++index) {
      const Module& m = str.modules[index];
      switch (sys.symbols[m.symbol].op) {
        case TurtleOp::Other: break;
        case TurtleOp::Forward: {
          const double len = param(0, step);
          if (len != 0 && st.width > 0) along(ShapeKind::Cylinder, st, len, 0.5 * st.width);
          move(st, len);
          break;
        }
        case TurtleOp::Move: move(st, param(0, step)); break;
        case TurtleOp::Left: State::rotate(st.h, st.l, param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::Right: State::rotate(st.h, st.l, -param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::PitchDown: State::rotate(st.h, st.u, -param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::PitchUp: State::rotate(st.h, st.u, param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::RollLeft: State::rotate(st.l, st.u, param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::RollRight: State::rotate(st.l, st.u, -param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::TurnAround: State::rotate(st.h, st.l, 180.0); st.orthonormalize(); break;
        case TurtleOp::Push:
          stack.push_back(st);
          out.max_stack_depth = std::max(out.max_stack_depth, stack.size());
          break;
        case TurtleOp::Pop:
          if (stack.empty()) error("']' without a matching '['");
          st = stack.back();
          stack.pop_back();
          break;
        case TurtleOp::Width: {
          const double w = param(0, st.width);
          if (!(w >= 0)) error("the width must be >= 0, got ", w);
          st.width = w;
          break;
        }
        case TurtleOp::Material: {
          const double i = m.num_params ? param(0, 0) : double(st.material) + 1.0;
          if (!(i >= 0 && i <= 2147483647.0 && i == std::floor(i)))
            error("the material index must be a whole number in [0, 2^31), got ", i);
          st.material = int32_t(i);
          break;
        }
        case TurtleOp::Sphere: {
          const double r = std::fabs(param(0, 0.5 * st.width));
          if (r > 0) emit(ShapeKind::Sphere, st, r * st.l, r * st.u, r * st.h, st.p);
          break;
        }
        case TurtleOp::Cone: {
          const double len = param(0, step), r = std::fabs(param(1, 0.5 * st.width));
          if (len != 0 && r > 0) along(ShapeKind::Cone, st, len, r);
          break;
        }
        case TurtleOp::Leaf: {
          const double len = param(0, step), w = std::fabs(param(1, 0.5 * len));
          if (len != 0 && w > 0) {
            const double half = 0.5 * len;
            emit(ShapeKind::Box, st, 0.5 * w * st.l, (std::fabs(len) / 100.0) * st.u, half * st.h,
                 st.p + half * st.h);
          }
          break;
        }
        case TurtleOp::Box: {
          const double x = std::fabs(param(0, step));
          const double y = std::fabs(param(1, x)), z = std::fabs(param(2, x));
          if (x > 0 && y > 0 && z > 0)
            emit(ShapeKind::Box, st, 0.5 * x * st.l, 0.5 * y * st.u, 0.5 * z * st.h, st.p);
          break;
        }
      }
    }
    out.end_position[0] = st.p.x;
    out.end_position[1] = st.p.y;
    out.end_position[2] = st.p.z;
    return std::move(out);
  }
};

}  // namespace

TurtleResult interpret(const LSystem& system, const ModuleString& string, const TurtleOptions& options) {
  TurtleOptions opt = options;
  if (opt.step < 0) opt.step = system.step;
  if (opt.angle < 0) opt.angle = system.angle;
  if (opt.width < 0) opt.width = system.width;
  if (!std::isfinite(opt.step) || !std::isfinite(opt.angle) || !std::isfinite(opt.width))
    fail(PLM_ERROR_INVALID_ARGUMENT, "turtle: step, angle and width must be finite");
  if (opt.material < 0) fail(PLM_ERROR_INVALID_ARGUMENT, "turtle: the material index must be >= 0");
  return Turtle{system, string, opt, {}, 0}.run();
}

}  // namespace plm::lsystem
