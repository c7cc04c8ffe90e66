#include "ol/octahedral.h"

#include <algorithm>
#include <map>
#include <mutex>
#include <vector>

#include "util/error.h"

namespace plm::ol {

namespace {

// Signed solid angle of the spherical triangle a, b, c (unit vectors), positive
// when counter-clockwise seen from outside (Van Oosterom & Strackee 1983).
double triangle_solid_angle(Vec3d a, Vec3d b, Vec3d c) {
  const double num = dot(a, cross(b, c));
  const double den = 1.0 + dot(a, b) + dot(b, c) + dot(c, a);
  return 2.0 * std::atan2(num, den);
}

// The bins' solid angles at resolution n (see OctGrid).
std::vector<double> solid_angles(uint32_t n) {
  std::vector<double> omega(size_t(n) * n, 0.0);
  // Each bin is cut into S x S cells of two spherical triangles whose corners
  // lie on the map. Neighbouring cells share corners, so the triangles tile
  // the sphere and the bins sum to 4 pi up to rounding whatever S is; S only
  // sets how closely the geodesic edges follow the map's curved bin edges.
  // About 2^20 cells in all keep this to tens of milliseconds.
  const uint32_t s = std::clamp<uint32_t>(1024 / n, 1, 16);
  const uint32_t m = n * s;
  std::vector<Vec3d> lo(m + 1), hi(m + 1);
  for (uint32_t a = 0; a <= m; ++a) hi[a] = oct_decode(double(a) / m, 0.0);
  for (uint32_t b = 0; b < m; ++b) {
    lo.swap(hi);
    for (uint32_t a = 0; a <= m; ++a) hi[a] = oct_decode(double(a) / m, double(b + 1) / m);
    const bool low_half = 2 * b < m;
    for (uint32_t a = 0; a < m; ++a) {
      // Split along the diagonal parallel to the diamond's edge in this
      // quadrant, so no triangle straddles the map's kink there.
      const bool anti = (2 * a < m) == low_half;
      const Vec3d p00 = lo[a], p10 = lo[a + 1], p01 = hi[a], p11 = hi[a + 1];
      const double w = anti ? triangle_solid_angle(p00, p10, p01) + triangle_solid_angle(p10, p11, p01)
                            : triangle_solid_angle(p00, p10, p11) + triangle_solid_angle(p00, p11, p01);
      omega[size_t(b / s) * n + a / s] += w;
    }
  }
  return omega;
}

}  // namespace

OctGrid::OctGrid(uint32_t resolution) : n_(resolution) {
  if (resolution == 0 || resolution > kMaxOlResolution)
    fail(PLM_ERROR_INVALID_ARGUMENT, "orientation lightmap resolution ", resolution, " is out of range: must be 1..",
         kMaxOlResolution);
  // The bins' solid angles take tens of milliseconds per resolution: made
  // once per process and resolution, then copied (a bake creates an OL per
  // L-system stub instance that photons hit, while it merges photon batches).
  static std::mutex mutex;
  static std::map<uint32_t, std::vector<double>> made;  // node addresses are stable
  const std::vector<double>* omega = nullptr;
  {
    std::lock_guard<std::mutex> lock(mutex);
    const auto it = made.find(n_);
    if (it != made.end()) omega = &it->second;
  }
  if (!omega) {
    std::vector<double> w = solid_angles(n_);
    std::lock_guard<std::mutex> lock(mutex);
    omega = &made.emplace(n_, std::move(w)).first->second;  // another thread's equal values may be there first
  }
  omega_ = *omega;
}

}  // namespace plm::ol
