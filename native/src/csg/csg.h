// A CSG object: analytic primitives combined by an n-ary boolean tree, ray
// traced exactly by combining the primitives' hit intervals along the ray
// ([Thesis §4.1.1]: the 3D set operations become 1D operations on intervals).
//
// The tree is flat: nodes with child ranges into one index array, leaves
// pointing at primitives. DIFFERENCE is the first child minus all others.
// Nested nodes of the same kind are merged at build ((A u B) u C = u(A, B, C),
// (A - B) - C = -(A, B, C)) so that trees stay shallow.
//
// Per ray, every node's crossing list lives in one fixed stack buffer of
// kMaxCrossings entries; the need of each tree is computed at build (a leaf
// gives 2 crossings, a torus 4; an operator at most the sum of its children)
// and a tree that would need more is rejected, so tracing never allocates.
//
// Coincident faces (coplanar, or any two boundaries closer than the object's
// tolerance along a ray) follow one rule: crossings of different operands
// that fall within the tolerance are one event; the solid's state (in/out)
// is compared before and after the whole event and a crossing is reported
// only if it changed. The reported primitive is then the earliest operand in
// child order (for DIFFERENCE the minuend) among those crossed. So:
//   - union of two boxes sharing a face: no internal face, from any side;
//   - box minus a box sharing a face (a pocket reaching the surface): the
//     shared face is removed, no zero-thickness skin remains;
//   - box minus a box touching it from outside: the first box's face stays,
//     with the first box as its primitive;
//   - intersection of boxes sharing a face: the face of the first child.
// Slivers thinner than the tolerance are dropped and gaps narrower than it
// closed. on_boundary() follows the same rule by looking at both sides of
// the point, so ray tracing and area estimation agree.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "csg/primitive.h"

namespace plm::csg {

enum class Op : uint8_t { Union, Intersection, Difference, Leaf };

struct NodeDesc {
  Op op = Op::Leaf;
  uint32_t first = 0;  // Leaf: primitive index; otherwise index of the first child in `children`
  uint32_t count = 0;  // number of children (ignored for a leaf)
};

struct CsgDesc {
  std::string name;
  std::vector<PrimitiveDesc> primitives;
  std::vector<uint32_t> materials;  // one per primitive
  std::vector<NodeDesc> nodes;
  std::vector<uint32_t> children;   // node indices
  uint32_t root = 0;
};

// Crossings one ray may need, summed over the tree (see above): 16 KiB of stack.
constexpr int kMaxCrossings = 1024;
constexpr int kMaxTreeDepth = 64;

struct CsgHit {
  double t = 0;
  uint32_t prim = 0;      // the primitive whose face was crossed (the last one traversed)
  uint32_t face = 0;
  uint32_t material = 0;  // the material of that primitive
  bool flipped = false;   // a face of a subtracted primitive: normal is minus the primitive's
  Vec3d p, n;             // world point; unit normal pointing out of the solid
};

class CsgObject {
 public:
  // Validates and flattens; throws plm::Error naming the object and the
  // offending primitive or node.
  explicit CsgObject(const CsgDesc& desc);

  const std::string& name() const { return name_; }
  uint32_t primitive_count() const { return uint32_t(prims_.size()); }
  const Primitive& primitive(uint32_t i) const { return prims_[i]; }
  uint32_t material(uint32_t i) const { return materials_[i]; }
  Vec3d bounds_lo() const { return lo_; }
  Vec3d bounds_hi() const { return hi_; }
  double tolerance() const { return tol_; }  // world length below which features vanish
  int scratch_crossings() const { return scratch_; }  // per-ray need, <= kMaxCrossings
  // Pairs of primitives with coplanar overlapping planar faces, found at build.
  const std::vector<std::string>& warnings() const { return warnings_; }

  // Crossings of the solid's boundary along o + t d with tnear <= t <= tfar,
  // sorted; `out` must hold kMaxCrossings entries (it is also the scratch).
  int crossings(Vec3d o, Vec3d d, double tnear, double tfar, Crossing* out) const;
  bool first_hit(Vec3d o, Vec3d d, double tnear, double tfar, CsgHit& hit) const;
  bool occluded(Vec3d o, Vec3d d, double tnear, double tfar) const;
  CsgHit make_hit(const Crossing& c, Vec3d o, Vec3d d) const;

  // Whether p is in the (closed) solid; meant for points off the boundary.
  bool inside(Vec3d p) const;
  // Whether p, a point on face `face` of primitive `prim`, lies on the
  // solid's boundary: the tree is evaluated with prim forced inside and
  // forced outside (other primitives a tolerance inside/outside along the
  // normal, for coincident faces); p is on the boundary iff the results differ.
  // Where faces of several primitives coincide, the surface belongs only to
  // the first of them in tree order that bounds the solid there, as in ray
  // tracing, so that no area is counted twice.
  bool on_boundary(uint32_t prim, int face, Vec3d p) const;

 private:
  struct Node {
    Op op;
    uint32_t first, count;  // as NodeDesc, into kids_
    uint32_t cap;           // most crossings this node's list can hold
    uint32_t need;          // scratch beyond its own list while evaluating it
    Vec3d lo, hi;           // bounds, padded by the tolerance
  };
  struct RayCtx {
    Vec3d o, d;
    double eps, t_lo, t_hi;
  };

  void validate(const CsgDesc& desc) const;
  void flatten(const CsgDesc& desc);
  void gather(const CsgDesc& desc, uint32_t node, Op parent, bool first, std::vector<uint32_t>& out);
  uint32_t add_node(const CsgDesc& desc, uint32_t node);
  void size_node(uint32_t node, int depth);
  int eval(uint32_t node, const RayCtx& r, Crossing* out, Crossing* arena) const;
  std::vector<bool> used_primitives() const;
  bool separates(uint32_t prim, int face, Vec3d p) const;
  template <typename Leaf>
  bool eval_bool(uint32_t node, const Leaf& leaf) const;

  std::string name_;
  std::vector<Primitive> prims_;
  std::vector<uint32_t> materials_;
  std::vector<Node> nodes_;
  std::vector<uint32_t> kids_;
  std::vector<uint32_t> leaf_order_;  // used primitives, first occurrence in tree order
  uint32_t root_ = 0;
  Vec3d lo_, hi_;
  double tol_ = 0;
  int scratch_ = 0;
  std::vector<std::string> warnings_;
};

}  // namespace plm::csg
