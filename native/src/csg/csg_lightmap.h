// CSG-aware lightmaps on the faces of analytic primitives ([Thesis §5.2]): every
// (primitive, face) of a CSG object gets a texel grid over a chart of the
// whole face; CSG operations then decide which parts of each texel are on
// the solid's boundary. Texels fully on the boundary are "uncut", texels fully
// removed are inert (they never receive light), and texels crossed by the
// boundary of another primitive are split into sub-texels, one per connected
// region of boundary samples (5.2.2), so that light never leaks across a
// groove or a hole edge inside one texel.
//
// Charts. Each face maps the unit square (s, t) onto the whole face, with no
// pole and texel areas bounded away from zero (local space, before the
// primitive's affine map; "ratio" is the max/min area element over the face):
//   box face          the square itself                               ratio 1
//   cylinder side     (angle / 2pi, (z+1)/2), periodic in s           ratio 1
//   disks (cylinder caps, cone base, paraboloid cap)
//                     Shirley-Chiu concentric square-to-disk map       ratio 1 (equal-area)
//   sphere            Clarberg's equal-area octahedral map             ratio 1
//   cone side         the concentric disk (x, y) lifted to the cone,
//                     z = 1 - 2 |(x, y)|: the apex is the disk centre,
//                     area element pi sqrt(5) everywhere               ratio 1
//   paraboloid bowl   the concentric disk lifted to z = x^2 + y^2       ratio sqrt(5)
//   torus             (angle about z, angle about the tube) / 2pi,
//                     both periodic                                    ratio (R+r)/(R-r)
//   half-space plane  the rectangle of the object's bounding box
//                     projected onto the plane (local x, y)            ratio 1
// An affine map multiplies the area element by |det M| |M^-T n| (Nanson),
// which is bounded above and below for a non-singular M. Measured max/min
// texel area on unit primitives at texel size 0.1 (csg_lightmap_test): 1
// (within 1e-9) for every chart except the torus (R 1, r 0.25: 1.644) and the
// paraboloid bowl (2.179).
//
// Sub-texels. A texel is sampled at the centres of a g x g grid of cells and
// each sample is classified with CsgObject::on_boundary. The areas are
// integrals of the area element: an uncut texel by 4 x 4 Gauss-Legendre, a
// sub-texel as the texel's area times its share of the cells, the cells
// weighted by the area element at their centres. Only cut texels store a
// label grid (an index from cut texels into one shared label array).
//
// The CsgObject is referenced, not copied: it must outlive the lightmap.
// All queries are const, allocate nothing and are safe from many threads.
#pragma once

#include <cstdint>
#include <vector>

#include "csg/csg.h"

namespace plm::csg {

// A half-space plane's chart: a rectangle of its local plane z = 0.
struct PlaneRect {
  double x0 = -1, x1 = 1, y0 = -1, y1 = 1;
};

// The bounding rectangle, in the plane's local (x, y), of the world box
// [lo, hi] projected onto a half-space's plane; false if the box is unbounded.
bool plane_rect(const Primitive& half_space, Vec3d lo, Vec3d hi, PlaneRect& out);

struct FacePoint {
  Vec3d p;      // world point
  Vec3d n;      // outward unit world normal of the primitive's face (not flipped for subtraction)
  double area;  // |dP/ds x dP/dt|: world area per unit (s, t) area
};

struct FaceCoord {
  double s, t;
};

// The chart of `face` (see above) at (s, t) in [0, 1]^2. `rect` is used only
// by half-space planes.
FacePoint face_point(const Primitive& prim, int face, double s, double t, const PlaneRect& rect = PlaneRect{});
// The inverse: (s, t) of the face point nearest (in chart terms) to the world
// point p, which should lie on or near the face. Periodic coordinates are in
// [0, 1), the others clamped to [0, 1].
FaceCoord face_param(const Primitive& prim, int face, Vec3d p, const PlaneRect& rect = PlaneRect{});

struct CsgLightmapSettings {
  double texel_size = 0.1;  // world length of a texel side (> 0)
  int grid = 8;             // g: classification samples per texel side, 2..32
  int max_resolution = 1024;  // per side, 1..4096
  // false: a plain lightmap of the same faces (no classification: every texel
  // one sub-texel, flipped normals not detected), for comparing costs.
  bool split = true;
};

struct CsgLightmapStats {
  uint64_t faces = 0, unbounded_faces = 0;  // unbounded: a half-space plane of an unbounded object, no texels
  uint64_t texels = 0, uncut = 0, cut = 0, inert = 0, sub_texels = 0;
  uint64_t bytes = 0;       // memory held by the lightmap's arrays
  double setup_seconds = 0;
};

class CsgLightmap {
 public:
  static constexpr uint32_t kNone = 0xFFFFFFFFu;
  static constexpr uint16_t kNoLabel = 0xFFFFu;

  struct Face {
    uint32_t prim;
    uint32_t face;
    uint32_t width, height;  // texels along s and t (0 x 0 for an unbounded plane)
    uint32_t first_texel;    // offset into the flat texel array
    PlaneRect rect;          // half-space planes only
  };

  // Throws plm::Error (PLM_ERROR_INVALID_ARGUMENT) for invalid settings or a
  // lightmap of more than 2^31 texels.
  CsgLightmap(const CsgObject& obj, const CsgLightmapSettings& settings);

  const CsgObject& object() const { return *obj_; }
  int grid() const { return g_; }
  const CsgLightmapStats& stats() const { return stats_; }

  uint32_t chart_count() const { return uint32_t(faces_.size()); }
  const Face& face(uint32_t i) const { return faces_[i]; }
  // Index of (prim, face) in face(), or kNone.
  uint32_t face_index(uint32_t prim, int face) const;
  uint32_t texel_count() const { return uint32_t(texels_.size()); }
  uint32_t texel_index(uint32_t face_idx, uint32_t x, uint32_t y) const {
    return faces_[face_idx].first_texel + y * faces_[face_idx].width + x;
  }
  uint32_t face_of_texel(uint32_t texel) const;

  // Per texel: 0 (inert), 1 (uncut, or cut with one region) or more.
  uint32_t texel_sub_count(uint32_t texel) const;
  bool texel_cut(uint32_t texel) const { return texels_[texel].cut != kNone; }
  uint32_t texel_first_sub(uint32_t texel) const { return texels_[texel].first_sub; }  // kNone if inert

  uint32_t sub_texel_count() const { return uint32_t(subs_.size()); }
  double area(uint32_t sub) const { return subs_[sub].area; }
  // The share of its texel's area that sub-texel `sub` covers: 1 for an uncut
  // texel, its cells' share of the area element for a cut one.
  double cover(uint32_t sub) const;
  Vec3d point(uint32_t sub) const { return subs_[sub].p; }    // representative point on the sub-texel
  Vec3d normal(uint32_t sub) const { return subs_[sub].n; }   // the solid's outward normal there
  uint32_t texel_of_sub(uint32_t sub) const { return subs_[sub].texel; }

  // The sub-texel holding a ray hit on face `face` of primitive `prim` (the
  // primitive whose face the ray crossed: [Thesis]'s traversal affiliation),
  // or -1: the texel from face_param, then the label of the grid cell nearest
  // to the hit that is on the boundary. A hit in a texel classified inert
  // (a sliver thinner than the grid) goes to the nearest boundary cell of
  // the neighbouring texels.
  int64_t sub_texel_of_hit(uint32_t prim, int face, Vec3d p) const;

  // A point on sub-texel `sub` from two uniform numbers (for direct light):
  // a cell picked by area, a point jittered inside it, re-jittered up to 4
  // times while it is off the boundary, else the cell centre. Uniform in
  // area where the chart is equal-area; elsewhere within the area element's
  // variation across one cell. n is the solid's outward normal.
  void sample_point(uint32_t sub, double u1, double u2, Vec3d& p, Vec3d& n) const;

  // Transfer to an artist's tessellated mesh: the sub-texel of the CSG surface
  // point nearest to p along the line p +- normal_hint (then along the three
  // axes if that line finds nothing), within 2 * tessellation_tolerance; -1 if
  // none.
  int64_t lookup(Vec3d p, Vec3d normal_hint, double tessellation_tolerance) const;

 private:
  struct Texel {
    uint32_t first_sub;  // kNone: inert
    uint32_t cut;        // index of the cut texel, kNone if uncut
  };
  struct SubTexel {
    Vec3d p, n;
    double area;
    uint32_t texel;
    uint16_t label;   // region label within a cut texel (0 if uncut)
    uint8_t flipped;  // the solid's normal is minus the face's
  };

  // Set-up, in the constructor's order.
  uint64_t add_faces(const CsgLightmapSettings& settings);
  void count_sub_texels(std::vector<uint16_t>& counts, std::vector<uint8_t>& cut) const;
  void place_sub_texels(const std::vector<uint16_t>& counts, const std::vector<uint8_t>& cut);
  void fill_texel(uint32_t i, bool split);
  void fill_cut_texel(uint32_t i, const Face& f, uint32_t x, uint32_t y, double texel_area);

  FaceCoord cell_centre(const Face& f, uint32_t x, uint32_t y, int cx, int cy) const;
  int classify_texel(const Face& f, uint32_t x, uint32_t y, uint16_t* labels) const;
  double texel_area(const Face& f, uint32_t x, uint32_t y) const;
  bool flipped_at(const FacePoint& fp) const;
  int64_t nearest_in_texel(uint32_t texel, double cx, double cy, double& dist2) const;

  const CsgObject* obj_;
  int g_;
  std::vector<Face> faces_;
  std::vector<uint32_t> prim_first_face_;  // faces_ index of each primitive's face 0
  std::vector<Texel> texels_;
  std::vector<SubTexel> subs_;
  std::vector<uint16_t> cut_counts_;  // sub-texels per cut texel
  std::vector<uint16_t> labels_;      // g * g per cut texel, kNoLabel off the boundary
  std::vector<float> weights_;        // g * g per cut texel: area element at the cell centre / texel mean
  CsgLightmapStats stats_;
};

}  // namespace plm::csg
