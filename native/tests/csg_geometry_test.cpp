// A CSG object inside an Embree scene, next to a triangle mesh: rtcIntersect1
// and rtcOccluded1 must agree with the object's own first_hit, and context
// filters must see each crossing in turn.
#include <gtest/gtest.h>
#include <embree3/rtcore.h>

#include <cmath>

#include "csg/csg_geometry.h"

namespace {

using namespace plm::csg;
using plm::Vec3d;

PrimitiveDesc prim(Shape shape, Vec3d s, Vec3d t) {
  PrimitiveDesc d;
  d.shape = shape;
  const double m[12] = {s.x, 0, 0, t.x, 0, s.y, 0, t.y, 0, 0, s.z, t.z};
  std::copy(m, m + 12, d.to_world);
  return d;
}

// Sphere (radius 1 at c) minus a cylinder (radius 0.4) along z through it.
CsgObject holed_sphere(Vec3d c) {
  CsgDesc d;
  d.name = "holed";
  d.primitives = {prim(Shape::Sphere, {1, 1, 1}, c), prim(Shape::Cylinder, {0.4, 0.4, 2}, c)};
  d.materials = {3, 4};
  d.nodes = {{Op::Leaf, 0, 0}, {Op::Leaf, 1, 0}, {Op::Difference, 0, 2}};
  d.children = {0, 1};
  d.root = 2;
  return CsgObject(d);
}

struct Fixture {
  RTCDevice device = rtcNewDevice(nullptr);
  RTCScene scene = rtcNewScene(device);
  unsigned csg_id = 0, quad_id = 0;
  Fixture(const CsgObject& obj, float quad_x) {
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    // A large quad in the plane x = quad_x.
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 4));
    const float verts[12] = {quad_x, -10, -10, quad_x, 10, -10, quad_x, 10, 10, quad_x, -10, 10};
    std::copy(verts, verts + 12, v);
    auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, 2));
    const unsigned tris[6] = {0, 1, 2, 0, 2, 3};
    std::copy(tris, tris + 6, idx);
    rtcCommitGeometry(g);
    quad_id = rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    csg_id = attach_csg(device, scene, obj);
    rtcCommitScene(scene);
  }
  ~Fixture() {
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
  }
};

RTCRayHit make_rayhit(Vec3d o, Vec3d d, float tnear, float tfar) {
  RTCRayHit rh{};
  rh.ray.org_x = float(o.x);
  rh.ray.org_y = float(o.y);
  rh.ray.org_z = float(o.z);
  rh.ray.dir_x = float(d.x);
  rh.ray.dir_y = float(d.y);
  rh.ray.dir_z = float(d.z);
  rh.ray.tnear = tnear;
  rh.ray.tfar = tfar;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

TEST(CsgGeometry, EmbreeHitsMatchFirstHit) {
  const CsgObject obj = holed_sphere({0.5, 0.25, -0.5});
  Fixture fx(obj, 1.0f);  // the quad cuts through the sphere
  plm::Rng rng(5, 0);
  int csg_hits = 0, quad_hits = 0;
  for (int i = 0; i < 5000; ++i) {
    // Origins and directions exactly representable in float, so both see the same ray.
    const Vec3d o{float(-4 + 0.5 * next_double(rng)), float(3 * next_double(rng) - 1.5), float(3 * next_double(rng) - 2)};
    const Vec3d d{float(1 + next_double(rng)), float(0.6 * next_double(rng) - 0.3), float(0.6 * next_double(rng) - 0.3)};
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh = make_rayhit(o, d, 0.0f, INFINITY);
    rtcIntersect1(fx.scene, &ctx, &rh);
    const double t_quad = (1.0 - o.x) / d.x;
    CsgHit hit;
    const bool has = obj.first_hit(o, d, 0, INFINITY, hit);
    const bool quad_in_range = std::fabs(o.y + t_quad * d.y) < 10 && std::fabs(o.z + t_quad * d.z) < 10;
    if (has && (!quad_in_range || hit.t < t_quad)) {
      ++csg_hits;
      ASSERT_EQ(rh.hit.geomID, fx.csg_id) << i;
      EXPECT_NEAR(rh.ray.tfar, hit.t, 1e-5 * hit.t);
      EXPECT_EQ(rh.hit.primID, hit.prim);
      EXPECT_EQ(uint32_t(rh.hit.u), hit.face);  // the face id travels in u
      EXPECT_EQ(rh.hit.v, hit.flipped ? 1.0f : 0.0f);
      // Embree's copy of the ray may differ by float rounding, which moves
      // near-silhouette hits a little: compare normals loosely.
      EXPECT_NEAR(rh.hit.Ng_x, hit.n.x, 1e-4);
      EXPECT_NEAR(rh.hit.Ng_y, hit.n.y, 1e-4);
      EXPECT_NEAR(rh.hit.Ng_z, hit.n.z, 1e-4);
      EXPECT_EQ(rh.hit.instID[0], RTC_INVALID_GEOMETRY_ID);
    } else if (quad_in_range) {
      ++quad_hits;
      EXPECT_EQ(rh.hit.geomID, fx.quad_id) << i;
      EXPECT_NEAR(rh.ray.tfar, t_quad, 1e-5 * t_quad);
    } else {
      EXPECT_EQ(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID);
    }
    // Occlusion up to just before the first hit, and beyond it.
    const float t_first = rh.ray.tfar;
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
      RTCRay short_ray = make_rayhit(o, d, 0.0f, t_first * 0.999f).ray;
      rtcOccluded1(fx.scene, &ctx, &short_ray);
      EXPECT_GE(short_ray.tfar, 0.0f) << i;
      RTCRay long_ray = make_rayhit(o, d, 0.0f, t_first * 1.001f).ray;
      rtcOccluded1(fx.scene, &ctx, &long_ray);
      EXPECT_EQ(long_ray.tfar, -INFINITY) << i;
    }
  }
  EXPECT_GT(csg_hits, 1000);
  EXPECT_GT(quad_hits, 1000);
}

TEST(CsgGeometry, RespectsTnearAndTfar) {
  const CsgObject obj = holed_sphere({0, 0, 0});
  Fixture fx(obj, 50.0f);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  // Along x through the centre: sphere at t = 4, hole wall at 4.6 and 5.4, sphere at 6.
  RTCRayHit rh = make_rayhit({-5, 0, 0}, {1, 0, 0}, 4.5f, INFINITY);
  rtcIntersect1(fx.scene, &ctx, &rh);
  ASSERT_EQ(rh.hit.geomID, fx.csg_id);
  EXPECT_NEAR(rh.ray.tfar, 4.6f, 1e-6);
  EXPECT_EQ(rh.hit.primID, 1u);
  EXPECT_EQ(rh.hit.v, 1.0f);     // the cylinder is subtracted
  EXPECT_NEAR(rh.hit.Ng_x, 1, 1e-6);  // out of the solid, into the hole
  rh = make_rayhit({-5, 0, 0}, {1, 0, 0}, 0.0f, 3.9f);
  rtcIntersect1(fx.scene, &ctx, &rh);
  EXPECT_EQ(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID);
  EXPECT_EQ(rh.ray.tfar, 3.9f);
}

// Rejects hits on one CSG primitive, as the bake's context skips the triangle a ray leaves.
struct SkipContext {
  RTCIntersectContext context;
  unsigned geom, prim;
};

void skip_primitive(const RTCFilterFunctionNArguments* args) {
  const auto* sc = reinterpret_cast<const SkipContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i)
    if (args->valid[i] && RTCHitN_geomID(args->hit, args->N, i) == sc->geom &&
        RTCHitN_primID(args->hit, args->N, i) == sc->prim)
      args->valid[i] = 0;
}

TEST(CsgGeometry, ContextFilterSeesEachCrossing) {
  const CsgObject obj = holed_sphere({0, 0, 0});
  Fixture fx(obj, 50.0f);
  SkipContext sc;
  rtcInitIntersectContext(&sc.context);
  sc.context.filter = skip_primitive;
  sc.geom = fx.csg_id;
  sc.prim = 0;  // skip the sphere: the first accepted crossing is the hole's wall
  RTCRayHit rh = make_rayhit({-5, 0, 0}, {1, 0, 0}, 0.0f, INFINITY);
  rtcIntersect1(fx.scene, &sc.context, &rh);
  ASSERT_EQ(rh.hit.geomID, fx.csg_id);
  EXPECT_NEAR(rh.ray.tfar, 4.6f, 1e-6);
  EXPECT_EQ(rh.hit.primID, 1u);
  sc.prim = 1;  // skip the cylinder: the sphere's near side
  rh = make_rayhit({-5, 0, 0}, {1, 0, 0}, 0.0f, INFINITY);
  rtcIntersect1(fx.scene, &sc.context, &rh);
  EXPECT_NEAR(rh.ray.tfar, 4.0f, 1e-6);
  // Occlusion: only cylinder crossings between t = 4.5 and 5.5, all rejected.
  RTCRay ray = make_rayhit({-5, 0, 0}, {1, 0, 0}, 4.5f, 5.5f).ray;
  rtcOccluded1(fx.scene, &sc.context, &ray);
  EXPECT_EQ(ray.tfar, 5.5f);
  sc.prim = 0;
  rtcOccluded1(fx.scene, &sc.context, &ray);
  EXPECT_EQ(ray.tfar, -INFINITY);
  // Bounds reach Embree: a ray that misses the object's box never calls it.
  RTCBounds b;
  rtcGetSceneBounds(fx.scene, &b);
  EXPECT_LE(b.lower_y, -1.0f);
  EXPECT_GE(b.upper_y, 10.0f);
}

}  // namespace
