// Rays through an L-system graph (Graph::first_hit, Graph::occluded).
//
// A ray walks the graph with an explicit stack of frames, one per level:
// each visit tests the clusters of the node's view (lsystem/graph/graph_view.h),
// then the boxes in the clusters met, four at a time in float SIMD
// (conservative: a box the ray meets always passes), intersects the
// primitives met and queues the hops met; hops are entered front to back
// (sorted by box entry, skipped once the entry lies beyond the closest hit so
// far), each mapping the ray into its target's frame. The hit record (path,
// classes per level, keys, normal) is made once per ray, from the hops that
// led to the closest hit.
#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "lsystem/graph/geometry.h"
#include "lsystem/graph/graph_impl.h"

namespace plm::lsystem {
namespace {


// Box tests in float, four boxes (a GraphBoxes4) at a time, conservative: a
// box that the ray meets in [t0, t1] in exact arithmetic always passes.
// The boxes are rounded outward; a near side's slab distance uses the origin
// rounded so that the distance errs low, a far side's so that it errs high
// (TraceFrame::on, of); what is left (1 / d from a double division rounded to
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
  explicit Ray4(const TraceFrame& f) {
    const __m128 i = _mm_load_ps(f.inv), n = _mm_load_ps(f.on), o = _mm_load_ps(f.of);
    inv[0] = _mm_shuffle_ps(i, i, 0x00), inv[1] = _mm_shuffle_ps(i, i, 0x55), inv[2] = _mm_shuffle_ps(i, i, 0xAA);
    on[0] = _mm_shuffle_ps(n, n, 0x00), on[1] = _mm_shuffle_ps(n, n, 0x55), on[2] = _mm_shuffle_ps(n, n, 0xAA);
    of[0] = _mm_shuffle_ps(o, o, 0x00), of[1] = _mm_shuffle_ps(o, o, 0x55), of[2] = _mm_shuffle_ps(o, o, 0xAA);
  }
};
#else
struct Ray4 {
  const TraceFrame& f;
  explicit Ray4(const TraceFrame& fr) : f(fr) {}
};
#endif

inline int boxes4(const GraphBoxes4& b, const TraceFrame& f, const Ray4& r, float t0, float t1, float* entry) {
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
inline void set_ray(TraceFrame& f, Vec3d o, Vec3d d) {
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

// A ray's walk through the graph: the frames (one per level), the hops still
// to enter and the closest hit so far, whose hit record is made once at the end.
struct RayWalk {
  RayWalk(const GraphClasses& graph, TraceThread& th, double t_near, double t_far, bool closest_hit)
      : g(graph), thread(th), tnear(t_near), t0(float_down(t_near)), closest(closest_hit), best(t_far) {
    if (thread.frames.size() < size_t(kMaxGraphLevels) + 1) thread.frames.resize(size_t(kMaxGraphLevels) + 1);
    if (thread.pending.size() < 256) thread.pending.resize(256);
    frames = thread.frames.data();
    pend = thread.pending.data();
  }
  // Room for `more` hops in the pending array.
  void reserve_pending(size_t more) {
    if (npend + more > thread.pending.size()) {
      thread.pending.resize(2 * (npend + more));
      pend = thread.pending.data();
    }
  }

  const GraphClasses& g;
  TraceThread& thread;
  const double tnear;
  const float t0;
  const bool closest;  // false: any hit ends the walk (occlusion)
  TraceFrame* frames;
  // Hops still to enter, nearest at the back: a per-thread array that only
  // grows (written field by field: no store-forwarding stalls).
  TracePending* pend;
  size_t npend = 0;
  double best;
  bool found = false;
  // The closest hit so far.
  const GraphTracePrim* hit_tp = nullptr;
  int hit_level = 0, hit_face = 0;
  Vec3d hit_p;  // in the frame of the hit primitive's view
  const GraphHop* hit_via[kMaxGraphLevels + 1];
  csg::Crossing cr[csg::kMaxPrimitiveCrossings];
};

// One visit of the node at `level`: tests its primitives and queues the hops
// that the ray meets before the closest hit so far, nearest last.
struct NodeVisit {
  NodeVisit(RayWalk& walk, int lev)
      : w(walk), level(lev), f(walk.frames[lev]), e(*f.e), r4(f), t1(float(walk.best)), np(e.tprims.size()),
        nh(e.hops.size()), first(walk.npend) {}

  // Primitive `tp`, whose box the ray enters before the closest hit so far;
  // true to stop (occluded).
  bool prim_met(const GraphTracePrim& tp) {
    const int n = csg::intersect(tp.gp->prim, f.o, f.d, 0.0, w.cr);
    for (int k = 0; k < n; ++k) {
      const double t = w.cr[k].t;
      if (t < w.tnear) continue;
      if (t >= w.best) break;
      w.found = true;
      if (!w.closest) return true;
      w.best = t;
      t1 = float(w.best);
      w.hit_tp = &tp;
      w.hit_level = level;
      w.hit_face = w.cr[k].face;
      w.hit_p = f.o + t * f.d;
      for (int lev = 1; lev <= level; ++lev) w.hit_via[lev] = w.frames[lev].via;
      break;
    }
    return false;
  }
  // Hop h, whose box the ray enters at t: inserted into this visit's queued
  // run, kept sorted with the nearest at the back.
  void queue_hop(size_t h, double t) {
    TracePending* pend = w.pend;
    size_t j = w.npend++;
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
  // Item `item` (a tprim, then the hops; else an unused lane, NaN origin)
  // whose box the ray enters at te (before best); true to stop (occluded).
  bool item_met(size_t item, float te) {
    if (item < np) return prim_met(e.tprims[item]);
    if (item < np + nh) queue_hop(item - np, te);
    return false;
  }
  // The items met in a cluster; the closest hit so far culls them.
  bool cluster_met(const GraphCluster& cl) {
    alignas(16) float item_entry[4];
    for (int m = boxes4(cl.box, f, r4, w.t0, t1, item_entry); m; m &= m - 1) {
      const int l = __builtin_ctz(unsigned(m));
      if (double(item_entry[l]) > w.best) continue;
      if (item_met(cl.item[l], item_entry[l])) return true;
    }
    return false;
  }
  // The clusters met (a single one directly), then the items met in them.
  bool run() {
    const size_t nc = e.clusters.size();
    if (nc == 1) return cluster_met(e.clusters[0]);
    alignas(16) float entry[4];
    for (size_t b = 0; b < e.cluster_boxes.size(); ++b) {
      for (int mask = boxes4(e.cluster_boxes[b], f, r4, w.t0, t1, entry); mask; mask &= mask - 1) {
        const int lane = __builtin_ctz(unsigned(mask));
        const size_t c = 4 * b + size_t(lane);
        if (c >= nc) break;  // an unused lane (NaN origin)
        if (double(entry[lane]) > w.best) continue;
        if (cluster_met(e.clusters[c])) return true;
      }
    }
    return false;
  }

  RayWalk& w;
  const int level;
  const TraceFrame& f;
  const GraphExpansion& e;
  const Ray4 r4;
  float t1;  // best in float: its rounding is within the 2^-20 of boxes4
  const size_t np, nh;
  const size_t first;  // this visit's run of queued hops
};

// Visits the node at `level`; true to stop (occlusion found).
bool visit(RayWalk& w, int level) {
  const GraphExpansion& e = *w.frames[level].e;
  if (e.clusters.empty()) return false;
  w.reserve_pending(e.hops.size());
  return NodeVisit(w, level).run();
}

// Enters the nearest hop still queued, unless a closer hit was found after it
// was queued; true to stop (occlusion found).
bool enter_next(RayWalk& w) {
  --w.npend;
  const double pt = w.pend[w.npend].t;
  const uint32_t plevel = w.pend[w.npend].level, phop = w.pend[w.npend].hop;
  if (pt > w.best) return false;
  const TraceFrame& f = w.frames[plevel];
  const int level = int(plevel) + 1;
  if (level > kMaxGraphLevels) {  // unreachable: a frame is at least one derivation step
    ++w.thread.truncated;
    return false;
  }
  const GraphHop& c = f.e->hops[phop];
  TraceFrame& next = w.frames[level];
  set_ray(next, c.to_local.point(f.o), c.to_local.vector(f.d));
  uint64_t key = 0;
  if (c.path_dependent) {  // then so are the nodes above it
    key = f.key;
    for (int s = 0; s < c.steps; ++s) key = child_path_key(key, c.path[s]);
  }
  next.key = key;
  next.via = &c;
  next.e = w.thread.cache.find(w.g, c.classes[c.steps - 1], key, c.path_dependent);
  return visit(w, level);
}

// The hit record of the closest hit: its path and classes from the hops that
// led to it, the normal mapped back up the hops, the keys.
void record_hit(const RayWalk& w, GraphHit& hit) {
  const GraphTracePrim& tp = *w.hit_tp;
  int lv = 0;  // derivation steps from the root
  hit.classes[0] = 0;
  for (int lev = 1; lev <= w.hit_level; ++lev) {
    const GraphHop& v = *w.hit_via[lev];
    for (int s = 0; s < v.steps; ++s) {
      hit.path[lv] = v.path[s];
      hit.classes[++lv] = v.classes[s];
    }
  }
  for (int s = 0; s < tp.steps; ++s) {
    hit.path[lv] = tp.path[s];
    hit.classes[++lv] = tp.classes[s];
  }
  hit.t = w.best;
  hit.levels = lv;
  hit.shape = tp.gp->shape;
  hit.material = tp.gp->material;
  hit.prim = tp.prim;
  // The normal (in the frame of the view that holds the primitive) back up the hops.
  Vec3d nl = csg::normal(tp.gp->prim, w.hit_face, w.hit_p);
  for (int lev = w.hit_level; lev > 0; --lev) nl = w.hit_via[lev]->to_local.transpose_vector(nl);
  hit.n = normalize(nl);
  hit.node_key = ancestor_path_key(w.g.root_key, hit, hit.levels);
  hit.instance_key = child_path_key(hit.node_key, hit.prim);
}

// Closest hit (hit != nullptr) or any hit (hit == nullptr) in [tnear, tfar).
bool trace(const GraphClasses& g, TraceThread& thread, Vec3d o, Vec3d d, double tnear, double tfar, GraphHit* hit) {
  const GraphNodeClass& root = g.classes[0];
  if (!(tnear <= tfar) || !box_hit(root.lo, root.hi, o, d, tnear, tfar)) return false;
  ExpansionCache& cache = thread.cache;
  cache.begin_trace(g);
  RayWalk w(g, thread, tnear, tfar, hit != nullptr);
  TraceFrame& f0 = w.frames[0];
  f0.e = cache.find(g, 0, g.root_key, root.path_dependent);
  set_ray(f0, o, d);
  f0.key = g.root_key;
  f0.via = nullptr;
  bool stop = visit(w, 0);
  while (!stop && w.npend > 0) stop = enter_next(w);
  if (w.found && hit) record_hit(w, *hit);
  cache.end_trace(g);
  return w.found;
}

}  // namespace

bool Graph::first_hit(Vec3d o, Vec3d d, double tnear, double tfar, GraphHit* hit) const {
  return trace(impl_->g, impl_->local(), o, d, tnear, tfar, hit);
}

bool Graph::occluded(Vec3d o, Vec3d d, double tnear, double tfar) const {
  return trace(impl_->g, impl_->local(), o, d, tnear, tfar, nullptr);
}

}  // namespace plm::lsystem
