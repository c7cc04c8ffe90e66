#include "csg/coplanar.h"

#include <cmath>

namespace plm::csg {
namespace {

constexpr int kDiskSides = 24;

struct PlanarFace {
  int face;
  Vec3d n, c;  // world unit normal, a point of the face
  int count;   // polygon corners; 0 for the unbounded plane of a half-space
  Vec3d v[kDiskSides];
};

std::string face_label(Shape shape, int face) {
  static const char* const box[] = {"-X", "+X", "-Y", "+Y", "-Z", "+Z"};
  std::string s = shape_name(shape);
  switch (shape) {
    case Shape::Box:
      return s + " face " + box[face];
    case Shape::Cylinder:
      return s + (face == 1 ? " bottom cap" : " top cap");
    case Shape::Cone:
      return s + " base";
    case Shape::Paraboloid:
      return s + " cap";
    default:
      return s + " plane";
  }
}

// A disk of radius 1 at height z as a polygon that contains it, so that an
// overlap is never missed (at worst a near-miss is reported).
void disk(const Primitive& p, int face, double z, PlanarFace& f) {
  f.face = face;
  f.count = kDiskSides;
  const double r = 1.0 / std::cos(3.14159265358979323846 / kDiskSides);
  for (int i = 0; i < kDiskSides; ++i) {
    const double a = 2 * 3.14159265358979323846 * i / kDiskSides;
    f.v[i] = p.to_world.point({r * std::cos(a), r * std::sin(a), z});
  }
  f.c = p.to_world.point({0, 0, z});
  f.n = normal(p, face, f.c);
}

int planar_faces(const Primitive& p, PlanarFace out[6]) {
  switch (p.shape) {
    case Shape::Box:
      for (int face = 0; face < 6; ++face) {
        PlanarFace& f = out[face];
        const int a = face / 2, b = (a + 1) % 3, e = (a + 2) % 3;
        const double corner[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
        Vec3d q;
        q[a] = (face & 1) ? 1.0 : -1.0;
        for (int i = 0; i < 4; ++i) {
          q[b] = corner[i][0];
          q[e] = corner[i][1];
          f.v[i] = p.to_world.point(q);
        }
        f.face = face;
        f.count = 4;
        q[b] = q[e] = 0;
        f.c = p.to_world.point(q);
        f.n = normal(p, face, f.c);
      }
      return 6;
    case Shape::Cylinder:
      disk(p, 1, -1, out[0]);
      disk(p, 2, 1, out[1]);
      return 2;
    case Shape::Cone:
      disk(p, 1, -1, out[0]);
      return 1;
    case Shape::Paraboloid:
      disk(p, 1, 1, out[0]);
      return 1;
    case Shape::HalfSpace:
      out[0].face = 0;
      out[0].count = 0;
      out[0].c = p.to_world.column(3);
      out[0].n = normal(p, 0, out[0].c);
      return 1;
    default:
      return 0;
  }
}

// Separating-axis test of two convex polygons in the plane (t, b): they
// overlap if no edge normal separates them by more than -tol (touching
// along an edge is not an overlap).
bool polygons_overlap(const PlanarFace& f, const PlanarFace& g, Vec3d t, Vec3d b, double tol) {
  const PlanarFace* poly[2] = {&f, &g};
  for (int s = 0; s < 2; ++s) {
    const PlanarFace& p = *poly[s];
    for (int i = 0; i < p.count; ++i) {
      const Vec3d e = p.v[(i + 1) % p.count] - p.v[i];
      const double ex = dot(e, t), ey = dot(e, b), len = std::hypot(ex, ey);
      if (!(len > 0)) continue;
      const double ax = -ey / len, ay = ex / len;
      double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
      for (int k = 0; k < 2; ++k)
        for (int j = 0; j < poly[k]->count; ++j) {
          const double x = ax * dot(poly[k]->v[j], t) + ay * dot(poly[k]->v[j], b);
          lo[k] = std::fmin(lo[k], x);
          hi[k] = std::fmax(hi[k], x);
        }
      if (hi[0] <= lo[1] + tol || hi[1] <= lo[0] + tol) return false;
    }
  }
  return true;
}

bool faces_overlap(const PlanarFace& f, const PlanarFace& g, double tol) {
  if (std::fabs(dot(f.n, g.n)) < 1 - 1e-9) return false;
  if (std::fabs(dot(f.n, g.c - f.c)) > tol) return false;
  if (f.count == 0 || g.count == 0) return true;  // an infinite plane meets any face in it
  const Vec3d t = normalize(cross(f.n, std::fabs(f.n.x) < 0.9 ? Vec3d{1, 0, 0} : Vec3d{0, 1, 0}));
  return polygons_overlap(f, g, t, cross(f.n, t), tol);
}

bool boxes_overlap(const Primitive& a, const Primitive& b, double tol) {
  for (int k = 0; k < 3; ++k)
    if (a.hi[k] + tol < b.lo[k] || b.hi[k] + tol < a.lo[k]) return false;
  return true;
}

}  // namespace

std::vector<std::string> find_coplanar_faces(const std::string& object, const std::vector<Primitive>& prims,
                                             const std::vector<bool>& used, double tol) {
  std::vector<std::string> out;
  PlanarFace fa[6], fb[6];
  for (size_t i = 0; i < prims.size(); ++i) {
    if (!used[i]) continue;
    const int na = planar_faces(prims[i], fa);
    for (size_t j = i + 1; j < prims.size() && na > 0; ++j) {
      if (!used[j] || !boxes_overlap(prims[i], prims[j], tol)) continue;
      const int nb = planar_faces(prims[j], fb);
      bool found = false;
      for (int a = 0; a < na && !found; ++a)
        for (int b = 0; b < nb && !found; ++b) {
          if (!faces_overlap(fa[a], fb[b], tol)) continue;
          found = true;
          out.push_back("CSG object '" + object + "': primitives " + std::to_string(i) + " (" +
                        face_label(prims[i].shape, fa[a].face) + ") and " + std::to_string(j) + " (" +
                        face_label(prims[j].shape, fb[b].face) +
                        ") have coplanar overlapping faces; the shared part follows the coincident-face rule");
        }
    }
  }
  return out;
}

}  // namespace plm::csg
