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

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "lsystem/embree_callbacks.h"
#include "lsystem/expr.h"
#include "util/error.h"
#include "util/rng.h"

namespace plm::lsystem {

using csg::Affine;
using csg::DVec3;

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

// v as a float rounded toward -inf / +inf (out of range: -inf / FLT_MAX, -FLT_MAX / +inf).
inline float float_down(double v) {
  float f = float(v);
  if (double(f) > v) {  // f is not -inf; f == -0 only for v < 0
    uint32_t b;
    std::memcpy(&b, &f, sizeof b);
    b = f > 0 ? b - 1 : b + 1;
    std::memcpy(&f, &b, sizeof b);
  }
  return f;
}
inline float float_up(double v) {
  float f = float(v);
  if (double(f) < v) {  // f is not +inf and not -0
    uint32_t b;
    std::memcpy(&b, &f, sizeof b);
    b = f >= 0 ? b + 1 : b - 1;
    std::memcpy(&f, &b, sizeof b);
  }
  return f;
}

// A view item's box (double, padded) for the clusters; ref: its item index.
struct ViewItem {
  DVec3 lo, hi;
  double c[3];  // centroid
  uint32_t ref;
};

double half_area(DVec3 lo, DVec3 hi) {
  const DVec3 e = hi - lo;
  return e.x * e.y + e.y * e.z + e.z * e.x;
}

// Reorders it[0, n) (n >= 2) along the axis and at the split of least
// surface area heuristic cost (centroid order); returns the size of the left part.
size_t sah_split(ViewItem* it, size_t n, std::vector<double>& right_area) {
  double best = kInf;
  int best_axis = 0;
  size_t best_m = n / 2;
  right_area.resize(n + 1);
  for (int a = 0; a < 3; ++a) {
    std::sort(it, it + n, [a](const ViewItem& x, const ViewItem& y) {
      return x.c[a] < y.c[a] || (x.c[a] == y.c[a] && x.ref < y.ref);
    });
    DVec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    for (size_t i = n; i > 0; --i) {
      grow(lo, hi, it[i - 1].lo, it[i - 1].hi);
      right_area[i - 1] = half_area(lo, hi);
    }
    lo = {kInf, kInf, kInf};
    hi = {-kInf, -kInf, -kInf};
    for (size_t m = 1; m < n; ++m) {
      grow(lo, hi, it[m - 1].lo, it[m - 1].hi);
      const double cost = half_area(lo, hi) * double(m) + right_area[m] * double(n - m);
      if (cost < best) {
        best = cost;
        best_axis = a;
        best_m = m;
      }
    }
  }
  if (best_axis != 2)
    std::sort(it, it + n, [best_axis](const ViewItem& x, const ViewItem& y) {
      return x.c[best_axis] < y.c[best_axis] || (x.c[best_axis] == y.c[best_axis] && x.ref < y.ref);
    });
  return best_m;
}

GraphBoxes4 empty_boxes4() {
  GraphBoxes4 b;
  for (int a = 0; a < 3; ++a)
    for (int l = 0; l < 4; ++l) {
      b.lo[a][l] = std::numeric_limits<float>::infinity();
      b.hi[a][l] = -std::numeric_limits<float>::infinity();
    }
  return b;
}

// Sets lane l of b to (lo, hi) rounded outward (lo > hi: left empty).
void set_lane(GraphBoxes4& b, int l, DVec3 lo, DVec3 hi) {
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return;
  for (int a = 0; a < 3; ++a) {
    b.lo[a][l] = float_down(lo[a]);
    b.hi[a][l] = float_up(hi[a]);
  }
}

// Splits it[0, n) by SAH until at most four items are left: each such part
// becomes a cluster and its box the cluster's lane in boxes (cluster c: block
// c / 4, lane c % 4).
void build_clusters(std::vector<GraphCluster>& clusters, std::vector<GraphBoxes4>& boxes, ViewItem* it, size_t n,
                    std::vector<double>& scratch) {
  if (n > 4) {
    const size_t m = sah_split(it, n, scratch);
    build_clusters(clusters, boxes, it, m, scratch);
    build_clusters(clusters, boxes, it + m, n - m, scratch);
    return;
  }
  GraphCluster c;
  c.box = empty_boxes4();
  DVec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
  for (int l = 0; l < 4; ++l) {
    c.item[l] = std::numeric_limits<uint32_t>::max();
    if (size_t(l) >= n) continue;
    c.item[l] = it[l].ref;
    set_lane(c.box, l, it[l].lo, it[l].hi);
    grow(lo, hi, it[l].lo, it[l].hi);
  }
  if (clusters.size() % 4 == 0) boxes.push_back(empty_boxes4());
  set_lane(boxes.back(), int(clusters.size() % 4), lo, hi);
  clusters.push_back(c);
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
  // A child reference's exact subtree box in the class frame and, for
  // inlining, the subtree boxes of its descendants down to kGraphInlineDepth - 1
  // further steps, also in the class frame: sub[production of the child][its
  // child] (empty where the child is not small enough to be inlined, see
  // kGraphInlineItems, or the set-up's allowance of such boxes ran out).
  struct DescBoxes {
    GraphBox box;
    std::vector<std::vector<DescBoxes>> sub;
  };
  std::vector<std::vector<std::vector<DescBoxes>>> child_desc;  // [class][production][child]
  // Set-up only: per class, the DescBoxes a reference's boxes down L steps
  // would take (the union over productions; saturating), for L < kGraphInlineDepth.
  std::vector<std::array<uint64_t, kGraphInlineDepth>> desc_nodes;
  size_t desc_left = size_t(1) << 20;  // sub-level boxes the set-up may still make
  int64_t bounds_budget = 0;           // GraphOptions::bounds_budget (capped to int64)
  int64_t bounds_total = 0;            // GraphOptions::bounds_total (capped to int64)
  int64_t bounds_visits = 0;           // nodes the set-up's unfoldings visited so far
  size_t desc_count = 0;               // DescBoxes made (for GraphStats::class_bytes)
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
  uint64_t root_key_ = 0;
  DVec3 world_lo{kInf, kInf, kInf}, world_hi{-kInf, -kInf, -kInf};  // see Graph::world_bounds_lo()
  bool inline_views = true;  // see kGraphInlineMinCacheBytes

  // A level of the traversal: the node's expansion and the ray in its frame.
  struct Frame {
    const GraphExpansion* e = nullptr;
    DVec3 o, d;
    // The ray for the float box tests (see boxes4), per axis (x, y, z, unused):
    // 1 / d and the origin moved down or up so that the near and the far slab
    // distances err outward.
    alignas(16) float inv[4], on[4], of[4];
    uint8_t near[3], far[3];         // per axis: the float offset in a GraphBoxes4 of the side met first / last
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
    // build_view's scratch (a miss allocates only what the entry keeps).
    std::vector<GraphBox> prim_boxes, hop_boxes;
    std::vector<ViewItem> items;
    std::vector<double> areas;
    std::vector<GraphCluster> clusters;
    std::vector<GraphBoxes4> cluster_boxes;
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
  // Recency is kept (entries moved to the front of the list) only once the
  // cache is half full: below that nothing is evicted soon, and a move per
  // entry and ray was ~4 % of a ray's cost; the entries touched meanwhile keep
  // their insertion order.
  bool half_full(const Cache& cache) const {
    return (opt.cache_entries && 2 * cache.lru.size() >= opt.cache_entries) ||
           (opt.cache_bytes && 2 * cache.bytes >= opt.cache_bytes);
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
    child_desc.emplace_back();
    skel.emplace_back();
    desc_nodes.emplace_back();
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
          skel[id][alt].children.push_back({cls, t});
          const int64_t given = std::min(bounds_budget, bounds_total - bounds_visits);
          int64_t budget = given;
          int levels = kGraphInlineDepth - 1;  // as deep as kGraphInlineDescBoxes allow
          while (levels > 0 && desc_nodes[cls][levels] > kGraphInlineDescBoxes) --levels;
          DescBoxes d = desc_boxes(cls, t, levels, budget);
          bounds_visits += given - budget;
          pad_box(d.box.lo, d.box.hi);
          grow(r.lo, r.hi, d.box.lo, d.box.hi);
          child_desc[id][alt].push_back(std::move(d));
          r.count = cc.max_primitives > std::numeric_limits<uint64_t>::max() - r.count
                        ? std::numeric_limits<uint64_t>::max()
                        : r.count + cc.max_primitives;
          r.path_dependent = r.path_dependent || cc.path_dependent;
        } else {
          const GraphBox& b = child_desc[id][alt][out->children.size()].box;
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

  // Can a view inline class cls (set-up: every production small enough)?
  bool inlinable(uint32_t cls) const {
    for (const Skeleton& k : skel[cls])
      if (k.prims.size() + k.children.size() > kGraphInlineItems) return false;
    return true;
  }

  // A child reference's DescBoxes (see child_desc): class cls under a, with
  // its descendants' boxes `levels` steps deep, all from one unfolding of at
  // most `budget` nodes (see subtree_box). Boxes are left unpadded (the
  // parent grows by them); a descendant's box is padded once it is placed.
  DescBoxes desc_boxes(uint32_t cls, const Affine& a, int levels, int64_t& budget) {
    DescBoxes d;
    ++desc_count;
    d.box = {{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}};
    size_t n = 0;
    for (const Skeleton& k : skel[cls]) n += k.children.size();
    if (levels <= 0 || !inlinable(cls) || n > desc_left) {
      subtree_box(cls, a, budget, d.box.lo, d.box.hi);
      return d;
    }
    desc_left -= n;
    const bool exact = budget > 0;
    if (exact)
      --budget;
    else
      subtree_box(cls, a, budget, d.box.lo, d.box.hi);  // budget spent: the class box mapped
    d.sub.resize(skel[cls].size());
    for (size_t a2 = 0; a2 < skel[cls].size(); ++a2) {
      if (exact)
        for (const SkeletonPrim& p : skel[cls][a2].prims) {
          DVec3 l, h;
          prim_box(p.shape, compose(a, p.m), &l, &h);
          grow(d.box.lo, d.box.hi, l, h);
        }
      for (const SkeletonChild& gc : skel[cls][a2].children) {
        DescBoxes c = desc_boxes(gc.cls, compose(a, gc.t), levels - 1, budget);
        if (exact) grow(d.box.lo, d.box.hi, c.box.lo, c.box.hi);
        pad_box(c.box.lo, c.box.hi);
        d.sub[a2].push_back(std::move(c));
      }
    }
    return d;
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
    child_desc[id].assign(alts, {});
    skel[id].assign(alts, {});
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
    std::array<uint64_t, kGraphInlineDepth>& dn = desc_nodes[id];
    dn.fill(1);
    for (int l = 1; l < kGraphInlineDepth && inlinable(id); ++l)  // else no boxes below it
      for (const Skeleton& k : skel[id])
        for (const SkeletonChild& ch : k.children) dn[l] = std::min(dn[l] + desc_nodes[ch.cls][l - 1], uint64_t(1) << 62);
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
           e.tprims.capacity() * sizeof(GraphTracePrim) + e.clusters.capacity() * sizeof(GraphCluster) +
           e.cluster_boxes.capacity() * sizeof(GraphBoxes4) +
           e.hops.capacity() * sizeof(GraphHop) + 64;
  }

  std::shared_ptr<const GraphExpansion> expand(uint32_t cls, uint64_t key) const {
    size_t alt = 0;
    std::shared_ptr<GraphExpansion> e = expand_base(cls, key, &alt);
    e->alt = uint32_t(alt);
    e->bytes = bytes_of(*e);
    return e;
  }

  // The traversal view of expansion e of (cls, key) (graph.h: small
  // descendants inlined, breadth first, unless inline_views is off).
  // Afterwards e holds only the view (children and prims_before are
  // released: the traversal reads hops).
  void build_view(Cache& cache, GraphExpansion* e, uint32_t cls, uint64_t key) const {
    const Affine identity{{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
    std::vector<GraphBox>& prim_boxes = cache.prim_boxes;  // per tprim / hop, in this node's frame
    std::vector<GraphBox>& hop_boxes = cache.hop_boxes;
    prim_boxes.clear();
    hop_boxes.clear();
    e->tprims.reserve(e->prims.size());  // enough without inlining
    e->hops.reserve(e->children.size());
    for (size_t i = 0; i < e->prims.size(); ++i) {
      GraphTracePrim tp{};
      tp.prim = uint32_t(i);
      e->tprims.push_back(tp);
      GraphBox b;
      prim_box(e->prims[i].shape, e->prims[i].prim.to_world, &b.lo, &b.hi);
      pad_box(b.lo, b.hi);
      prim_boxes.push_back(b);
    }
    // This node and its inlined descendants, whose children are still to be
    // placed; a descendant's expansion is made here and dropped after (cached
    // entries hold views only; a miss is cheap: graph.h, trace_primitive).
    struct Node {
      const GraphExpansion* x;
      const std::vector<DescBoxes>* desc;  // x's children's boxes, in this node's frame
      Affine to_node;                      // x's frame -> this node's
      Affine from_node;                    // this node's frame -> x's
      uint64_t key;
      uint8_t steps;
      uint32_t path[kGraphInlineDepth], classes[kGraphInlineDepth];
    };
    std::vector<std::shared_ptr<GraphExpansion>> made;
    std::vector<Node> queue(1);
    queue[0].x = e;
    queue[0].desc = &child_desc[cls][e->alt];
    queue[0].to_node = identity;
    queue[0].from_node = identity;
    queue[0].key = key;
    queue[0].steps = 0;
    size_t planned = e->prims.size() + e->children.size();  // primitives and hops of the view so far
    for (size_t qi = 0; qi < queue.size(); ++qi) {
      const Node nd = queue[qi];  // a copy: the queue grows
      for (size_t k = 0; k < nd.x->children.size(); ++k) {
        const GraphChild& ch = nd.x->children[k];
        const DescBoxes& db = (*nd.desc)[k];
        const uint64_t ck = ch.path_dependent ? child_key(nd.key, uint32_t(k)) : 0;
        Node c = nd;
        c.steps = uint8_t(nd.steps + 1);
        c.path[nd.steps] = uint32_t(k);
        c.classes[nd.steps] = ch.cls;
        if (inline_views && c.steps < kGraphInlineDepth && !db.sub.empty()) {
          size_t calt = 0;
          std::shared_ptr<GraphExpansion> ce = expand_base(ch.cls, ck, &calt);
          const size_t items = ce->prims.size() + ce->children.size();
          if (items <= kGraphInlineItems && planned + items - 1 <= kGraphInlineViewItems) {
            planned += items - 1;
            ce->alt = uint32_t(calt);
            c.x = ce.get();
            c.desc = &db.sub[calt];
            c.to_node = compose(nd.to_node, ch.to_parent);
            c.from_node = compose(ch.to_local, nd.from_node);
            c.key = ck;
            for (size_t j = 0; j < ce->prims.size(); ++j) {
              const GraphPrimitive& cp = ce->prims[j];
              const Affine w = compose(c.to_node, cp.prim.to_world);  // placed in this node's frame
              csg::PrimitiveDesc d;
              d.shape = csg_shape(cp.shape);
              std::copy(w.m, w.m + 12, d.to_world);
              e->inlined_prims.push_back(GraphPrimitive{cp.shape, cp.material, trace_primitive(d)});
              GraphTracePrim tp{};
              tp.prim = uint32_t(j);
              tp.steps = c.steps;
              std::copy(c.path, c.path + c.steps, tp.path);
              std::copy(c.classes, c.classes + c.steps, tp.classes);
              e->tprims.push_back(tp);
              GraphBox b;  // in this node's frame
              prim_box(cp.shape, w, &b.lo, &b.hi);
              pad_box(b.lo, b.hi);
              prim_boxes.push_back(b);
            }
            made.push_back(std::move(ce));
            queue.push_back(c);
            continue;
          }
        }
        GraphHop h{};
        h.to_local = compose(ch.to_local, nd.from_node);
        h.path_dependent = ch.path_dependent;
        h.steps = c.steps;
        std::copy(c.path, c.path + c.steps, h.path);
        std::copy(c.classes, c.classes + c.steps, h.classes);
        e->hops.push_back(h);
        hop_boxes.push_back(db.box);
      }
    }
    e->inlined_prims.shrink_to_fit();
    e->tprims.shrink_to_fit();
    e->hops.shrink_to_fit();
    // The clusters of items; an item with an empty box (a hop to a subtree
    // that draws nothing) is never met and left out.
    std::vector<ViewItem>& items = cache.items;
    items.clear();
    auto add_item = [&](const GraphBox& b, size_t ref) {
      if (!(b.lo.x <= b.hi.x && b.lo.y <= b.hi.y && b.lo.z <= b.hi.z)) return;
      ViewItem it;
      it.lo = b.lo;
      it.hi = b.hi;
      for (int a = 0; a < 3; ++a) it.c[a] = 0.5 * (b.lo[a] + b.hi[a]);
      it.ref = uint32_t(ref);
      items.push_back(it);
    };
    for (size_t i = 0; i < prim_boxes.size(); ++i) add_item(prim_boxes[i], i);
    for (size_t i = 0; i < hop_boxes.size(); ++i) add_item(hop_boxes[i], prim_boxes.size() + i);
    cache.clusters.clear();
    cache.cluster_boxes.clear();
    if (!items.empty()) build_clusters(cache.clusters, cache.cluster_boxes, items.data(), items.size(), cache.areas);
    e->clusters.assign(cache.clusters.begin(), cache.clusters.end());
    if (cache.clusters.size() > 1)  // one cluster is tested without its box
      e->cluster_boxes.assign(cache.cluster_boxes.begin(), cache.cluster_boxes.end());
    std::vector<GraphChild>().swap(e->children);
    std::vector<uint32_t>().swap(e->prims_before);
    // The vectors are final: point the trace primitives at their primitives.
    const size_t own = e->prims.size();
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
        if (memo.it != cache.lru.begin() && half_full(cache)) cache.lru.splice(cache.lru.begin(), cache.lru, memo.it);
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
      build_view(cache, e, cls, path);
      if (!cache.memo[cls].transient) {
        cache.bytes = cache.bytes - before + e->bytes;
        cache.peak = std::max(cache.peak, cache.bytes);
      }
    }
    return e;
  }

  // Box tests in float, four boxes (a GraphBoxes4) at a time, conservative: a
  // box that the ray meets in [t0, t1] in exact arithmetic always passes.
  // The boxes are rounded outward; a near side's slab distance uses the origin
  // rounded so that the distance errs low, a far side's so that it errs high
  // (Frame::on, of); what is left (1 / d from a double division rounded to
  // float, the float subtraction and product) are relative errors of at most
  // ~3 float ulps, which widening the far distance by 2^-20 relative covers
  // (the entry is narrowed by as much: the front-to-back order and the skip
  // beyond the closest hit stay conservative). A zero direction component gives
  // 0 * inf = NaN on a slab's boundary, which max / min drop (the closed slab
  // contains the ray); an empty box (lo = +inf, hi = -inf) gives a far distance
  // of -inf, widened to NaN, and never passes (unless the origin is NaN).
  // Returns the mask of the boxes met; entry[k]: box k's entry.
#if defined(__SSE2__)
  // A frame's float ray, each value broadcast to four lanes (made once per visit).
  struct Ray4 {
    __m128 inv[3], on[3], of[3];
    explicit Ray4(const Frame& f) {
      const __m128 i = _mm_load_ps(f.inv), n = _mm_load_ps(f.on), o = _mm_load_ps(f.of);
      inv[0] = _mm_shuffle_ps(i, i, 0x00), inv[1] = _mm_shuffle_ps(i, i, 0x55), inv[2] = _mm_shuffle_ps(i, i, 0xAA);
      on[0] = _mm_shuffle_ps(n, n, 0x00), on[1] = _mm_shuffle_ps(n, n, 0x55), on[2] = _mm_shuffle_ps(n, n, 0xAA);
      of[0] = _mm_shuffle_ps(o, o, 0x00), of[1] = _mm_shuffle_ps(o, o, 0x55), of[2] = _mm_shuffle_ps(o, o, 0xAA);
    }
  };
#else
  struct Ray4 {
    const Frame& f;
    explicit Ray4(const Frame& fr) : f(fr) {}
  };
#endif
  static int boxes4(const GraphBoxes4& b, const Frame& f, const Ray4& r, float t0, float t1, float* entry) {
    constexpr float kWiden = 1.0f / 1048576.0f;  // 2^-20
    const float* p = &b.lo[0][0];
#if defined(__SSE2__)
    __m128 tn = _mm_set1_ps(t0), tf = _mm_set1_ps(t1);
    for (int a = 0; a < 3; ++a) {
      const __m128 n = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(p + f.near[a]), r.on[a]), r.inv[a]);
      const __m128 x = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(p + f.far[a]), r.of[a]), r.inv[a]);
      tn = _mm_max_ps(n, tn);  // NaN in n: tn
      tf = _mm_min_ps(x, tf);
    }
    const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7FFFFFFF)), k = _mm_set1_ps(kWiden);
    tf = _mm_add_ps(tf, _mm_mul_ps(_mm_and_ps(tf, abs_mask), k));
    _mm_store_ps(entry, _mm_sub_ps(tn, _mm_mul_ps(_mm_and_ps(tn, abs_mask), k)));
    return _mm_movemask_ps(_mm_cmple_ps(tn, tf));
#else
    int mask = 0;
    for (int l = 0; l < 4; ++l) {
      float tn = t0, tf = t1;
      for (int a = 0; a < 3; ++a) {
        const float n = (p[f.near[a] + l] - r.f.on[a]) * r.f.inv[a];
        const float x = (p[f.far[a] + l] - r.f.of[a]) * r.f.inv[a];
        tn = n > tn ? n : tn;  // as _mm_max_ps / _mm_min_ps: NaN in n / x is dropped
        tf = x < tf ? x : tf;
      }
      tf = tf + std::fabs(tf) * kWiden;
      entry[l] = tn - std::fabs(tn) * kWiden;
      if (tn <= tf) mask |= 1 << l;
    }
    return mask;
#endif
  }

  // The frame's ray: o, d and, for boxes4, 1 / d (a double division rounded
  // to float) and the origin in float moved down and up by more than its
  // rounding (|o| 2^-23 + FLT_MIN, also with denormals flushed), branch free.
  static void set_ray(Frame& f, DVec3 o, DVec3 d) {
    f.o = o;
    f.d = d;
#if defined(__SSE2__)
    const __m128d one = _mm_set1_pd(1.0);
    const __m128 inv4 = _mm_movelh_ps(_mm_cvtpd_ps(_mm_div_pd(one, _mm_setr_pd(d.x, d.y))),
                                      _mm_cvtpd_ps(_mm_div_sd(one, _mm_set_sd(d.z))));
    const __m128 o4 = _mm_movelh_ps(_mm_cvtpd_ps(_mm_setr_pd(o.x, o.y)), _mm_cvtpd_ps(_mm_set_sd(o.z)));
    const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7FFFFFFF));
    const __m128 slack = _mm_add_ps(_mm_mul_ps(_mm_and_ps(o4, abs_mask), _mm_set1_ps(1.0f / 8388608.0f)),
                                    _mm_set1_ps(std::numeric_limits<float>::min()));
    const __m128 up = _mm_add_ps(o4, slack), down = _mm_sub_ps(o4, slack);
    const __m128 neg = _mm_castsi128_ps(_mm_srai_epi32(_mm_castps_si128(inv4), 31));  // sign of 1 / d
    _mm_store_ps(f.inv, inv4);
    _mm_store_ps(f.on, _mm_or_ps(_mm_and_ps(neg, down), _mm_andnot_ps(neg, up)));
    _mm_store_ps(f.of, _mm_or_ps(_mm_and_ps(neg, up), _mm_andnot_ps(neg, down)));
    const int signs = _mm_movemask_ps(inv4);
#else
    int signs = 0;
    for (int a = 0; a < 3; ++a) {
      f.inv[a] = float(1.0 / d[a]);
      const float of0 = float(o[a]), slack = std::fabs(of0) * (1.0f / 8388608.0f) + std::numeric_limits<float>::min();
      const bool neg = std::signbit(f.inv[a]);
      f.on[a] = neg ? of0 - slack : of0 + slack;
      f.of[a] = neg ? of0 + slack : of0 - slack;
      signs |= int(neg) << a;
    }
#endif
    for (int a = 0; a < 3; ++a) {
      const int neg = (signs >> a) & 1;
      f.near[a] = uint8_t(4 * a + 12 * neg);  // hi[a] : lo[a]
      f.far[a] = uint8_t(4 * a + 12 * (1 - neg));
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
    const float t0 = float_down(tnear);
    // The closest hit so far; the hit record is made once at the end.
    const GraphTracePrim* hit_tp = nullptr;
    int hit_level = 0, hit_face = 0;
    DVec3 hit_p;  // in the frame of the hit primitive's view
    const GraphHop* hit_via[kMaxGraphLevels + 1];
    csg::Crossing cr[csg::kMaxPrimitiveCrossings];
    // Tests the primitives of the node at `level` and queues the hops that
    // the ray meets before `best`, nearest last; true to stop (occlusion found).
    auto visit = [&](int level) {
      const Frame& f = frames[level];
      const GraphExpansion& e = *f.e;
      alignas(16) float entry[4];
      const Ray4 r4(f);
      float t1 = float(best);  // its rounding is within the 2^-20 of boxes4
      const size_t np = e.tprims.size(), nh = e.hops.size();
      if (e.clusters.empty()) return false;
      if (npend + nh > cache.pending.size()) {
        cache.pending.resize(2 * (npend + nh));
        pend = cache.pending.data();
      }
      const size_t first = npend;  // this visit's run of queued hops
      // Item `item` (a tprim, then the hops; else an unused lane, NaN origin)
      // whose box the ray enters at te (before best); true to stop (occluded).
      auto item_met = [&](size_t item, float te) -> bool {
        if (item < np) {
          const GraphTracePrim& tp = e.tprims[item];
          const int n = csg::intersect(tp.gp->prim, f.o, f.d, 0.0, cr);
          for (int k = 0; k < n; ++k) {
            const double t = cr[k].t;
            if (t < tnear) continue;
            if (t >= best) break;
            found = true;
            if (!hit) return true;
            best = t;
            t1 = float(best);
            hit_tp = &tp;
            hit_level = level;
            hit_face = cr[k].face;
            hit_p = f.o + t * f.d;
            for (int lev = 1; lev <= level; ++lev) hit_via[lev] = frames[lev].via;
            break;
          }
        } else if (item < np + nh) {
          const size_t h = item - np;
          const double t = te;
          // Insertion into this visit's queued run, kept sorted with the nearest at the back.
          size_t j = npend++;
          while (j > first && pend[j - 1].t < t) {
            pend[j].t = pend[j - 1].t;
            pend[j].level = pend[j - 1].level;
            pend[j].hop = pend[j - 1].hop;
            --j;
          }
          pend[j].t = t;
          pend[j].level = uint32_t(level);
          pend[j].hop = uint32_t(h);
        }
        return false;
      };
      // The clusters met (a single one directly), then the items met in
      // them; the closest hit so far culls both.
      auto cluster_met = [&](const GraphCluster& cl) -> bool {
        alignas(16) float item_entry[4];
        for (int m = boxes4(cl.box, f, r4, t0, t1, item_entry); m; m &= m - 1) {
          const int l = __builtin_ctz(unsigned(m));
          if (double(item_entry[l]) > best) continue;
          if (item_met(cl.item[l], item_entry[l])) return true;
        }
        return false;
      };
      const size_t nc = e.clusters.size();
      if (nc == 1) return cluster_met(e.clusters[0]);
      for (size_t b = 0; b < e.cluster_boxes.size(); ++b) {
        for (int mask = boxes4(e.cluster_boxes[b], f, r4, t0, t1, entry); mask; mask &= mask - 1) {
          const int lane = __builtin_ctz(unsigned(mask));
          const size_t c = 4 * b + size_t(lane);
          if (c >= nc) break;  // an unused lane (NaN origin)
          if (double(entry[lane]) > best) continue;
          if (cluster_met(e.clusters[c])) return true;
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
      set_ray(g, c.to_local.point(f.o), c.to_local.vector(f.d));
      uint64_t key = 0;
      if (c.path_dependent) {  // then so are the nodes above it
        key = f.key;
        for (int s = 0; s < c.steps; ++s) key = child_key(key, c.path[s]);
      }
      g.key = key;
      g.via = &c;
      g.e = find(cache, c.classes[c.steps - 1], key, c.path_dependent);
      stop = visit(level);
    }
    if (found && hit) {
      const GraphTracePrim& tp = *hit_tp;
      int lv = 0;  // derivation steps from the root
      hit->classes[0] = 0;
      for (int lev = 1; lev <= hit_level; ++lev) {
        const GraphHop& v = *hit_via[lev];
        for (int s = 0; s < v.steps; ++s) {
          hit->path[lv] = v.path[s];
          hit->classes[++lv] = v.classes[s];
        }
      }
      for (int s = 0; s < tp.steps; ++s) {
        hit->path[lv] = tp.path[s];
        hit->classes[++lv] = tp.classes[s];
      }
      hit->t = best;
      hit->levels = lv;
      hit->shape = tp.gp->shape;
      hit->material = tp.gp->material;
      hit->prim = tp.prim;
      // The normal (in the frame of the view that holds the primitive) back up the hops.
      DVec3 nl = csg::normal(tp.gp->prim, hit_face, hit_p);
      for (int lev = hit_level; lev > 0; --lev) nl = hit_via[lev]->to_local.transpose_vector(nl);
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
  g.bounds_budget = int64_t(std::min<size_t>(o.bounds_budget, size_t(INT64_MAX)));
  g.bounds_total = int64_t(std::min<size_t>(o.bounds_total, size_t(INT64_MAX)));
  // The root: the axiom at depth D (its class depth is D + 1).
  GraphNodeClass root;
  root.symbol = kRoot;
  root.depth = depth + 1;
  root.width = g.width;
  root.material = g.material;
  g.classes.push_back(root);
  g.end.emplace_back();
  g.end_variable.push_back(0);
  g.child_desc.emplace_back();
  g.skel.emplace_back();
  g.desc_nodes.emplace_back();
  g.analyse(0);
  int64_t budget = g.bounds_budget;
  g.subtree_box(0, o.world, budget, g.world_lo, g.world_hi);
  pad_box(g.world_lo, g.world_hi);
  g.skel = {};  // set-up only
  g.desc_nodes = {};
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
  s.bounds_visits = uint64_t(g.bounds_visits);
  s.class_bytes = g.classes.size() * (sizeof(GraphNodeClass) + sizeof(State) + 96) +
                  g.desc_count * sizeof(Graph::Impl::DescBoxes);
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
  return attach_user_geometry<graph_bounds, graph_intersect, occluded_n<Graph>>(device, scene, &graph);
}

}  // namespace plm::lsystem
