// One Embree user geometry (one primitive) over an object of ours: the CSG
// solids and the L-system objects attach themselves through this.
#pragma once

#include <embree3/rtcore.h>

namespace plm {

// Attaches a user geometry whose callbacks receive `object` as their user
// pointer; returns its geometry id. The object is referenced, not copied.
inline unsigned attach_user_geometry(RTCDevice device, RTCScene scene, const void* object, RTCBoundsFunction bounds,
                                     RTCIntersectFunctionN intersect, RTCOccludedFunctionN occluded) {
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
  rtcSetGeometryUserPrimitiveCount(geom, 1);
  rtcSetGeometryUserData(geom, const_cast<void*>(object));
  rtcSetGeometryBoundsFunction(geom, bounds, nullptr);
  rtcSetGeometryIntersectFunction(geom, intersect);
  rtcSetGeometryOccludedFunction(geom, occluded);
  rtcCommitGeometry(geom);
  const unsigned id = rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  return id;
}

}  // namespace plm
