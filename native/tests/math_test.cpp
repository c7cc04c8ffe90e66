// The hot-loop helpers of util/math.h and util/rng.h against their reference
// definitions: the photon pass relies on them giving the same numbers.
#include "util/math.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "util/rng.h"

namespace plm {
namespace {

bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

// sincos_2pi against double-precision sin / cos of 2 pi u: every float u
// that is a multiple of 2^-24 (what Rng::next_float returns) plus random
// floats in [0, 1) (Sobol points).
TEST(Math, SinCos2PiMatchesLibm) {
  double worst = 0.0;
  auto check = [&](float u) {
    float s, c;
    sincos_2pi(u, s, c);
    const double a = 2.0 * kPiD * double(u);
    worst = std::max({worst, std::fabs(double(s) - std::sin(a)), std::fabs(double(c) - std::cos(a))});
  };
  for (uint32_t i = 0; i < (1u << 24); i += 3) check(float(i) * (1.0f / 16777216.0f));
  std::mt19937 gen(5);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  for (int i = 0; i < 1000000; ++i) check(uni(gen));
  EXPECT_LT(worst, 2e-7);  // a few float ulps; std::sinf is within 6e-8

  // Exact at the quarter turns, signs included.
  const float us[4] = {0.0f, 0.25f, 0.5f, 0.75f}, ss[4] = {0.0f, 1.0f, 0.0f, -1.0f}, cs[4] = {1.0f, 0.0f, -1.0f, 0.0f};
  for (int k = 0; k < 4; ++k) {
    float s, c;
    sincos_2pi(us[k], s, c);
    EXPECT_EQ(s, ss[k]) << us[k];
    EXPECT_EQ(c, cs[k]) << us[k];
  }
}

TEST(Math, CosineHemisphereIsUnitAndUpward) {
  Rng rng(3, 4);
  for (int i = 0; i < 100000; ++i) {
    const Vec3 d = cosine_hemisphere(rng.next_float(), rng.next_float());
    EXPECT_NEAR(length(d), 1.0f, 1e-6f);
    EXPECT_GE(d.z, 0.0f);
  }
}

// The photon tracer stores make_frame(n) per triangle and uses (t, -b) on the
// back side: that must be bit for bit make_frame(-n).
TEST(Math, FrameOfFlippedNormalIsTAndMinusB) {
  std::mt19937 gen(11);
  std::normal_distribution<float> g;
  for (int i = 0; i < 200000; ++i) {
    Vec3 n = normalize(Vec3{g(gen), g(gen), g(gen)});
    if (i % 1000 == 0) n = {0.0f, 0.0f, i % 2000 ? 1.0f : -1.0f};  // the poles, where the sign switches
    Vec3 t, b, tf, bf;
    make_frame(n, t, b);
    make_frame(-n, tf, bf);
    const Vec3 mb = -b;
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(same_bits(tf[k], t[k])) << i;
      ASSERT_TRUE(same_bits(bf[k], mb[k])) << i;
    }
  }
}

// radical_inverse2 (byte swap + three steps) against the plain bit loop.
TEST(Rng, RadicalInverseReversesBits) {
  Rng rng(1, 2);
  for (int i = 0; i < 100000; ++i) {
    const uint64_t x = i < 50000 ? uint64_t(i) : (uint64_t(rng.next_u32()) << 32 | rng.next_u32());
    uint64_t r = 0;
    for (int k = 0; k < 64; ++k) r |= ((x >> k) & 1u) << (63 - k);
    ASSERT_EQ(radical_inverse2(x), double(r >> 11) * (1.0 / 9007199254740992.0)) << x;
  }
}

TEST(Rng, PrehashedSeedGivesTheSameStream) {
  Rng a(42, 7), b(Rng::SeedHash{splitmix64(42)}, 7);
  for (int i = 0; i < 100; ++i) ASSERT_EQ(a.next_u32(), b.next_u32());
}

}  // namespace
}  // namespace plm
