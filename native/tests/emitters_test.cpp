// Emitter sampling with the frame computed once per emitter (build_emitters).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "transport/lights/emitters.h"
#include "util/math.h"
#include "util/rng.h"

namespace plm {
namespace {

bool same_bits(Vec3 a, Vec3 b) { return std::memcmp(&a, &b, sizeof(Vec3)) == 0; }

// A light rotated 30 degrees about x and 50 about z, 1 m up.
plm_light tilted(plm_light_type type) {
  plm_light l;
  plm_light_default(&l, type);
  const float a = 0.5235988f, b = 0.8726646f;
  const float ca = std::cos(a), sa = std::sin(a), cb = std::cos(b), sb = std::sin(b);
  const float r[9] = {cb, -sb * ca, sb * sa, sb, cb * ca, -cb * sa, 0.0f, sa, ca};  // Rz(b) Rx(a)
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) l.matrix[4 * i + j] = r[3 * i + j];
  l.matrix[3] = 0.0f;
  l.matrix[7] = 0.0f;
  l.matrix[11] = 1.0f;
  l.matrix[12] = l.matrix[13] = l.matrix[14] = 0.0f;
  l.matrix[15] = 1.0f;
  l.power = 100.0f;
  l.size_x = 0.5f;
  l.size_y = 0.25f;
  return l;
}

// Spot, rectangle and disk: the stored frame is make_frame(normal) bit for
// bit (what sample_emitter computed per photon before), and the directions
// follow their laws: cosine-weighted about the emitting side (mean cosine
// 2/3) for area lights, inside the cone for the spot.
TEST(Emitters, FrameOncePerEmitterSamplesTheSameLaws) {
  Scene scene;
  scene.lights.push_back({"spot", tilted(PLM_LIGHT_SPOT)});
  scene.lights.push_back({"rect", tilted(PLM_LIGHT_AREA_RECT)});
  scene.lights.push_back({"disk", tilted(PLM_LIGHT_AREA_DISK)});
  const std::vector<Emitter> emitters = build_emitters(scene, {0, 0, 0}, 10.0f);
  ASSERT_EQ(emitters.size(), 3u);
  for (const Emitter& e : emitters) {
    Vec3 t, b;
    make_frame(e.normal, t, b);
    EXPECT_TRUE(same_bits(t, e.frame_t) && same_bits(b, e.frame_b)) << int(e.kind);
    Rng rng(1, uint64_t(e.kind));
    double mean_cos = 0.0;
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
      const float u[4] = {rng.next_float(), rng.next_float(), rng.next_float(), rng.next_float()};
      const EmitterSample s = sample_emitter(e, u);
      ASSERT_NEAR(length(s.direction), 1.0f, 1e-5f) << int(e.kind);
      const float c = dot(s.direction, e.normal);
      if (e.kind == EmitterKind::Spot) {
        ASSERT_GE(c, e.cos_half - 1e-5f);
      } else {
        ASSERT_GE(c, -1e-6f) << int(e.kind);
      }
      mean_cos += c;
    }
    mean_cos /= n;
    if (e.kind != EmitterKind::Spot) {
      EXPECT_NEAR(mean_cos, 2.0 / 3.0, 0.003) << int(e.kind);  // its standard error: about 0.0005
    }
  }
}

}  // namespace
}  // namespace plm
