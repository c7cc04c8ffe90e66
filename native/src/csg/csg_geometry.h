// A CsgObject inside an Embree scene, as one user-geometry primitive: Embree's
// BVH culls by the object's bounds, the callbacks trace the object exactly.
//
// What a hit holds (the Mitsuba habit: only t, uv and ids; shading data is
// recomputed afterwards from the CSG object):
//   tfar    the ray parameter (the ray's direction need not be unit)
//   Ng      unit world normal pointing out of the solid
//   u       the face id within the primitive, as an integer-valued float
//           (recover it with uint32_t(hit.u)); the normal, material and
//           (u, v) face parameters follow from primitive + face + point
//   v       1 for a face of a subtracted primitive (normal = minus the
//           primitive's outward normal), else 0
//   primID  the CSG primitive whose face was crossed (not Embree's 0)
//   geomID  the id returned by attach_csg; instID[0] from the context
// Context and geometry filter functions see every crossing of the object in
// order along the ray; rejecting one moves on to the object's next crossing
// (a ray leaving a face can skip that face and still hit the object again).
// occluded() sets tfar = -inf as Embree expects.
#pragma once

#include <embree3/rtcore.h>

#include "csg/csg.h"

namespace plm::csg {

// Attaches obj to scene (not yet committed) and returns its geometry id.
// obj is referenced, not copied: it must outlive every use of the scene.
unsigned attach_csg(RTCDevice device, RTCScene scene, const CsgObject& obj);

}  // namespace plm::csg
