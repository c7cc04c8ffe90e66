// 3D turtle (lsystem/language/turtle.h).
#include "lsystem/language/turtle.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "lsystem/language/turtle_state.h"
#include "util/error.h"

namespace plm::lsystem {
namespace {

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

  void emit(ShapeKind shape, const Vec3d (&cols)[4], const TurtleState& st) {
    if (out.primitives.size() >= opt.max_primitives)
      error("more than ", opt.max_primitives, " primitives (TurtleOptions::max_primitives)");
    TurtlePrimitive prim;
    prim.shape = shape;
    prim.material = st.material;
    if (!turtle_map(cols, prim.to_world)) error("the primitive's transform overflowed");
    for (int r = 0; r < 3; ++r) {
      const double c = prim.to_world[4 * r + 3], e = primitive_extent(shape, prim.to_world, r);
      out.lo[r] = std::min(out.lo[r], c - e);
      out.hi[r] = std::max(out.hi[r], c + e);
    }
    ++out.count[int(shape)];
    out.primitives.push_back(prim);
  }

  TurtleResult run() {
    TurtleState st;
    st.width = opt.width;
    st.material = opt.material;
    std::vector<TurtleState> stack;
    for (int r = 0; r < 3; ++r) {
      out.lo[r] = std::numeric_limits<double>::infinity();
      out.hi[r] = -std::numeric_limits<double>::infinity();
    }
    auto emit_to = [this](ShapeKind shape, const Vec3d (&cols)[4], const TurtleState& s) { emit(shape, cols, s); };
    auto error_to = [this](const auto&... args) { error(args...); };
    for (index = 0; index < str.modules.size(); ++index) {
      const Module& m = str.modules[index];
      const TurtleOp op = sys.symbols[m.symbol].op;
      if (op == TurtleOp::Push) {
        stack.push_back(st);
        out.max_stack_depth = std::max(out.max_stack_depth, stack.size());
      } else if (op == TurtleOp::Pop) {
        if (stack.empty()) error("']' without a matching '['");
        st = stack.back();
        stack.pop_back();
      } else {
        turtle_move(op, str.params.data() + m.first_param, m.num_params, opt.step, opt.angle, st, emit_to, error_to);
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
