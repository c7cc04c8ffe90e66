#include "csg/csg.h"

#include <algorithm>
#include <limits>

#include "csg/coplanar.h"
#include "util/error.h"

namespace plm::csg {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

const char* op_name(Op op) {
  static const char* const names[] = {"union", "intersection", "difference", "leaf"};
  return names[int(op)];
}

bool apply(Op op, bool a, bool b) {
  switch (op) {
    case Op::Union:
      return a || b;
    case Op::Intersection:
      return a && b;
    default:
      return a && !b;
  }
}

// Appends a crossing to a list that alternates entry/exit. A crossing within
// eps of the previous one (always of the other direction) cancels it: a
// sliver is dropped, a seam between touching intervals closed.
void emit(Crossing* out, int& n, const Crossing& c, double eps) {
  if (n > 0 && c.t <= out[n - 1].t + eps) {
    --n;
    return;
  }
  out[n++] = c;
}

// a op b for two sorted crossing lists, by a sweep over their crossings.
// Crossings of a and b within eps of each other form one event (the
// coincident-face rule in csg.h); the event's crossing is a's if a has one.
int combine(Op op, const Crossing* a, int na, const Crossing* b, int nb, double eps, Crossing* out) {
  int ia = 0, ib = 0, n = 0;
  bool in_a = false, in_b = false, state = false;
  while (ia < na || ib < nb) {
    const double t0 = std::fmin(ia < na ? a[ia].t : kInf, ib < nb ? b[ib].t : kInf);
    const bool take_a = ia < na && a[ia].t <= t0 + eps, take_b = ib < nb && b[ib].t <= t0 + eps;
    Crossing c;
    if (take_b) {
      c = b[ib++];
      c.flip ^= uint8_t(op == Op::Difference);  // entering a subtracted solid leaves the result
      in_b = !in_b;
    }
    if (take_a) {
      c = a[ia++];
      in_a = !in_a;
    }
    const bool s = apply(op, in_a, in_b);
    if (s != state) {
      emit(out, n, c, eps);
      state = s;
    }
  }
  return n;
}

// Whether the part [t_lo, t_hi] of the line o + t d meets the box.
bool segment_hits_box(Vec3d o, Vec3d d, double t_lo, double t_hi, Vec3d lo, Vec3d hi) {
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    double t0 = (lo[a] - o[a]) / d[a], t1 = (hi[a] - o[a]) / d[a];
    if (t0 > t1) std::swap(t0, t1);
    t_lo = std::fmax(t_lo, t0);
    t_hi = std::fmin(t_hi, t1);
    if (t_lo > t_hi) return false;
  }
  return true;
}

}  // namespace

CsgObject::CsgObject(const CsgDesc& desc) : name_(desc.name) {
  validate(desc);
  prims_.reserve(desc.primitives.size());
  for (const PrimitiveDesc& p : desc.primitives) prims_.push_back(make_primitive(p));
  materials_ = desc.materials;
  flatten(desc);
  size_node(root_, 0);
  const Node& root = nodes_[root_];
  if (!(root.lo.x <= root.hi.x && root.lo.y <= root.hi.y && root.lo.z <= root.hi.z))
    fail(PLM_ERROR_INVALID_SCENE, "CSG object '", name_, "' is empty: its intersections have disjoint bounds");
  if (!(is_finite(root.lo) && is_finite(root.hi)))
    fail(PLM_ERROR_INVALID_SCENE, "CSG object '", name_,
         "' is unbounded: a half-space must be intersected with, or subtracted from, a bounded solid");
  lo_ = root.lo;
  hi_ = root.hi;
  tol_ = kRelativeTolerance * max_abs_component(hi_ - lo_) + kRoundingTolerance * std::fmax(max_abs_component(lo_), max_abs_component(hi_));
  const Vec3d pad{tol_, tol_, tol_};
  for (Node& n : nodes_) n.lo = n.lo - pad, n.hi = n.hi + pad;
  scratch_ = int(root.cap + root.need);
  if (scratch_ > kMaxCrossings)
    fail(PLM_ERROR_INVALID_SCENE, "CSG object '", name_, "' needs ", scratch_, " ray crossings of scratch, more than ",
         kMaxCrossings, ": split it into several objects");
  const std::vector<bool> used = used_primitives();
  std::vector<bool> listed(prims_.size(), false);
  for (const Node& n : nodes_)  // children precede parents, left to right: tree order
    if (n.op == Op::Leaf && !listed[n.first]) leaf_order_.push_back(n.first), listed[n.first] = true;
  warnings_ = find_coplanar_faces(name_, prims_, used, tol_);
}

void CsgObject::validate(const CsgDesc& d) const {
  const size_t np = d.primitives.size(), nn = d.nodes.size();
  if (np == 0) fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "' has no primitives");
  if (d.materials.size() != np)
    fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "' has ", d.materials.size(), " materials for ", np,
         " primitives");
  for (size_t i = 0; i < np; ++i) {
    const std::string problem = check_primitive(d.primitives[i]);
    if (!problem.empty()) fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "': primitive ", i, ": ", problem);
  }
  if (d.root >= nn) fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "': root node ", d.root, " of ", nn, " nodes");
  for (size_t i = 0; i < nn; ++i) {
    const NodeDesc& n = d.nodes[i];
    if (int(n.op) > int(Op::Leaf)) fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "': node ", i, " has an unknown operator");
    if (n.op == Op::Leaf) {
      if (n.first >= np)
        fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "': node ", i, " refers to primitive ", n.first,
             ", but there are ", np);
      continue;
    }
    if (n.count == 0) fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "': node ", i, " (", op_name(n.op), ") has no children");
    if (uint64_t(n.first) + n.count > d.children.size())
      fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "': node ", i, " children [", n.first, ", ",
           uint64_t(n.first) + n.count, ") exceed the ", d.children.size(), " child entries");
    for (uint32_t k = 0; k < n.count; ++k)
      if (d.children[n.first + k] >= nn)
        fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "': node ", i, " has child ", d.children[n.first + k],
             ", but there are ", nn, " nodes");
  }
  // Cycles: depth-first from the root, iteratively (the input may be deep).
  std::vector<uint8_t> color(nn, 0);  // 0 new, 1 on the path, 2 done
  std::vector<std::pair<uint32_t, uint32_t>> stack{{d.root, 0}};
  color[d.root] = 1;
  while (!stack.empty()) {
    auto& [node, k] = stack.back();
    const NodeDesc& n = d.nodes[node];
    if (n.op == Op::Leaf || k == n.count) {
      color[node] = 2;
      stack.pop_back();
      continue;
    }
    const uint32_t child = d.children[n.first + k++];
    if (color[child] == 1)
      fail(PLM_ERROR_INVALID_ARGUMENT, "CSG object '", d.name, "': the tree has a cycle through node ", child);
    if (color[child] == 0) {
      color[child] = 1;
      stack.push_back({child, 0});
    }
  }
}

// Copies the reachable tree into nodes_/kids_, merging nested nodes of the
// same operator. Children are stored before their parent is finished, so the
// arrays stay flat; shared subtrees (a DAG) are copied per use.
void CsgObject::flatten(const CsgDesc& desc) {
  root_ = add_node(desc, desc.root);
}

uint32_t CsgObject::add_node(const CsgDesc& desc, uint32_t node) {
  if (nodes_.size() > (1u << 20))
    fail(PLM_ERROR_INVALID_SCENE, "CSG object '", name_, "' expands to more than 2^20 nodes (shared subtrees?)");
  const NodeDesc& n = desc.nodes[node];
  if (n.op == Op::Leaf) {
    nodes_.push_back({Op::Leaf, n.first, 0, 0, 0, {}, {}});
    return uint32_t(nodes_.size() - 1);
  }
  std::vector<uint32_t> kids;
  for (uint32_t k = 0; k < n.count; ++k) gather(desc, desc.children[n.first + k], n.op, k == 0, kids);
  const uint32_t first = uint32_t(kids_.size());
  kids_.insert(kids_.end(), kids.begin(), kids.end());
  nodes_.push_back({n.op, first, uint32_t(kids.size()), 0, 0, {}, {}});
  return uint32_t(nodes_.size() - 1);
}

// The operands of a parent with operator `parent` contributed by `node`:
// its own children when it is the same operator (and, for a difference,
// the first operand), else the node itself.
void CsgObject::gather(const CsgDesc& desc, uint32_t node, Op parent, bool first, std::vector<uint32_t>& out) {
  const NodeDesc& n = desc.nodes[node];
  if (n.op == parent && (parent != Op::Difference || first)) {
    for (uint32_t k = 0; k < n.count; ++k) gather(desc, desc.children[n.first + k], parent, first && k == 0, out);
    return;
  }
  out.push_back(add_node(desc, node));
}

// Bounds, list capacity and scratch need, bottom-up.
void CsgObject::size_node(uint32_t index, int depth) {
  if (depth > kMaxTreeDepth)
    fail(PLM_ERROR_INVALID_SCENE, "CSG object '", name_, "': the tree is deeper than ", kMaxTreeDepth, " levels");
  Node& n = nodes_[index];
  if (n.op == Op::Leaf) {
    const Primitive& p = prims_[n.first];
    n.cap = p.shape == Shape::Torus ? 4 : 2;
    n.need = 0;
    n.lo = p.lo;
    n.hi = p.hi;
    return;
  }
  uint32_t cap = 0;
  for (uint32_t k = 0; k < n.count; ++k) {
    size_node(kids_[n.first + k], depth + 1);
    cap += nodes_[kids_[n.first + k]].cap;
  }
  Node& m = n;  // size_node adds no nodes: the reference stays valid
  m.cap = cap;
  m.need = nodes_[kids_[m.first]].need;
  for (uint32_t k = 1; k < m.count; ++k) {
    const Node& c = nodes_[kids_[m.first + k]];
    m.need = std::max(m.need, c.cap + std::max(c.need, cap));
  }
  const Node& c0 = nodes_[kids_[m.first]];
  m.lo = c0.lo;
  m.hi = c0.hi;
  for (uint32_t k = 1; k < m.count && m.op != Op::Difference; ++k) {
    const Node& c = nodes_[kids_[m.first + k]];
    if (m.op == Op::Union) {
      m.lo = min(m.lo, c.lo);
      m.hi = max(m.hi, c.hi);
    } else {
      m.lo = max(m.lo, c.lo);
      m.hi = min(m.hi, c.hi);
    }
  }
}

std::vector<bool> CsgObject::used_primitives() const {
  std::vector<bool> used(prims_.size(), false);
  for (const Node& n : nodes_)
    if (n.op == Op::Leaf) used[n.first] = true;
  return used;
}

int CsgObject::eval(uint32_t index, const RayCtx& r, Crossing* out, Crossing* arena) const {
  const Node& n = nodes_[index];
  if (!segment_hits_box(r.o, r.d, r.t_lo, r.t_hi, n.lo, n.hi)) return 0;
  if (n.op == Op::Leaf) {
    const int count = intersect(prims_[n.first], r.o, r.d, r.eps, out);
    for (int i = 0; i < count; ++i) out[i].prim = int32_t(n.first);
    return count;
  }
  int count = eval(kids_[n.first], r, out, arena);
  for (uint32_t k = 1; k < n.count; ++k) {
    if (count == 0 && n.op != Op::Union) return 0;  // nothing left to intersect or subtract from
    const Node& child = nodes_[kids_[n.first + k]];
    Crossing* result = arena + child.cap;
    const int m = eval(kids_[n.first + k], r, arena, result);
    if (m == 0) {
      if (n.op == Op::Intersection) return 0;
      continue;
    }
    count = combine(n.op, out, count, arena, m, r.eps, result);
    std::copy(result, result + count, out);
  }
  return count;
}

int CsgObject::crossings(Vec3d o, Vec3d d, double tnear, double tfar, Crossing* out) const {
  const double len = length(d);
  if (!(len > 0) || !(tnear <= tfar)) return 0;
  RayCtx r{o, d, (tol_ + kRoundingTolerance * max_abs_component(o)) / len, 0, 0};
  r.t_lo = tnear - 4 * r.eps;
  r.t_hi = tfar + 4 * r.eps;
  const int n = eval(root_, r, out, out + nodes_[root_].cap);
  int kept = 0;
  for (int i = 0; i < n; ++i)
    if (out[i].t >= tnear && out[i].t <= tfar && std::isfinite(out[i].t)) out[kept++] = out[i];
  return kept;
}

CsgHit CsgObject::make_hit(const Crossing& c, Vec3d o, Vec3d d) const {
  CsgHit h;
  h.t = c.t;
  h.prim = uint32_t(c.prim);
  h.face = c.face;
  h.material = materials_[h.prim];
  h.flipped = c.flip != 0;
  h.p = o + d * c.t;
  const Vec3d n = normal(prims_[h.prim], c.face, h.p);
  h.n = h.flipped ? -n : n;
  return h;
}

bool CsgObject::first_hit(Vec3d o, Vec3d d, double tnear, double tfar, CsgHit& hit) const {
  Crossing buffer[kMaxCrossings];
  if (crossings(o, d, tnear, tfar, buffer) == 0) return false;
  hit = make_hit(buffer[0], o, d);
  return true;
}

bool CsgObject::occluded(Vec3d o, Vec3d d, double tnear, double tfar) const {
  Crossing buffer[kMaxCrossings];
  return crossings(o, d, tnear, tfar, buffer) > 0;
}

template <typename Leaf>
bool CsgObject::eval_bool(uint32_t index, const Leaf& leaf) const {
  const Node& n = nodes_[index];
  if (n.op == Op::Leaf) return leaf(n.first);
  bool acc = eval_bool(kids_[n.first], leaf);
  for (uint32_t k = 1; k < n.count; ++k) {
    if (n.op == Op::Union ? acc : !acc) return acc;  // decided
    const bool b = eval_bool(kids_[n.first + k], leaf);
    acc = n.op == Op::Difference ? !b : b;
  }
  return acc;
}

bool CsgObject::inside(Vec3d p) const {
  return eval_bool(root_, [&](uint32_t i) { return classify(prims_[i], p) != Side::Outside; });
}

bool CsgObject::on_boundary(uint32_t prim, int face, Vec3d p) const {
  if (!separates(prim, face, p)) return false;
  for (uint32_t j : leaf_order_) {
    if (j == prim) return true;
    if (classify(prims_[j], p) == Side::Boundary && separates(j, face_at(prims_[j], p), p)) return false;
  }
  return true;
}

bool CsgObject::separates(uint32_t prim, int face, Vec3d p) const {
  const Vec3d n = normal(prims_[prim], face, p);
  const double delta = 4 * (tol_ + kRoundingTolerance * max_abs_component(p));
  const Vec3d below = p - n * delta, above = p + n * delta;
  const bool in = eval_bool(root_, [&](uint32_t i) { return i == prim || inside_strict(prims_[i], below); });
  const bool out = eval_bool(root_, [&](uint32_t i) { return i != prim && inside_strict(prims_[i], above); });
  return in != out;
}

}  // namespace plm::csg
