// L-system scene graph traced without flattening (lsystem/graph.h).
#include "lsystem/graph.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <array>
#include <atomic>
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
constexpr double kInfinity = std::numeric_limits<double>::infinity();
}  // namespace

// graph.h: csg::make_primitive without the check and the face areas.
csg::Primitive trace_primitive(const csg::PrimitiveDesc& desc) { return csg::make_primitive_without_areas(desc); }

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

// The exact box of a turtle primitive whose local->frame map is m: the
// extent along row r is sqrt(m0^2 + m1^2 + m2^2) for a sphere, sqrt(m0^2 +
// m1^2) + |m2| for a cylinder and a cone (by its cylinder hull, as the turtle
// bounds it), |m0| + |m1| + |m2| for a box. Not padded.
void prim_box(ShapeKind shape, const Affine& m, DVec3* lo, DVec3* hi) {
  for (int r = 0; r < 3; ++r) {
    const double e = primitive_extent(shape, m.m, r);
    (*lo)[r] = m.m[4 * r + 3] - e;
    (*hi)[r] = m.m[4 * r + 3] + e;
  }
}

// Pads a non-empty box by 1e-9 relative (as transform_box does).
void pad_box(DVec3& lo, DVec3& hi) {
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return;
  const double pad = 1e-9 * (max_abs(lo) + max_abs(hi)) + 1e-300;
  lo = lo - DVec3{pad, pad, pad};
  hi = hi + DVec3{pad, pad, pad};
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
  // Per class, per production: each child reference's box in the class frame.
  std::vector<std::vector<std::vector<GraphBox>>> child_boxes;
  // Set-up only (emptied after): per class, the primitives and child
  // references of all its productions, for the exact child bounds.
  struct SkeletonPrim {
    ShapeKind shape;
    Affine m;
  };
  struct SkeletonChild {
    uint32_t cls;
    Affine t;
  };
  struct Skeleton {
    std::vector<SkeletonPrim> prims;
    std::vector<SkeletonChild> children;
  };
  std::vector<std::vector<Skeleton>> skel;  // [class][production]
  // Per class, per production, per child, per production of the child: the
  // boxes of the child's children in the class frame (for inlining).
  std::vector<std::vector<std::vector<std::vector<std::vector<GraphBox>>>>> grand_boxes;
  uint64_t root_key_ = 0;
  DVec3 world_lo{kInf, kInf, kInf}, world_hi{-kInf, -kInf, -kInf};  // see Graph::world_bounds_lo()
  bool inline_views = true;  // see kGraphInlineMinCacheBytes

  // A level of the traversal: the node's expansion and the ray in its frame.
  struct Frame {
    const GraphExpansion* e = nullptr;
    DVec3 o, d, inv;                 // inv = 1 / d per component (+-inf for +-0)
    uint8_t near[3], far[3];         // per axis: the box coordinate met first / last (see slab)
    uint64_t key = 0;                // path key where the class is path dependent (and the root), else 0
    const GraphHop* via = nullptr;   // how the ray got here from the frame above (null at the root)
  };
  struct Pending {
    double t;                        // box entry along the ray
    uint32_t level, hop;             // hop `hop` of the node at `level`
  };

  // Per-thread LRU cache of expansions.
  struct Cache {
    struct Entry {
      CacheKey key;
      std::shared_ptr<const GraphExpansion> e;
      uint64_t stamp;                           // the traversal that last looked it up
    };
    std::list<Entry> lru;  // front: most recently used
    std::unordered_map<CacheKey, std::list<Entry>::iterator, CacheKeyHash> map;
    // Per class: the entry of its last lookup, found again without hashing
    // (a class that is not path dependent has one entry; valid until evicted).
    struct Memo {
      bool valid = false;
      uint64_t path = 0;
      std::list<Entry>::iterator it;
      uint64_t stamp = 0;                   // it->stamp, read without touching the list
      const GraphExpansion* e = nullptr;    // it->e.get()
      bool transient = false;               // e is in `transient`, not in the list (it is not valid)
      uint32_t freq = 0;                    // the class's recent lookups (see admit())
    };
    std::vector<Memo> memo;
    // Expansions that a full cache did not admit: held until the traversal ends.
    std::vector<std::pair<uint32_t, std::shared_ptr<const GraphExpansion>>> transient;
    uint64_t lookups = 0;                   // since the frequencies were last halved
    size_t bytes = 0, peak = 0;
    uint64_t hits = 0, misses = 0, evictions = 0, truncated = 0, bypassed = 0;
    GraphHit last_hit;
    // The running traversal (0: none): its entries are not evicted.
    uint64_t epoch = 0, tick = 0;
    std::vector<Frame> frames;      // kMaxGraphLevels + 1, one per level
    std::vector<Pending> pending;   // children still to visit, nearest at the back
  };
  mutable tbb::enumerable_thread_specific<Cache> caches;
  // Never reused, so a thread's remembered (id, cache) can only be this graph's.
  const uint64_t id = next_id();
  static uint64_t next_id() {
    static std::atomic<uint64_t> counter{0};
    return ++counter;
  }
  // The calling thread's cache: caches.local() (a hash lookup) once per thread and graph in a row.
  Cache& local_cache() const {
    struct Last {
      uint64_t id = 0;
      Cache* cache = nullptr;
    };
    static thread_local Last last;
    if (last.id != id) last = {id, &caches.local()};
    return *last.cache;
  }

  // A traversal's start and end: entries looked up in between stay until
  // end(), which trims the cache back to its capacity.
  void begin_trace(Cache& cache) const {
    cache.epoch = ++cache.tick;
    ready(cache);
    if (cache.frames.size() < size_t(kMaxGraphLevels) + 1) cache.frames.resize(size_t(kMaxGraphLevels) + 1);
    if (cache.pending.size() < 256) cache.pending.resize(256);
  }
  void ready(Cache& cache) const {
    if (cache.memo.size() < classes.size()) cache.memo.resize(classes.size());
  }
  void end_trace(Cache& cache) const {
    cache.epoch = 0;
    for (const auto& t : cache.transient) {
      Cache::Memo& m = cache.memo[t.first];
      if (m.transient) m = {false, 0, {}, 0, nullptr, false, m.freq};
    }
    cache.transient.clear();
    trim(cache);
  }
  // Admission (scan resistance): a miss is cached when the cache has room
  // for it, or when its class was looked up more often lately than the class
  // of the entry it would evict first; otherwise it is held for the running
  // traversal only. Plain LRU lets the many cold nodes deep in a plant push
  // out the nodes that most rays visit, once the working set exceeds the
  // cache (the tree of docs/benchmarks.md at 64 KiB). Frequencies count
  // lookups per class (hits and misses), halved every 16 lookups per class.
  bool admit(const Cache& cache, uint32_t cls, size_t bytes) const {
    const bool full = (opt.cache_bytes && cache.bytes + bytes > opt.cache_bytes) ||
                      (opt.cache_entries && cache.lru.size() + 1 > opt.cache_entries);
    if (!full || cache.lru.empty() || cache.lru.back().stamp == cache.epoch) return true;
    return cache.memo[cls].freq > cache.memo[cache.lru.back().key.cls].freq;
  }
  void count_lookup(Cache& cache, uint32_t cls) const {
    ++cache.memo[cls].freq;
    if (++cache.lookups >= 16 * uint64_t(cache.memo.size())) {
      for (Cache::Memo& m : cache.memo) m.freq >>= 1;
      cache.lookups = 0;
    }
  }
  bool over(const Cache& cache) const {
    return cache.lru.size() > 1 && ((opt.cache_entries && cache.lru.size() > opt.cache_entries) ||
                                    (opt.cache_bytes && cache.bytes > opt.cache_bytes));
  }
  // Evicts least recently used entries that the running traversal did not touch.
  void trim(Cache& cache) const {
    while (over(cache) && (cache.epoch == 0 || cache.lru.back().stamp != cache.epoch)) {
      const CacheKey gone = cache.lru.back().key;
      Cache::Memo& m = cache.memo[gone.cls];
      if (m.valid && m.path == gone.path) m.valid = false;
      cache.bytes -= cache.lru.back().e->bytes;
      cache.map.erase(gone);
      cache.lru.pop_back();
      ++cache.evictions;
    }
  }

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
    child_boxes.emplace_back();
    skel.emplace_back();
    grand_boxes.emplace_back();
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
  // id, alt: the class and the production walked (child boxes are recorded
  // per production at set-up and read back when expanding).
  WalkResult walk(const GraphNodeClass& owner_copy, uint32_t id, size_t alt, const Successor& s, bool setup,
                  GraphExpansion* out) {
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
      if (setup) {  // an expansion repeats a set-up walk of the same (class, production)
        const std::string why = csg::check_primitive(d);
        if (!why.empty()) error(why);
      }
      if (r.count < std::numeric_limits<uint64_t>::max()) ++r.count;
      Affine m;
      std::copy(d.to_world, d.to_world + 12, m.m);
      DVec3 blo, bhi;
      prim_box(shape, m, &blo, &bhi);
      pad_box(blo, bhi);
      if (setup) {
        grow(r.lo, r.hi, blo, bhi);
        skel[id][alt].prims.push_back({shape, m});
      } else {
        out->prims.push_back(GraphPrimitive{shape, st.material, trace_primitive(d)});
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
        if (setup) {
          const int64_t budget0 = int64_t(std::min<size_t>(opt.bounds_budget, size_t(INT64_MAX)));
          DVec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
          int64_t budget = budget0;
          subtree_box(cls, t, budget, lo, hi);
          pad_box(lo, hi);
          skel[id][alt].children.push_back({cls, t});
          child_boxes[id][alt].push_back({lo, hi});
          std::vector<std::vector<GraphBox>> grand(skel[cls].size());
          for (size_t a2 = 0; a2 < skel[cls].size(); ++a2)
            for (const SkeletonChild& gc : skel[cls][a2].children) {
              DVec3 glo{kInf, kInf, kInf}, ghi{-kInf, -kInf, -kInf};
              budget = budget0;
              subtree_box(gc.cls, compose(t, gc.t), budget, glo, ghi);
              pad_box(glo, ghi);
              grand[a2].push_back({glo, ghi});
            }
          grand_boxes[id][alt].push_back(std::move(grand));
          grow(r.lo, r.hi, lo, hi);
          r.count = cc.max_primitives > std::numeric_limits<uint64_t>::max() - r.count
                        ? std::numeric_limits<uint64_t>::max()
                        : r.count + cc.max_primitives;
          r.path_dependent = r.path_dependent || cc.path_dependent;
        } else {
          const GraphBox& b = child_boxes[id][alt][out->children.size()];
          out->children.push_back(GraphChild{cls, cc.path_dependent, t, csg::inverse(t), b.lo, b.hi});
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

  // The box, under a, of every primitive below class cls (see Bounds in
  // graph.h); where budget runs out, the class box mapped by a.
  void subtree_box(uint32_t cls, const Affine& a, int64_t& budget, DVec3& lo, DVec3& hi) const {
    const GraphNodeClass& c = classes[cls];
    if (!(c.lo.x <= c.hi.x && c.lo.y <= c.hi.y && c.lo.z <= c.hi.z)) return;  // draws nothing
    if (budget <= 0) {
      DVec3 l, h;
      transform_box(a, c.lo, c.hi, &l, &h);
      grow(lo, hi, l, h);
      return;
    }
    --budget;
    for (const Skeleton& k : skel[cls]) {
      for (const SkeletonPrim& p : k.prims) {
        DVec3 l, h;
        prim_box(p.shape, compose(a, p.m), &l, &h);
        grow(lo, hi, l, h);
      }
      for (const SkeletonChild& ch : k.children) subtree_box(ch.cls, compose(a, ch.t), budget, lo, hi);
    }
  }

  void analyse(uint32_t id) {
    const size_t alts = classes[id].symbol == kRoot ? 1 : classes[id].alternatives.size();
    child_boxes[id].assign(alts, {});
    skel[id].assign(alts, {});
    grand_boxes[id].assign(alts, {});
    DVec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    uint64_t count = 0;
    bool path_dependent = alts > 1, variable = false;
    State first_end;
    for (size_t a = 0; a < alts; ++a) {
      const GraphNodeClass copy = classes[id];  // classes may grow while walking
      const Successor s = rewrite(copy, a);
      const WalkResult r = walk(copy, id, a, s, true, nullptr);
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

  size_t choose_alt(uint32_t cls, uint64_t key) const {
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
    return alt;
  }

  // What the turtle draws for (cls, key): primitives and child references.
  std::shared_ptr<GraphExpansion> expand_base(uint32_t cls, uint64_t key, size_t* alt) const {
    const GraphNodeClass& c = classes[cls];
    *alt = choose_alt(cls, key);
    auto e = std::make_shared<GraphExpansion>();
    const Successor s = rewrite(c, *alt);
    const_cast<Impl*>(this)->walk(c, cls, *alt, s, false, e.get());  // lookup only: no set-up state changes
    return e;
  }

  static size_t bytes_of(const GraphExpansion& e) {
    return sizeof(GraphExpansion) + e.prims.capacity() * sizeof(GraphPrimitive) +
           e.children.capacity() * sizeof(GraphChild) + e.prims_before.capacity() * sizeof(uint32_t) +
           e.inlined_prims.capacity() * sizeof(GraphPrimitive) +
           e.tprims.capacity() * sizeof(GraphTracePrim) + e.prim_boxes.capacity() * sizeof(GraphBox) +
           e.hops.capacity() * sizeof(GraphHop) + e.hop_boxes.capacity() * sizeof(GraphBox) +
           e.groups.capacity() * sizeof(GraphGroup) + 64;
  }

  std::shared_ptr<const GraphExpansion> expand(uint32_t cls, uint64_t key) const {
    size_t alt = 0;
    std::shared_ptr<GraphExpansion> e = expand_base(cls, key, &alt);
    e->alt = uint32_t(alt);
    e->bytes = bytes_of(*e);
    return e;
  }

  // The traversal view of expansion e of (cls, key) (graph.h: small children
  // inlined, unless inline_views is off). Afterwards e holds only the view
  // (children and prims_before are released: the traversal reads hops).
  void build_view(GraphExpansion* e, uint32_t cls, uint64_t key) const {
    const size_t alt = e->alt;
    auto own_box = [](const GraphPrimitive& gp) {
      GraphBox b;
      prim_box(gp.shape, gp.prim.to_world, &b.lo, &b.hi);
      pad_box(b.lo, b.hi);
      return b;
    };
    for (size_t i = 0; i < e->prims.size(); ++i) {
      e->tprims.push_back({nullptr, nullptr, uint32_t(i), 0, 0});
      e->prim_boxes.push_back(own_box(e->prims[i]));
    }
    // A child's expansion, made here and dropped after (cached entries hold
    // views only; a miss is cheap: graph.h, trace_primitive).
    std::vector<std::shared_ptr<GraphExpansion>> made;
    std::vector<const GraphExpansion*> inlined(e->children.size(), nullptr);
    for (size_t k = 0; k < e->children.size(); ++k) {
      const GraphChild& ch = e->children[k];
      const uint64_t ck = ch.path_dependent ? child_key(key, uint32_t(k)) : 0;
      const GraphExpansion* ce = nullptr;
      if (inline_views) {
        size_t calt = 0;
        made.push_back(expand_base(ch.cls, ck, &calt));
        made.back()->alt = uint32_t(calt);
        ce = made.back().get();
      }
      if (ce && ce->prims.size() + ce->children.size() <= kGraphInlineItems) {
        inlined[k] = ce;
      } else {
        e->hops.push_back({ch.to_local, nullptr, ch.cls, ch.path_dependent, 1, {uint32_t(k), 0}, 0});
        e->hop_boxes.push_back({ch.lo, ch.hi});
      }
    }
    e->groups.push_back({GraphBox{}, uint32_t(e->tprims.size()), uint32_t(e->hops.size()), Affine{}});
    for (size_t k = 0; k < e->children.size(); ++k) {
      if (!inlined[k]) continue;
      const GraphChild& ch = e->children[k];
      const GraphExpansion& ce = *inlined[k];
      for (size_t j = 0; j < ce.prims.size(); ++j) {
        const GraphPrimitive& cp = ce.prims[j];
        e->inlined_prims.push_back(cp);
        e->tprims.push_back({nullptr, nullptr, uint32_t(j), uint32_t(k), ch.cls});
        GraphBox b;  // in this node's frame
        prim_box(cp.shape, compose(ch.to_parent, cp.prim.to_world), &b.lo, &b.hi);
        pad_box(b.lo, b.hi);
        e->prim_boxes.push_back(b);
      }
      const std::vector<GraphBox>& gb = grand_boxes[cls][alt][k][ce.alt];
      for (size_t kk = 0; kk < ce.children.size(); ++kk) {
        const GraphChild& gc = ce.children[kk];
        e->hops.push_back({gc.to_local, nullptr, gc.cls, gc.path_dependent, 2, {uint32_t(k), uint32_t(kk)}, ch.cls});
        e->hop_boxes.push_back(gb[kk]);
      }
      e->groups.push_back({GraphBox{ch.lo, ch.hi}, uint32_t(e->tprims.size()), uint32_t(e->hops.size()), ch.to_local});
    }
    e->inlined_prims.shrink_to_fit();
    e->tprims.shrink_to_fit();
    e->prim_boxes.shrink_to_fit();
    e->hops.shrink_to_fit();
    e->hop_boxes.shrink_to_fit();
    e->groups.shrink_to_fit();
    std::vector<GraphChild>().swap(e->children);
    std::vector<uint32_t>().swap(e->prims_before);
    // The vectors are final: point the trace primitives and hops at their primitives and groups.
    const uint32_t own = e->groups[0].prim_end;
    for (size_t g = 1, i = own, h = e->groups[0].hop_end; g < e->groups.size(); ++g) {
      for (; i < e->groups[g].prim_end; ++i) e->tprims[i].mid = &e->groups[g].to_child;
      for (; h < e->groups[g].hop_end; ++h) e->hops[h].mid = &e->groups[g].to_child;
    }
    for (size_t i = 0; i < e->tprims.size(); ++i)
      e->tprims[i].gp = i < own ? &e->prims[e->tprims[i].prim] : &e->inlined_prims[i - own];
    e->has_view = true;
    e->bytes = bytes_of(*e);
  }

  // The cache entry of (cls, path), expanded on a miss; stamped with the
  // running traversal. Recency is kept per traversal: an entry moves to the
  // front of the LRU list at its first lookup in a traversal only.
  const std::shared_ptr<const GraphExpansion>& get(Cache& cache, uint32_t cls, uint64_t path,
                                                   bool path_dependent) const {
    const CacheKey key{cls, path_dependent ? path : 0};
    Cache::Memo& memo = cache.memo[cls];
    count_lookup(cache, cls);
    if (memo.valid && !memo.transient && memo.path == key.path) {  // the common case: no hashing
      ++cache.hits;
      if (memo.stamp != cache.epoch || cache.epoch == 0) {
        memo.it->stamp = memo.stamp = cache.epoch;
        if (memo.it != cache.lru.begin()) cache.lru.splice(cache.lru.begin(), cache.lru, memo.it);
      }
      return memo.it->e;
    }
    const auto it = cache.map.find(key);
    if (it != cache.map.end()) {
      ++cache.hits;
      it->second->stamp = cache.epoch;
      cache.lru.splice(cache.lru.begin(), cache.lru, it->second);
      memo = {true, key.path, it->second, cache.epoch, it->second->e.get(), false, memo.freq};
      return it->second->e;
    }
    ++cache.misses;
    std::shared_ptr<const GraphExpansion> e = expand(cls, path);
    if (cache.epoch != 0 && !admit(cache, cls, e->bytes)) {
      ++cache.bypassed;
      cache.transient.emplace_back(cls, std::move(e));
      memo = {true, key.path, {}, cache.epoch, cache.transient.back().second.get(), true, memo.freq};
      return cache.transient.back().second;
    }
    cache.lru.push_front(Cache::Entry{key, std::move(e), cache.epoch});
    cache.map.emplace(key, cache.lru.begin());
    memo = {true, key.path, cache.lru.begin(), cache.epoch, cache.lru.front().e.get(), false, memo.freq};
    cache.bytes += cache.lru.front().e->bytes;
    cache.peak = std::max(cache.peak, cache.bytes);
    trim(cache);  // never evicts the new entry: it carries the running traversal's stamp
    return cache.lru.front().e;
  }

  // get() for the traversal: the expansion itself, without touching the list
  // when the class's memo already holds this traversal's entry.
  const GraphExpansion* find(Cache& cache, uint32_t cls, uint64_t path, bool path_dependent) const {
    const Cache::Memo& memo = cache.memo[cls];
    if (memo.stamp == cache.epoch && memo.valid && memo.path == (path_dependent ? path : 0)) {
      ++cache.hits;
      return memo.e;
    }
    GraphExpansion* e = const_cast<GraphExpansion*>(get(cache, cls, path, path_dependent).get());
    if (!e->has_view) {  // the thread's own entry: no other thread sees it
      const size_t before = e->bytes;
      build_view(e, cls, path);
      if (!cache.memo[cls].transient) {
        cache.bytes = cache.bytes - before + e->bytes;
        cache.peak = std::max(cache.peak, cache.bytes);
      }
    }
    return e;
  }

  // Slab test of the box (lo, hi) against the ray of frame f over [t0, t1];
  // true with *entry = the entry t if they meet. A zero direction component
  // gives 0 * inf = NaN on a slab's boundary, which leaves the range as it is
  // (the closed slab contains the ray); an empty box (lo > hi) never meets.
  // The frame's near[a] / far[a] pick lo or hi by the sign of inv[a].
  static bool slab(const GraphBox& box, const Frame& f, double t0, double t1, double* entry) {
    const double* b = &box.lo.x;  // lo.x lo.y lo.z hi.x hi.y hi.z
    static_assert(sizeof(GraphBox) == 6 * sizeof(double), "GraphBox is two DVec3");
    const double nx = (b[f.near[0]] - f.o.x) * f.inv.x, fx = (b[f.far[0]] - f.o.x) * f.inv.x;
    const double ny = (b[f.near[1]] - f.o.y) * f.inv.y, fy = (b[f.far[1]] - f.o.y) * f.inv.y;
    const double nz = (b[f.near[2]] - f.o.z) * f.inv.z, fz = (b[f.far[2]] - f.o.z) * f.inv.z;
    if (nx > t0) t0 = nx;
    if (ny > t0) t0 = ny;
    if (nz > t0) t0 = nz;
    if (fx < t1) t1 = fx;
    if (fy < t1) t1 = fy;
    if (fz < t1) t1 = fz;
    *entry = t0;
    return t0 <= t1;
  }

  static void set_ray(Frame& f, DVec3 o, DVec3 d) {
    f.o = o;
    f.d = d;
    f.inv = DVec3{1.0 / d.x, 1.0 / d.y, 1.0 / d.z};
    for (int a = 0; a < 3; ++a) {
      const bool neg = f.inv[a] < 0;  // -0 gives -inf: negative
      f.near[a] = uint8_t(neg ? 3 + a : a);
      f.far[a] = uint8_t(neg ? a : 3 + a);
    }
  }

  // Closest hit (hit != nullptr) or any hit (hit == nullptr) in [tnear, tfar).
  bool trace(DVec3 o, DVec3 d, double tnear, double tfar, GraphHit* hit) const {
    const GraphNodeClass& root = classes[0];
    if (!(tnear <= tfar) || !box_hit(root.lo, root.hi, o, d, tnear, tfar)) return false;
    Cache& cache = local_cache();
    begin_trace(cache);
    Frame* frames = cache.frames.data();
    // Hops still to enter, nearest at the back: a per-thread array that only
    // grows (written field by field: no store-forwarding stalls).
    Pending* pend = cache.pending.data();
    size_t npend = 0;
    double best = tfar;
    bool found = false;
    // The closest hit so far; the hit record is made once at the end.
    const GraphTracePrim* hit_tp = nullptr;
    int hit_level = 0, hit_face = 0;
    DVec3 hit_p;  // in the hit primitive's frame
    const GraphHop* hit_via[kMaxGraphLevels + 1];
    csg::Crossing cr[csg::kMaxPrimitiveCrossings];
    // Tests the primitives of the node at `level` and queues the hops that
    // the ray meets before `best`, nearest last; true to stop (occlusion found).
    auto visit = [&](int level) {
      const Frame& f = frames[level];
      const GraphExpansion& e = *f.e;
      const size_t nh = e.hops.size();
      if (npend + nh > cache.pending.size()) {
        cache.pending.resize(2 * (npend + nh));
        pend = cache.pending.data();
      }
      const size_t first = npend;
      const GraphBox* pboxes = e.prim_boxes.data();
      const GraphBox* hboxes = e.hop_boxes.data();
      uint32_t p = 0, h = 0;
      for (size_t gi = 0; gi < e.groups.size(); ++gi) {
        const GraphGroup& grp = e.groups[gi];
        double entry;
        if (gi > 0 && !slab(grp.box, f, tnear, best, &entry)) {
          p = grp.prim_end;
          h = grp.hop_end;
          continue;
        }
        DVec3 co = f.o, cd = f.d;  // the ray in the primitives' frame (an inlined child's: made when needed)
        bool mapped = gi == 0;
        for (; p < grp.prim_end; ++p) {
          if (!slab(pboxes[p], f, tnear, best, &entry)) continue;
          const GraphTracePrim& tp = e.tprims[p];
          if (!mapped) {
            co = grp.to_child.point(f.o);
            cd = grp.to_child.vector(f.d);
            mapped = true;
          }
          const int n = csg::intersect(tp.gp->prim, co, cd, 0.0, cr);
          for (int k = 0; k < n; ++k) {
            const double t = cr[k].t;
            if (t < tnear) continue;
            if (t >= best) break;
            found = true;
            if (!hit) return true;
            best = t;
            hit_tp = &tp;
            hit_level = level;
            hit_face = cr[k].face;
            hit_p = co + t * cd;
            for (int lev = 1; lev <= level; ++lev) hit_via[lev] = frames[lev].via;
            break;
          }
        }
        for (; h < grp.hop_end; ++h) {
          if (!slab(hboxes[h], f, tnear, best, &entry)) continue;
          // Insertion into this node's queued run, kept sorted with the nearest at the back.
          size_t j = npend++;
          while (j > first && pend[j - 1].t < entry) {
            pend[j].t = pend[j - 1].t;
            pend[j].level = pend[j - 1].level;
            pend[j].hop = pend[j - 1].hop;
            --j;
          }
          pend[j].t = entry;
          pend[j].level = uint32_t(level);
          pend[j].hop = h;
        }
      }
      return false;
    };
    Frame& f0 = frames[0];
    f0.e = find(cache, 0, root_key_, classes[0].path_dependent);
    set_ray(f0, o, d);
    f0.key = root_key_;
    f0.via = nullptr;
    bool stop = visit(0);
    while (!stop && npend > 0) {
      --npend;
      const double pt = pend[npend].t;
      const uint32_t plevel = pend[npend].level, phop = pend[npend].hop;
      if (pt > best) continue;  // a closer hit was found after it was queued
      const Frame& f = frames[plevel];
      const int level = int(plevel) + 1;
      if (level > kMaxGraphLevels) {  // unreachable: a frame is at least one derivation step
        ++cache.truncated;
        continue;
      }
      const GraphHop& c = f.e->hops[phop];
      Frame& g = frames[level];
      if (c.mid) {  // through the inlined child's frame, as without inlining
        const DVec3 mo = c.mid->point(f.o), md = c.mid->vector(f.d);
        set_ray(g, c.to_local.point(mo), c.to_local.vector(md));
      } else {
        set_ray(g, c.to_local.point(f.o), c.to_local.vector(f.d));
      }
      uint64_t key = 0;
      if (c.path_dependent) {  // then so are the nodes above it
        key = f.key;
        if (c.steps == 2) key = child_key(key, c.index[0]);
        key = child_key(key, c.index[c.steps - 1]);
      }
      g.key = key;
      g.via = &c;
      g.e = find(cache, c.cls, key, c.path_dependent);
      stop = visit(level);
    }
    if (found && hit) {
      const GraphTracePrim& tp = *hit_tp;
      int lv = 0;  // derivation steps from the root
      hit->classes[0] = 0;
      for (int lev = 1; lev <= hit_level; ++lev) {
        const GraphHop& v = *hit_via[lev];
        if (v.steps == 2) {
          hit->path[lv] = v.index[0];
          hit->classes[++lv] = v.mid_cls;
        }
        hit->path[lv] = v.index[v.steps - 1];
        hit->classes[++lv] = v.cls;
      }
      if (tp.mid) {
        hit->path[lv] = tp.child;
        hit->classes[++lv] = tp.child_cls;
      }
      hit->t = best;
      hit->levels = lv;
      hit->shape = tp.gp->shape;
      hit->material = tp.gp->material;
      hit->prim = tp.prim;
      DVec3 nl = csg::normal(tp.gp->prim, hit_face, hit_p);
      if (tp.mid) nl = tp.mid->transpose_vector(nl);
      for (int lev = hit_level; lev > 0; --lev) {
        nl = hit_via[lev]->to_local.transpose_vector(nl);
        if (hit_via[lev]->mid) nl = hit_via[lev]->mid->transpose_vector(nl);
      }
      hit->n = csg::normalize(nl);
      hit->node_key = ancestor_key(*hit, hit->levels);
      hit->instance_key = child_key(hit->node_key, hit->prim);
    }
    end_trace(cache);
    return found;
  }

  uint64_t root_key() const { return root_key_; }
  uint64_t ancestor_key(const GraphHit& hit, int level) const {
    uint64_t k = root_key_;
    for (int l = 0; l < std::min(level, hit.levels); ++l) k = Graph::child_key(k, hit.path[l]);
    return k;
  }


  // level: child steps from the root; key_level < 0: no keys; stub: the
  // ancestor key at key_level inherited from above.
  // memo: per class, its expansion where the class is not path dependent
  // (flatten() keeps its own expansions: cached entries hold only the
  // traversal view, see find()).
  void flatten(uint32_t cls, uint64_t key, const Affine& to_world, size_t cap, FlattenResult& out,
               std::vector<std::shared_ptr<const GraphExpansion>>& memo, int level = 0, int key_level = -1,
               uint64_t stub = 0) const {
    if (out.truncated) return;
    if (level <= key_level) stub = key;
    std::shared_ptr<const GraphExpansion> e;
    if (classes[cls].path_dependent) {
      e = expand(cls, key);
    } else {
      if (!memo[cls]) memo[cls] = expand(cls, 0);
      e = memo[cls];
    }
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
              memo, level + 1, key_level, stub);
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
  g.root_key_ = splitmix64(o.seed);
  g.inline_views = o.cache_bytes == 0 || o.cache_bytes >= kGraphInlineMinCacheBytes;
  // The root: the axiom at depth D (its class depth is D + 1).
  GraphNodeClass root;
  root.symbol = kRoot;
  root.depth = depth + 1;
  root.width = g.width;
  root.material = g.material;
  g.classes.push_back(root);
  g.end.emplace_back();
  g.end_variable.push_back(0);
  g.child_boxes.emplace_back();
  g.skel.emplace_back();
  g.grand_boxes.emplace_back();
  g.analyse(0);
  int64_t budget = int64_t(std::min<size_t>(o.bounds_budget, size_t(INT64_MAX)));
  g.subtree_box(0, o.world, budget, g.world_lo, g.world_hi);
  pad_box(g.world_lo, g.world_hi);
  g.skel = {};  // set-up only
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
DVec3 Graph::world_bounds_lo() const { return impl_->world_lo; }
DVec3 Graph::world_bounds_hi() const { return impl_->world_hi; }
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
    s.bypassed += c.bypassed;
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
    c.transient.clear();
    c.lookups = 0;
    c.hits = c.misses = c.evictions = c.truncated = c.bypassed = 0;
  }
}

FlattenResult Graph::flatten(size_t max_primitives) const {
  FlattenResult out;
  const Affine identity{{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
  std::vector<std::shared_ptr<const GraphExpansion>> memo(impl_->classes.size());
  impl_->flatten(0, root_key(), identity, max_primitives, out, memo);
  return out;
}

FlattenResult Graph::flatten(size_t max_primitives, int key_level) const {
  if (key_level < 0) fail(PLM_ERROR_INVALID_ARGUMENT, "lsystem graph: flatten key level must be >= 0, got ", key_level);
  FlattenResult out;
  const Affine identity{{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
  std::vector<std::shared_ptr<const GraphExpansion>> memo(impl_->classes.size());
  impl_->flatten(0, root_key(), identity, max_primitives, out, memo, 0, key_level, 0);
  return out;
}

const GraphHit& Graph::last_embree_hit() const { return impl_->local_cache().last_hit; }

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
