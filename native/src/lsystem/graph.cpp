// L-system scene graph traced without flattening (lsystem/graph.h).
#include "lsystem/graph.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <cmath>
#include <limits>
#include <list>
#include <map>
#include <tuple>
#include <unordered_map>

#include "accel/user_geometry.h"
#include "lsystem/embree_callbacks.h"
#include "lsystem/expr.h"
#include "util/error.h"
#include "util/rng.h"

namespace plm::lsystem {

using csg::Affine;
using csg::DVec3;

namespace {

constexpr uint32_t kRoot = std::numeric_limits<uint32_t>::max();
constexpr double kInf = std::numeric_limits<double>::infinity();

// The turtle state of lsystem/turtle.cpp, in a node's local frame.
struct State {
  DVec3 p{0, 0, 0};
  DVec3 h{0, 0, 1}, l{-1, 0, 0}, u{0, -1, 0};
  double width = 0.1;
  int32_t material = 0;

  static void rotate(DVec3& a, DVec3& b, double degrees) {
    double s, c;
    sincos_degrees(degrees, &s, &c);
    const DVec3 na = c * a + s * b, nb = c * b - s * a;
    a = na;
    b = nb;
  }
  void orthonormalize() {
    h = csg::normalize(h);
    l = csg::normalize(l - dot(l, h) * h);
    u = cross(h, l);
  }
  // The map from a child's local frame (the turtle's start frame) to this frame.
  Affine frame() const {
    const DVec3 cols[4] = {-l, -u, h, p};
    Affine a;
    for (int c = 0; c < 4; ++c) {
      a.m[c] = cols[c].x;
      a.m[4 + c] = cols[c].y;
      a.m[8 + c] = cols[c].z;
    }
    return a;
  }
  bool same(const State& o) const {
    return p.x == o.p.x && p.y == o.p.y && p.z == o.p.z && h.x == o.h.x && h.y == o.h.y && h.z == o.h.z &&
           l.x == o.l.x && l.y == o.l.y && l.z == o.l.z && u.x == o.u.x && u.y == o.u.y && u.z == o.u.z &&
           width == o.width && material == o.material;
  }
};

Affine compose(const Affine& a, const Affine& b) {
  Affine c;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 4; ++k) {
      double v = a.m[4 * r] * b.m[k] + a.m[4 * r + 1] * b.m[4 + k] + a.m[4 * r + 2] * b.m[8 + k];
      if (k == 3) v += a.m[4 * r + 3];
      c.m[4 * r + k] = v;
    }
  }
  return c;
}

void grow(DVec3& lo, DVec3& hi, DVec3 a, DVec3 b) {
  lo = csg::min(lo, a);
  hi = csg::max(hi, b);
}

// The box (lo, hi) mapped by t, as an axis-aligned box, padded by 1e-9 relative.
void transform_box(const Affine& t, DVec3 lo, DVec3 hi, DVec3* out_lo, DVec3* out_hi) {
  DVec3 a{kInf, kInf, kInf}, b{-kInf, -kInf, -kInf};
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) {
    *out_lo = a;
    *out_hi = b;
    return;
  }
  for (int k = 0; k < 8; ++k) {
    const DVec3 c{(k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z};
    const DVec3 w = t.point(c);
    a = csg::min(a, w);
    b = csg::max(b, w);
  }
  const double pad = 1e-9 * (max_abs(a) + max_abs(b)) + 1e-300;
  *out_lo = a - DVec3{pad, pad, pad};
  *out_hi = b + DVec3{pad, pad, pad};
}

bool box_hit(DVec3 lo, DVec3 hi, DVec3 o, DVec3 d, double t0, double t1) {
  for (int a = 0; a < 3; ++a) {
    if (!(lo[a] <= hi[a])) return false;
    if (d[a] == 0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    const double inv = 1.0 / d[a];
    double ta = (lo[a] - o[a]) * inv, tb = (hi[a] - o[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

csg::Shape csg_shape(ShapeKind k) {
  switch (k) {
    case ShapeKind::Cylinder: return csg::Shape::Cylinder;
    case ShapeKind::Sphere: return csg::Shape::Sphere;
    case ShapeKind::Cone: return csg::Shape::Cone;
    case ShapeKind::Box: return csg::Shape::Box;
  }
  return csg::Shape::Box;
}

bool uses_rand(const std::vector<ExprNode>& nodes, int32_t root) {
  if (root < 0) return false;
  const ExprNode& n = nodes[size_t(root)];
  if (n.kind == ExprNode::Rand || n.kind == ExprNode::RandRange) return true;
  if (n.kind == ExprNode::Const || n.kind == ExprNode::Var) return false;
  return uses_rand(nodes, n.a) || uses_rand(nodes, n.b);
}

// A rewritten module's successor: modules and their evaluated parameters.
struct Successor {
  struct Mod {
    uint32_t symbol, first, count;
  };
  std::vector<Mod> mods;
  std::vector<double> params;
};

struct ClassKey {
  uint32_t symbol;
  int depth;
  uint64_t width_bits;
  int32_t material;
  std::vector<uint64_t> params;
  bool operator<(const ClassKey& o) const {
    return std::tie(symbol, depth, width_bits, material, params) <
           std::tie(o.symbol, o.depth, o.width_bits, o.material, o.params);
  }
};

// The key of a parameter or width: its bits with the mantissa rounded to 40
// bits, so that values equal but for rounding (l * r1 * r2 and l * r2 * r1)
// are one state; the state keeps the value it was first met with (the others
// differ from it by a few ulps).
uint64_t bits(double v) {
  if (v == 0) v = 0;  // -0 and +0 are one state
  uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  constexpr int kDropped = 12;  // of the 52 mantissa bits
  if ((b & 0x7FF0000000000000ull) != 0x7FF0000000000000ull)  // finite: round to nearest
    b = (b + (uint64_t(1) << (kDropped - 1))) & ~((uint64_t(1) << kDropped) - 1);
  return b;
}

struct CacheKey {
  uint32_t cls;
  uint64_t path;
  bool operator==(const CacheKey& o) const { return cls == o.cls && path == o.path; }
};
struct CacheKeyHash {
  size_t operator()(const CacheKey& k) const { return size_t(splitmix64(k.path ^ (uint64_t(k.cls) << 32))); }
};

}  // namespace

struct Graph::Impl {
  LSystem sys;
  GraphOptions opt;
  double step = 1, angle = 90, width = 0.1;
  int32_t material = 0;
  int levels = 0;
  std::vector<GraphNodeClass> classes;
  std::vector<State> end;            // per class: net turtle state at its end (first production's)
  std::vector<uint8_t> end_variable; // per class: productions end in different states
  std::map<ClassKey, uint32_t> index;
  std::map<std::pair<uint32_t, int>, size_t> per_symbol_depth;
  std::vector<double> vars;          // set-up scratch

  // Per-thread LRU cache of expansions.
  struct Cache {
    using Entry = std::pair<CacheKey, std::shared_ptr<const GraphExpansion>>;
    std::list<Entry> lru;  // front: most recently used
    std::unordered_map<CacheKey, std::list<Entry>::iterator, CacheKeyHash> map;
    // Per class: the entry of its last lookup, found again without hashing
    // (a class that is not path dependent has one entry; valid until evicted).
    struct Memo {
      bool valid = false;
      uint64_t path = 0;
      std::list<Entry>::iterator it;
    };
    std::vector<Memo> memo;
    size_t bytes = 0, peak = 0;
    uint64_t hits = 0, misses = 0, evictions = 0, truncated = 0;
    GraphHit last_hit;
  };
  mutable tbb::enumerable_thread_specific<Cache> caches;

  std::string symbol_name(uint32_t s) const { return s == kRoot ? std::string("axiom") : sys.symbols[s].name; }

  // ---- set-up ----

  // Applicable productions of (symbol, params): what derive() would choose from.
  std::vector<std::pair<int32_t, double>> alternatives(uint32_t symbol, const double* params, size_t n) {
    std::vector<std::pair<int32_t, double>> out;
    for (const int32_t pi : sys.productions_of[symbol]) {
      const Production& p = sys.productions[size_t(pi)];
      if (p.pred.slots.size() != n) continue;
      for (size_t k = 0; k < n; ++k) vars[size_t(p.pred.slots[k])] = params[k];
      try {
        if (p.condition >= 0 && evaluate(sys.nodes, p.condition, vars.data(), nullptr) == 0) continue;
        if (p.probability < 0) return {{pi, -1.0}};
        const double w = evaluate(sys.nodes, p.probability, vars.data(), nullptr);
        if (w < 0) fail(PLM_ERROR_INVALID_ARGUMENT, "line ", p.line, ": production '", p.text,
                        "': the probability is negative (", w, ")");
        if (w > 0) out.emplace_back(pi, w);
      } catch (const EvalError& e) {
        fail(PLM_ERROR_INVALID_ARGUMENT, "line ", p.line, ": production '", p.text, "': ", e.what);
      }
    }
    return out;
  }

  Successor rewrite(const GraphNodeClass& c, size_t alt) const {
    Successor s;
    std::vector<double> v(vars.size(), 0.0);
    const std::vector<ModuleTemplate>* mods = &sys.axiom;
    const Production* p = nullptr;
    if (c.symbol != kRoot) {
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

  // The class of a non-terminal module, created (and analysed) at set-up.
  uint32_t intern(uint32_t symbol, const double* params, size_t n, int depth, double w, int32_t mat) {
    ClassKey key{symbol, depth, bits(w), mat, {}};
    for (size_t k = 0; k < n; ++k) key.params.push_back(bits(params[k]));
    const auto it = index.find(key);
    if (it != index.end()) return it->second;
    if (classes.size() >= opt.max_classes)
      fail(PLM_ERROR_OUT_OF_MEMORY, "lsystem graph: more than ", opt.max_classes,
           " node classes (GraphOptions::max_classes)");
    if (++per_symbol_depth[{symbol, depth}] > opt.max_classes_per_symbol_depth)
      fail(PLM_ERROR_INVALID_ARGUMENT,
           "parametric productions need the flattened path: module '", symbol_name(symbol), "' reaches depth ",
           depth, " in more than ", opt.max_classes_per_symbol_depth,
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
    const uint32_t id = uint32_t(classes.size());
    classes.push_back(std::move(c));
    end.emplace_back();
    end_variable.push_back(0);
    index.emplace(std::move(key), id);
    analyse(id);
    return id;
  }

  // Is module (symbol, params) at this depth a child reference? At set-up this
  // creates its class; while tracing it only looks it up.
  bool child_class(bool setup, uint32_t symbol, const double* params, size_t n, int depth, const State& st,
                   uint32_t* cls) {
    if (depth <= 0 || sys.productions_of[symbol].empty()) return false;
    if (setup) {
      if (alternatives(symbol, params, n).empty()) return false;
      *cls = intern(symbol, params, n, depth, st.width, st.material);
      return true;
    }
    ClassKey key{symbol, depth, bits(st.width), st.material, {}};
    for (size_t k = 0; k < n; ++k) key.params.push_back(bits(params[k]));
    const auto it = index.find(key);
    if (it == index.end()) return false;
    *cls = it->second;
    return true;
  }

  struct WalkResult {
    DVec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    uint64_t count = 0;
    bool path_dependent = false;
    bool end_variable = false;
    State end;
  };

  // Interprets a successor in the node's frame: draws terminal modules,
  // references non-terminal ones. setup: bounds and classes; else fills out.
  WalkResult walk(const GraphNodeClass& owner_copy, const Successor& s, bool setup, GraphExpansion* out) {
    const uint32_t owner_symbol = owner_copy.symbol;
    const int child_depth = owner_copy.depth - 1;
    WalkResult r;
    State st;
    st.width = owner_copy.width;
    st.material = owner_copy.material;
    std::vector<std::pair<State, bool>> stack;
    bool pending = false;  // a child with a variable end state was the last thing in this branch
    size_t index_in_successor = 0;
    auto error = [&](const auto&... args) {
      fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: successor of '", symbol_name(owner_symbol),
           "' (depth ", owner_copy.depth, "), module ", index_in_successor + 1, " ('",
           sys.symbols[s.mods[index_in_successor].symbol].name, "'): ", args...);
    };
    auto emit = [&](ShapeKind shape, DVec3 x, DVec3 y, DVec3 z, DVec3 t) {
      csg::PrimitiveDesc d;
      d.shape = csg_shape(shape);
      const DVec3 cols[4] = {x, y, z, t};
      for (int c = 0; c < 4; ++c) {
        d.to_world[c] = cols[c].x;
        d.to_world[4 + c] = cols[c].y;
        d.to_world[8 + c] = cols[c].z;
      }
      for (double v : d.to_world)
        if (!std::isfinite(v)) error("the primitive's transform overflowed");
      const std::string why = csg::check_primitive(d);
      if (!why.empty()) error(why);
      GraphPrimitive g{shape, st.material, csg::make_primitive(d)};
      if (r.count < std::numeric_limits<uint64_t>::max()) ++r.count;
      if (setup) {
        grow(r.lo, r.hi, g.prim.lo, g.prim.hi);
      } else {
        out->prims.push_back(g);
      }
    };
    auto along = [&](ShapeKind shape, double len, double rad) {
      DVec3 h = st.h, l = st.l;
      if (len < 0) {
        h = -h;
        l = -l;
      }
      const double half = 0.5 * std::fabs(len);
      emit(shape, rad * l, rad * st.u, half * h, st.p + half * h);
    };
    auto move = [&](double len) {
      st.p = st.p + len * st.h;
      if (!is_finite(st.p)) error("the turtle's position overflowed");
    };

    for (index_in_successor = 0; index_in_successor < s.mods.size(); ++index_in_successor) {
      const Successor::Mod& m = s.mods[index_in_successor];
      const double* params = s.params.data() + m.first;
      auto param = [&](size_t k, double fallback) { return k < m.count ? params[k] : fallback; };
      const TurtleOp op = sys.symbols[m.symbol].op;
      uint32_t cls = 0;
      const bool child = child_class(setup, m.symbol, params, m.count, child_depth, st, &cls);
      if (pending) {
        if (op == TurtleOp::Pop) {
          pending = false;
        } else if (child || op != TurtleOp::Other) {
          error("it follows a stochastic module whose productions end in different turtle states; "
                "the graph needs such a module to end its branch (or the successor)");
        }
      }
      if (child) {
        const GraphNodeClass& cc = classes[cls];
        const Affine t = st.frame();
        DVec3 lo, hi;
        transform_box(t, cc.lo, cc.hi, &lo, &hi);
        if (setup) {
          grow(r.lo, r.hi, lo, hi);
          r.count = cc.max_primitives > std::numeric_limits<uint64_t>::max() - r.count
                        ? std::numeric_limits<uint64_t>::max()
                        : r.count + cc.max_primitives;
          r.path_dependent = r.path_dependent || cc.path_dependent;
        } else {
          out->children.push_back(GraphChild{cls, t, csg::inverse(t), lo, hi});
          out->prims_before.push_back(uint32_t(out->prims.size()));
        }
        const State& e = end[cls];
        st.p = t.point(e.p);
        st.h = t.vector(e.h);
        st.l = t.vector(e.l);
        st.u = t.vector(e.u);
        st.width = e.width;
        st.material = e.material;
        if (end_variable[cls]) pending = true;
        continue;
      }
      switch (op) {
        case TurtleOp::Other: break;
        case TurtleOp::Forward: {
          const double len = param(0, step);
          if (len != 0 && st.width > 0) along(ShapeKind::Cylinder, len, 0.5 * st.width);
          move(len);
          break;
        }
        case TurtleOp::Move: move(param(0, step)); break;
        case TurtleOp::Left: State::rotate(st.h, st.l, param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::Right: State::rotate(st.h, st.l, -param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::PitchDown: State::rotate(st.h, st.u, -param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::PitchUp: State::rotate(st.h, st.u, param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::RollLeft: State::rotate(st.l, st.u, param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::RollRight: State::rotate(st.l, st.u, -param(0, angle)); st.orthonormalize(); break;
        case TurtleOp::TurnAround: State::rotate(st.h, st.l, 180.0); st.orthonormalize(); break;
        case TurtleOp::Push: stack.emplace_back(st, pending); break;
        case TurtleOp::Pop:
          if (stack.empty())
            error("']' without a matching '[' in the same successor: brackets may not cross node boundaries");
          st = stack.back().first;
          pending = stack.back().second;
          stack.pop_back();
          break;
        case TurtleOp::Width: {
          const double w = param(0, st.width);
          if (!(w >= 0)) error("the width must be >= 0, got ", w);
          st.width = w;
          break;
        }
        case TurtleOp::Material: {
          const double i = m.count ? param(0, 0) : double(st.material) + 1.0;
          if (!(i >= 0 && i <= 2147483647.0 && i == std::floor(i)))
            error("the material index must be a whole number in [0, 2^31), got ", i);
          st.material = int32_t(i);
          break;
        }
        case TurtleOp::Sphere: {
          const double rad = std::fabs(param(0, 0.5 * st.width));
          if (rad > 0) emit(ShapeKind::Sphere, rad * st.l, rad * st.u, rad * st.h, st.p);
          break;
        }
        case TurtleOp::Cone: {
          const double len = param(0, step), rad = std::fabs(param(1, 0.5 * st.width));
          if (len != 0 && rad > 0) along(ShapeKind::Cone, len, rad);
          break;
        }
        case TurtleOp::Leaf: {
          const double len = param(0, step), w = std::fabs(param(1, 0.5 * len));
          if (len != 0 && w > 0) {
            const double half = 0.5 * len;
            emit(ShapeKind::Box, 0.5 * w * st.l, (std::fabs(len) / 100.0) * st.u, half * st.h, st.p + half * st.h);
          }
          break;
        }
        case TurtleOp::Box: {
          const double x = std::fabs(param(0, step));
          const double y = std::fabs(param(1, x)), z = std::fabs(param(2, x));
          if (x > 0 && y > 0 && z > 0) emit(ShapeKind::Box, 0.5 * x * st.l, 0.5 * y * st.u, 0.5 * z * st.h, st.p);
          break;
        }
      }
    }
    if (!stack.empty()) {
      index_in_successor = s.mods.size() - 1;
      error("'[' without a matching ']' in the same successor: brackets may not cross node boundaries");
    }
    r.end = st;
    r.end_variable = pending;
    return r;
  }

  void analyse(uint32_t id) {
    const size_t alts = classes[id].symbol == kRoot ? 1 : classes[id].alternatives.size();
    DVec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    uint64_t count = 0;
    bool path_dependent = alts > 1, variable = false;
    State first_end;
    for (size_t a = 0; a < alts; ++a) {
      const GraphNodeClass copy = classes[id];  // classes may grow while walking
      const Successor s = rewrite(copy, a);
      const WalkResult r = walk(copy, s, true, nullptr);
      grow(lo, hi, r.lo, r.hi);
      count = std::max(count, r.count);
      path_dependent = path_dependent || r.path_dependent;
      variable = variable || r.end_variable;
      if (a == 0) {
        first_end = r.end;
      } else if (!r.end.same(first_end)) {
        variable = true;
      }
    }
    GraphNodeClass& c = classes[id];
    c.lo = lo;
    c.hi = hi;
    c.max_primitives = count;
    c.path_dependent = path_dependent;
    end[id] = first_end;
    end_variable[id] = variable ? 1 : 0;
  }

  // ---- tracing ----

  std::shared_ptr<const GraphExpansion> expand(uint32_t cls, uint64_t key) const {
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
    const Successor s = rewrite(c, alt);
    const_cast<Impl*>(this)->walk(c, s, false, e.get());  // lookup only: no set-up state changes
    e->bytes = sizeof(GraphExpansion) + e->prims.capacity() * sizeof(GraphPrimitive) +
               e->children.capacity() * sizeof(GraphChild) + e->prims_before.capacity() * sizeof(uint32_t) + 64;
    return e;
  }

  std::shared_ptr<const GraphExpansion> get(Cache& cache, uint32_t cls, uint64_t path) const {
    const CacheKey key{cls, classes[cls].path_dependent ? path : 0};
    if (cache.memo.size() < classes.size()) cache.memo.resize(classes.size());
    Cache::Memo& memo = cache.memo[cls];
    if (memo.valid && memo.path == key.path) {  // the common case: no hashing
      ++cache.hits;
      if (memo.it != cache.lru.begin()) cache.lru.splice(cache.lru.begin(), cache.lru, memo.it);
      return memo.it->second;
    }
    const auto it = cache.map.find(key);
    if (it != cache.map.end()) {
      ++cache.hits;
      cache.lru.splice(cache.lru.begin(), cache.lru, it->second);
      memo = {true, key.path, it->second};
      return it->second->second;
    }
    ++cache.misses;
    auto e = expand(cls, path);
    cache.lru.emplace_front(key, e);
    cache.map.emplace(key, cache.lru.begin());
    memo = {true, key.path, cache.lru.begin()};
    cache.bytes += e->bytes;
    cache.peak = std::max(cache.peak, cache.bytes);
    while (cache.lru.size() > 1 && ((opt.cache_entries && cache.lru.size() > opt.cache_entries) ||
                                    (opt.cache_bytes && cache.bytes > opt.cache_bytes))) {
      const CacheKey gone = cache.lru.back().first;
      Cache::Memo& m = cache.memo[gone.cls];
      if (m.valid && m.path == gone.path) m.valid = false;
      cache.bytes -= cache.lru.back().second->bytes;
      cache.map.erase(gone);
      cache.lru.pop_back();
      ++cache.evictions;
    }
    return e;
  }

  struct Frame {
    std::shared_ptr<const GraphExpansion> e;
    DVec3 o, d;
    uint64_t key = 0;
    uint32_t cls = 0, next = 0, index = 0;
    const GraphChild* via = nullptr;
  };

  // Closest hit (hit != nullptr) or any hit (hit == nullptr) in [tnear, tfar).
  bool trace(DVec3 o, DVec3 d, double tnear, double tfar, GraphHit* hit) const {
    const GraphNodeClass& root = classes[0];
    if (!(tnear <= tfar) || !box_hit(root.lo, root.hi, o, d, tnear, tfar)) return false;
    Cache& cache = caches.local();
    std::array<Frame, kMaxGraphLevels + 1> frames;
    double best = tfar;
    bool found = false;
    csg::Crossing cr[csg::kMaxPrimitiveCrossings];
    // Tests the primitives of frame `top`; true to stop (occlusion found).
    auto prims = [&](int top) {
      const Frame& f = frames[size_t(top)];
      const auto& ps = f.e->prims;
      for (size_t i = 0; i < ps.size(); ++i) {
        const int n = csg::intersect(ps[i].prim, f.o, f.d, 0.0, cr);
        for (int k = 0; k < n; ++k) {
          const double t = cr[k].t;
          if (t < tnear) continue;
          if (t >= best) break;
          found = true;
          if (!hit) return true;
          best = t;
          hit->t = t;
          hit->shape = ps[i].shape;
          hit->material = ps[i].material;
          hit->prim = uint32_t(i);
          hit->levels = top;
          for (int lev = 0; lev <= top; ++lev) {
            hit->classes[lev] = frames[size_t(lev)].cls;
            if (lev > 0) hit->path[lev - 1] = frames[size_t(lev)].index;
          }
          hit->node_key = f.key;
          hit->instance_key = child_key(f.key, uint32_t(i));
          DVec3 nl = csg::normal(ps[i].prim, cr[k].face, f.o + t * f.d);
          for (int lev = top; lev > 0; --lev) nl = frames[size_t(lev)].via->to_local.transpose_vector(nl);
          hit->n = csg::normalize(nl);
          break;
        }
      }
      return false;
    };
    frames[0].e = get(cache, 0, root_key());
    frames[0].o = o;
    frames[0].d = d;
    frames[0].key = root_key();
    frames[0].cls = 0;
    frames[0].next = 0;
    int top = 0;
    if (prims(0)) return true;
    while (top >= 0) {
      Frame& f = frames[size_t(top)];
      const auto& ch = f.e->children;
      bool pushed = false;
      while (f.next < ch.size()) {
        const uint32_t i = f.next++;
        const GraphChild& c = ch[i];
        if (!box_hit(c.lo, c.hi, f.o, f.d, tnear, best)) continue;
        if (top + 1 > kMaxGraphLevels) {  // unreachable: levels are checked at set-up
          ++cache.truncated;
          continue;
        }
        Frame& g = frames[size_t(top + 1)];
        g.o = c.to_local.point(f.o);
        g.d = c.to_local.vector(f.d);
        g.key = child_key(f.key, i);
        g.cls = c.cls;
        g.index = i;
        g.next = 0;
        g.via = &c;
        g.e = get(cache, c.cls, g.key);
        ++top;
        if (prims(top)) return true;
        pushed = true;
        break;
      }
      if (!pushed) {
        frames[size_t(top)].e.reset();
        --top;
      }
    }
    return found;
  }

  uint64_t root_key() const { return splitmix64(opt.seed); }

  // level: child steps from the root; key_level < 0: no keys; stub: the
  // ancestor key at key_level inherited from above.
  void flatten(uint32_t cls, uint64_t key, const Affine& to_world, size_t cap, FlattenResult& out, int level = 0,
               int key_level = -1, uint64_t stub = 0) const {
    if (out.truncated) return;
    if (level <= key_level) stub = key;
    const auto e = get(caches.local(), cls, key);
    auto emit = [&](size_t from, size_t to) {
      for (size_t i = from; i < to; ++i) {
        if (out.primitives.size() >= cap) {
          out.truncated = true;
          return;
        }
        const GraphPrimitive& g = e->prims[i];
        TurtlePrimitive p;
        p.shape = g.shape;
        p.material = g.material;
        const Affine w = compose(to_world, g.prim.to_world);
        std::copy(w.m, w.m + 12, p.to_world);
        out.primitives.push_back(p);
        if (key_level >= 0) out.keys.push_back(stub);
      }
    };
    size_t done = 0;
    for (size_t i = 0; i < e->children.size() && !out.truncated; ++i) {
      emit(done, e->prims_before[i]);
      done = e->prims_before[i];
      if (out.truncated) return;
      flatten(e->children[i].cls, child_key(key, uint32_t(i)), compose(to_world, e->children[i].to_parent), cap, out,
              level + 1, key_level, stub);
    }
    if (!out.truncated) emit(done, e->prims.size());
  }
};

Graph::Graph(const LSystem& system, const GraphOptions& options) : impl_(std::make_unique<Impl>()) {
  Impl& g = *impl_;
  g.sys = system;
  g.opt = options;
  const GraphOptions& o = g.opt;
  g.step = o.step < 0 ? system.step : o.step;
  g.angle = o.angle < 0 ? system.angle : o.angle;
  g.width = o.width < 0 ? system.width : o.width;
  g.material = o.material;
  if (!std::isfinite(g.step) || !std::isfinite(g.angle) || !std::isfinite(g.width))
    fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: step, angle and width must be finite");
  if (g.material < 0) fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: the material index must be >= 0");
  if (o.max_levels < 1 || o.max_levels > kMaxGraphLevels)
    fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: max_levels must be in [1, ", kMaxGraphLevels, "], got ",
         o.max_levels);
  const int depth = o.depth >= 0 ? o.depth : system.depth;
  if (depth + 1 > o.max_levels)
    fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: depth ", depth, " needs ", depth + 1,
         " traversal levels, over the limit of ", o.max_levels,
         " (GraphOptions::max_levels); use the flattened path or a smaller depth");
  g.levels = depth + 1;
  size_t slots = 0;
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
    slots = std::max(slots, size_t(p.num_slots));
  }
  for (const ModuleTemplate& t : system.axiom)
    for (const int32_t a : t.args)
      if (uses_rand(system.nodes, a))
        fail(PLM_ERROR_INVALID_ARGUMENT, "line ", system.axiom_line, ": axiom: rand() needs the flattened path");
  g.vars.assign(slots + 1, 0.0);
  // The root: the axiom at depth D (its class depth is D + 1).
  GraphNodeClass root;
  root.symbol = kRoot;
  root.depth = depth + 1;
  root.width = g.width;
  root.material = g.material;
  g.classes.push_back(root);
  g.end.emplace_back();
  g.end_variable.push_back(0);
  g.analyse(0);
}

Graph::~Graph() = default;

bool Graph::first_hit(DVec3 o, DVec3 d, double tnear, double tfar, GraphHit* hit) const {
  return impl_->trace(o, d, tnear, tfar, hit);
}

bool Graph::occluded(DVec3 o, DVec3 d, double tnear, double tfar) const {
  return impl_->trace(o, d, tnear, tfar, nullptr);
}

DVec3 Graph::bounds_lo() const { return impl_->classes[0].lo; }
DVec3 Graph::bounds_hi() const { return impl_->classes[0].hi; }
const GraphNodeClass& Graph::node_class(uint32_t id) const { return impl_->classes.at(id); }
uint64_t Graph::root_key() const { return impl_->root_key(); }

uint64_t Graph::child_key(uint64_t key, uint32_t index) { return splitmix64(key ^ splitmix64(uint64_t(index) + 1)); }

uint64_t Graph::ancestor_key(const GraphHit& hit, int level) const {
  uint64_t k = root_key();
  for (int l = 0; l < std::min(level, hit.levels); ++l) k = child_key(k, hit.path[l]);
  return k;
}

GraphStats Graph::stats() const {
  const Impl& g = *impl_;
  GraphStats s;
  s.classes = g.classes.size();
  s.levels = g.levels;
  s.class_bytes = g.classes.size() * (sizeof(GraphNodeClass) + sizeof(State) + 96);
  for (const GraphNodeClass& c : g.classes)
    s.class_bytes += c.params.capacity() * 8 * 2 + c.alternatives.capacity() * sizeof(c.alternatives[0]);
  for (const Impl::Cache& c : g.caches) {
    s.cache_hits += c.hits;
    s.cache_misses += c.misses;
    s.evictions += c.evictions;
    s.cached_entries += c.lru.size();
    s.cached_bytes += c.bytes;
    s.peak_cached_bytes += c.peak;
    s.truncated += c.truncated;
  }
  s.flattened_primitives = g.classes[0].max_primitives;
  return s;
}

void Graph::reset_cache() const {
  for (Impl::Cache& c : impl_->caches) {
    c.lru.clear();
    c.map.clear();
    c.memo.clear();
    c.bytes = c.peak = 0;
    c.hits = c.misses = c.evictions = c.truncated = 0;
  }
}

FlattenResult Graph::flatten(size_t max_primitives) const {
  FlattenResult out;
  const Affine identity{{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
  impl_->flatten(0, root_key(), identity, max_primitives, out);
  return out;
}

FlattenResult Graph::flatten(size_t max_primitives, int key_level) const {
  if (key_level < 0) fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: flatten key level must be >= 0, got ", key_level);
  FlattenResult out;
  const Affine identity{{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
  impl_->flatten(0, root_key(), identity, max_primitives, out, 0, key_level, 0);
  return out;
}

const GraphHit& Graph::last_embree_hit() const { return impl_->caches.local().last_hit; }

// ---- Embree ----

namespace {

void graph_bounds(const RTCBoundsFunctionArguments* args) {
  const Graph& g = *static_cast<const Graph*>(args->geometryUserPtr);
  write_bounds(g.bounds_lo(), g.bounds_hi(), 0.0, args->bounds_o);
}

void graph_intersect(const RTCIntersectFunctionNArguments* args) {
  intersect_n<Graph>(args, [](const Graph& g) -> GraphHit& { return const_cast<GraphHit&>(g.last_embree_hit()); });
}

}  // namespace

unsigned attach_graph(RTCDevice device, RTCScene scene, const Graph& graph) {
  return attach_user_geometry(device, scene, &graph, graph_bounds, graph_intersect, occluded_n<Graph>);
}

}  // namespace plm::lsystem
