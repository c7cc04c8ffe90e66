// Node classes of an L-system graph: set-up and expansion (lsystem/graph/graph_classes.h).
#include "lsystem/graph/graph_classes.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "lsystem/graph/geometry.h"
#include "lsystem/language/expr.h"
#include "util/error.h"
#include "util/rng.h"

namespace plm::lsystem {

// graph.h: csg::make_primitive without the check and the face areas.
csg::Primitive trace_primitive(const csg::PrimitiveDesc& desc) { return csg::make_primitive_without_areas(desc); }

namespace {


// The key of a parameter or width (see ClassKey): its bits with the mantissa
// rounded to 40 bits, so that l * r1 * r2 and l * r2 * r1 are one state.
uint64_t bits(double v) {
  if (v == 0) v = 0;  // -0 and +0 are one state
  uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  constexpr int kDropped = 12;  // of the 52 mantissa bits
  if ((b & 0x7FF0000000000000ull) != 0x7FF0000000000000ull)  // finite: round to nearest
    b = (b + (uint64_t(1) << (kDropped - 1))) & ~((uint64_t(1) << kDropped) - 1);
  return b;
}

ClassKey class_key(uint32_t symbol, const double* params, size_t n, int depth, double w, int32_t mat) {
  ClassKey key{symbol, depth, bits(w), mat, {}};
  for (size_t k = 0; k < n; ++k) key.params.push_back(bits(params[k]));
  return key;
}

bool uses_rand(const std::vector<ExprNode>& nodes, int32_t root) {
  if (root < 0) return false;
  const ExprNode& n = nodes[size_t(root)];
  if (n.kind == ExprNode::Rand || n.kind == ExprNode::RandRange) return true;
  if (n.kind == ExprNode::Const || n.kind == ExprNode::Var) return false;
  return uses_rand(nodes, n.a) || uses_rand(nodes, n.b);
}

std::string symbol_name(const LSystem& sys, uint32_t s) {
  return s == kRootSymbol ? std::string("axiom") : sys.symbols[s].name;
}

// A rewritten module's successor: modules and their evaluated parameters.
struct Successor {
  struct Mod {
    uint32_t symbol, first, count;
  };
  std::vector<Mod> mods;
  std::vector<double> params;
};

Successor rewrite(const GraphClasses& g, const GraphNodeClass& c, size_t alt) {
  const LSystem& sys = g.sys;
  Successor s;
  std::vector<double> v(g.vars, 0.0);
  const std::vector<ModuleTemplate>* mods = &sys.axiom;
  const Production* p = nullptr;
  if (c.symbol != kRootSymbol) {
    p = &sys.productions[size_t(c.alternatives[alt].first)];
    for (size_t k = 0; k < c.params.size(); ++k) v[size_t(p->pred.slots[k])] = c.params[k];
    mods = &p->successor;
  }
  for (const ModuleTemplate& t : *mods) {
    s.mods.push_back({t.symbol, uint32_t(s.params.size()), uint32_t(t.args.size())});
    for (const int32_t a : t.args) {
      try {
        s.params.push_back(evaluate(sys.nodes, a, v.data(), nullptr));
      } catch (const EvalError& e) {
        if (p) fail(PLM_ERROR_INVALID_ARGUMENT, "line ", p->line, ": production '", p->text, "': ", e.what);
        fail(PLM_ERROR_INVALID_ARGUMENT, "line ", sys.axiom_line, ": axiom: ", e.what);
      }
    }
  }
  return s;
}

struct WalkEnd {
  TurtleState end;
  bool end_variable = false;  // a child with a variable end state ends a branch
};

// Runs the turtle over successor s of class `owner` (a copy: the set-up's
// classes grow meanwhile). V decides which modules are child references
// (v.child), takes each reference (v.reference) and each primitive
// (v.primitive); with V::kSetup the primitives are checked as well.
template <typename V>
WalkEnd walk(const GraphClasses& g, const GraphNodeClass& owner, const Successor& s, V& v) {
  const LSystem& sys = g.sys;
  const int child_depth = owner.depth - 1;
  TurtleState st;
  st.width = owner.width;
  st.material = owner.material;
  std::vector<std::pair<TurtleState, bool>> stack;
  bool pending = false;  // a child with a variable end state was the last thing in this branch
  size_t index = 0;
  auto error = [&](const auto&... args) {
    fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: successor of '", symbol_name(sys, owner.symbol), "' (depth ",
         owner.depth, "), module ", index + 1, " ('", sys.symbols[s.mods[index].symbol].name, "'): ", args...);
  };
  auto emit = [&](ShapeKind shape, const Vec3d (&cols)[4], const TurtleState& at) {
    csg::PrimitiveDesc d;
    d.shape = csg_shape(shape);
    if (!turtle_map(cols, d.to_world)) error("the primitive's transform overflowed");
    if constexpr (V::kSetup) {  // an expansion repeats a set-up walk of the same (class, production)
      const std::string why = csg::check_primitive(d);
      if (!why.empty()) error(why);
    }
    v.primitive(shape, d, at.material);
  };
  for (index = 0; index < s.mods.size(); ++index) {
    const Successor::Mod& m = s.mods[index];
    const double* params = s.params.data() + m.first;
    const TurtleOp op = sys.symbols[m.symbol].op;
    uint32_t cls = 0;
    const bool child = v.child(m.symbol, params, m.count, child_depth, st, &cls);
    if (pending) {
      if (op == TurtleOp::Pop) {
        pending = false;
      } else if (child || op != TurtleOp::Other) {
        error("it follows a stochastic module whose productions end in different turtle states; "
              "the graph needs such a module to end its branch (or the successor)");
      }
    }
    if (child) {
      const Affine3d t = st.frame();
      v.reference(cls, t);
      const TurtleState& e = g.end[cls];
      st.p = t.point(e.p);
      st.h = t.vector(e.h);
      st.l = t.vector(e.l);
      st.u = t.vector(e.u);
      st.width = e.width;
      st.material = e.material;
      if (g.end_variable[cls]) pending = true;
      continue;
    }
    if (op == TurtleOp::Push) {
      stack.emplace_back(st, pending);
    } else if (op == TurtleOp::Pop) {
      if (stack.empty())
        error("']' without a matching '[' in the same successor: brackets may not cross node boundaries");
      st = stack.back().first;
      pending = stack.back().second;
      stack.pop_back();
    } else {
      turtle_move(op, params, m.count, g.step, g.angle, st, emit, error);
    }
  }
  if (!stack.empty()) {
    index = s.mods.size() - 1;
    error("'[' without a matching ']' in the same successor: brackets may not cross node boundaries");
  }
  return {st, pending};
}

// The expansion's walk: child classes are looked up, primitives and
// references go into the expansion.
struct ExpandWalk {
  static constexpr bool kSetup = false;
  const GraphClasses& g;
  uint32_t cls;
  size_t alt;
  GraphExpansion* out;

  bool child(uint32_t symbol, const double* params, size_t n, int depth, const TurtleState& st, uint32_t* child) const {
    if (depth <= 0 || g.sys.productions_of[symbol].empty()) return false;
    const auto it = g.index.find(class_key(symbol, params, n, depth, st.width, st.material));
    if (it == g.index.end()) return false;
    *child = it->second;
    return true;
  }
  void reference(uint32_t child, const Affine3d& t) {
    const GraphBox& b = g.child_desc[cls][alt][out->children.size()].box;
    out->children.push_back(GraphChild{child, g.classes[child].path_dependent, t, inverse(t), b.lo, b.hi});
    out->prims_before.push_back(uint32_t(out->prims.size()));
  }
  void primitive(ShapeKind shape, const csg::PrimitiveDesc& d, int32_t material) {
    out->prims.push_back(GraphPrimitive{shape, material, trace_primitive(d)});
  }
};

// The set-up: interns classes bottom-up from the root (each class is
// analysed when first met), with its bounds and end state.
class Builder {
 public:
  Builder(GraphClasses& g, const GraphOptions& o) : g_(g), bounds_(o), vars_(g.vars, 0.0) {}

  void build_root(int depth) {
    GraphNodeClass root;
    root.symbol = kRootSymbol;
    root.depth = depth + 1;
    root.width = g_.width;
    root.material = g_.material;
    add(std::move(root));
    analyse(0);
    g_.world_lo = {kInf, kInf, kInf};
    g_.world_hi = {-kInf, -kInf, -kInf};
    bounds_.world_box(g_.classes, g_.opt.world, &g_.world_lo, &g_.world_hi);
    g_.bounds_visits = bounds_.visits();
    g_.desc_boxes = bounds_.desc_boxes_made();
  }

 private:
  // The set-up's walk of production alt of class id: child classes are
  // interned, primitives and references give the bounds.
  struct SetupWalk {
    static constexpr bool kSetup = true;
    Builder& b;
    uint32_t id;
    size_t alt;
    Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    uint64_t count = 0;
    bool path_dependent = false;

    bool child(uint32_t symbol, const double* params, size_t n, int depth, const TurtleState& st, uint32_t* cls) {
      if (depth <= 0 || b.g_.sys.productions_of[symbol].empty()) return false;
      if (b.alternatives(symbol, params, n).empty()) return false;
      *cls = b.intern(symbol, params, n, depth, st.width, st.material);
      return true;
    }
    void reference(uint32_t cls, const Affine3d& t) {
      const GraphNodeClass& cc = b.g_.classes[cls];
      DescBoxes d = b.bounds_.add_child(b.g_.classes, id, alt, cls, t);
      grow(lo, hi, d.box.lo, d.box.hi);
      b.g_.child_desc[id][alt].push_back(std::move(d));
      count = cc.max_primitives > std::numeric_limits<uint64_t>::max() - count ? std::numeric_limits<uint64_t>::max()
                                                                              : count + cc.max_primitives;
      path_dependent = path_dependent || cc.path_dependent;
    }
    void primitive(ShapeKind shape, const csg::PrimitiveDesc& d, int32_t) {
      if (count < std::numeric_limits<uint64_t>::max()) ++count;
      const Affine3d m = Affine3d::from_array(d.to_world);
      Vec3d blo, bhi;
      prim_box(shape, m, &blo, &bhi);
      pad_box(blo, bhi);
      grow(lo, hi, blo, bhi);
      b.bounds_.add_primitive(id, alt, shape, m);
    }
  };

  // Applicable productions of (symbol, params): what derive() would choose from.
  std::vector<std::pair<int32_t, double>> alternatives(uint32_t symbol, const double* params, size_t n) {
    const LSystem& sys = g_.sys;
    std::vector<std::pair<int32_t, double>> out;
    for (const int32_t pi : sys.productions_of[symbol]) {
      const Production& p = sys.productions[size_t(pi)];
      if (p.pred.slots.size() != n) continue;
      for (size_t k = 0; k < n; ++k) vars_[size_t(p.pred.slots[k])] = params[k];
      try {
        if (p.condition >= 0 && evaluate(sys.nodes, p.condition, vars_.data(), nullptr) == 0) continue;
        if (p.probability < 0) return {{pi, -1.0}};
        const double w = evaluate(sys.nodes, p.probability, vars_.data(), nullptr);
        if (w < 0) fail(PLM_ERROR_INVALID_ARGUMENT, "line ", p.line, ": production '", p.text,
                        "': the probability is negative (", w, ")");
        if (w > 0) out.emplace_back(pi, w);
      } catch (const EvalError& e) {
        fail(PLM_ERROR_INVALID_ARGUMENT, "line ", p.line, ": production '", p.text, "': ", e.what);
      }
    }
    return out;
  }

  uint32_t add(GraphNodeClass c) {
    const uint32_t id = uint32_t(g_.classes.size());
    g_.classes.push_back(std::move(c));
    g_.end.emplace_back();
    g_.end_variable.push_back(0);
    g_.child_desc.emplace_back();
    return id;
  }

  // The class of a non-terminal module, created and analysed when first met.
  uint32_t intern(uint32_t symbol, const double* params, size_t n, int depth, double w, int32_t mat) {
    ClassKey key = class_key(symbol, params, n, depth, w, mat);
    const auto it = g_.index.find(key);
    if (it != g_.index.end()) return it->second;
    if (g_.classes.size() >= g_.opt.max_classes)
      fail(PLM_ERROR_OUT_OF_MEMORY, "lsystem graph: more than ", g_.opt.max_classes,
           " node classes (GraphOptions::max_classes)");
    if (++per_symbol_depth_[{symbol, depth}] > g_.opt.max_classes_per_symbol_depth)
      fail(PLM_ERROR_INVALID_ARGUMENT,
           "parametric productions need the flattened path: module '", symbol_name(g_.sys, symbol),
           "' reaches depth ", depth, " in more than ", g_.opt.max_classes_per_symbol_depth,
           " distinct states (parameters, width, material); the graph needs parameters that are constant per "
           "(module, depth)");
    GraphNodeClass c;
    c.symbol = symbol;
    c.depth = depth;
    c.width = w;
    c.material = mat;
    c.params.assign(params, params + n);
    c.alternatives = alternatives(symbol, params, n);
    for (const auto& a : c.alternatives) c.total_weight += std::max(a.second, 0.0);
    const uint32_t id = add(std::move(c));
    g_.index.emplace(std::move(key), id);
    analyse(id);
    return id;
  }

  // Walks every production of class id: its box, flattened count, path
  // dependence and end state.
  void analyse(uint32_t id) {
    const size_t alts = g_.classes[id].symbol == kRootSymbol ? 1 : g_.classes[id].alternatives.size();
    g_.child_desc[id].assign(alts, {});
    bounds_.begin_class(id, alts);
    Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    uint64_t count = 0;
    bool path_dependent = alts > 1, variable = false;
    TurtleState first_end;
    for (size_t a = 0; a < alts; ++a) {
      const GraphNodeClass copy = g_.classes[id];  // classes grow while walking
      const Successor s = rewrite(g_, copy, a);
      SetupWalk v{*this, id, a};
      const WalkEnd r = walk(g_, copy, s, v);
      grow(lo, hi, v.lo, v.hi);
      count = std::max(count, v.count);
      path_dependent = path_dependent || v.path_dependent;
      variable = variable || r.end_variable;
      if (a == 0) {
        first_end = r.end;
      } else if (!r.end.same(first_end)) {
        variable = true;
      }
    }
    GraphNodeClass& c = g_.classes[id];
    c.lo = lo;
    c.hi = hi;
    c.max_primitives = count;
    c.path_dependent = path_dependent;
    g_.end[id] = first_end;
    g_.end_variable[id] = variable ? 1 : 0;
    bounds_.end_class(id);
  }

  GraphClasses& g_;
  BoundsUnfolding bounds_;
  std::vector<double> vars_;  // alternatives()' parameter slots
  std::map<std::pair<uint32_t, int>, size_t> per_symbol_depth_;
};

// What the graph cannot represent: context and rand() need the flattened path.
void check_system(const LSystem& system) {
  for (const Production& p : system.productions) {
    if (!p.left.empty() || !p.right.empty())
      fail(PLM_ERROR_INVALID_ARGUMENT, "line ", p.line, ": production '", p.text,
           "': context-sensitive productions need the flattened path");
    bool r = uses_rand(system.nodes, p.condition) || uses_rand(system.nodes, p.probability);
    for (const ModuleTemplate& t : p.successor)
      for (const int32_t a : t.args) r = r || uses_rand(system.nodes, a);
    if (r)
      fail(PLM_ERROR_INVALID_ARGUMENT, "line ", p.line, ": production '", p.text,
           "': rand() in productions needs the flattened path");
  }
  for (const ModuleTemplate& t : system.axiom)
    for (const int32_t a : t.args)
      if (uses_rand(system.nodes, a))
        fail(PLM_ERROR_INVALID_ARGUMENT, "line ", system.axiom_line, ": axiom: rand() needs the flattened path");
}

}  // namespace

GraphClasses::GraphClasses(const LSystem& system, const GraphOptions& options) : sys(system), opt(options) {
  const GraphOptions& o = opt;
  step = o.step < 0 ? system.step : o.step;
  angle = o.angle < 0 ? system.angle : o.angle;
  width = o.width < 0 ? system.width : o.width;
  material = o.material;
  if (!std::isfinite(step) || !std::isfinite(angle) || !std::isfinite(width))
    fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: step, angle and width must be finite");
  if (material < 0) fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: the material index must be >= 0");
  if (o.max_levels < 1 || o.max_levels > kMaxGraphLevels)
    fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: max_levels must be in [1, ", kMaxGraphLevels, "], got ",
         o.max_levels);
  const int depth = o.depth >= 0 ? o.depth : system.depth;
  if (depth + 1 > o.max_levels)
    fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: depth ", depth, " needs ", depth + 1,
         " traversal levels, over the limit of ", o.max_levels,
         " (GraphOptions::max_levels); use the flattened path or a smaller depth");
  levels = depth + 1;
  check_system(system);
  size_t slots = 0;
  for (const Production& p : system.productions) slots = std::max(slots, size_t(p.num_slots));
  vars = slots + 1;
  root_key = splitmix64(o.seed);
  inline_views = o.cache_bytes == 0 || o.cache_bytes >= kGraphInlineMinCacheBytes;
  Builder(*this, o).build_root(depth);
}

std::shared_ptr<GraphExpansion> GraphClasses::expand(uint32_t cls, uint64_t key) const {
  const GraphNodeClass& c = classes[cls];
  size_t alt = 0;
  if (c.alternatives.size() > 1) {
    RandomStream rng{stream_key(key, uint64_t(c.depth), c.symbol, 3)};
    double u = rng.uniform() * c.total_weight;
    alt = c.alternatives.size() - 1;
    for (size_t k = 0; k < c.alternatives.size(); ++k) {
      if (u < c.alternatives[k].second) {
        alt = k;
        break;
      }
      u -= c.alternatives[k].second;
    }
  }
  auto e = std::make_shared<GraphExpansion>();
  e->alt = uint32_t(alt);
  ExpandWalk v{*this, cls, alt, e.get()};
  walk(*this, c, rewrite(*this, c, alt), v);
  return e;
}

}  // namespace plm::lsystem
