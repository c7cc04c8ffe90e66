// Owen-scrambled Sobol points (util/sobol.h): the stratification that makes
// them worth using, checked on the points themselves.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "util/sobol.h"

namespace {

// Every dimension of the first 2^m points of a group puts exactly one point in
// each interval [k / 2^m, (k + 1) / 2^m), whatever the key and group.
TEST(Sobol, EachDimensionIsStratified) {
  const uint32_t m = 10, n = 1u << m;
  for (uint32_t key : {0u, 12345u, 0xdeadbeefu}) {
    for (uint32_t group : {0u, 1u, 7u}) {
      std::vector<int> count[4];
      for (auto& c : count) c.assign(n, 0);
      for (uint32_t i = 0; i < n; ++i) {
        float u[4];
        plm::sobol_group(i, key, group, 4, u);
        for (int d = 0; d < 4; ++d) {
          ASSERT_GE(u[d], 0.0f);
          ASSERT_LT(u[d], 1.0f);
          ++count[d][uint32_t(u[d] * float(n))];
        }
      }
      for (int d = 0; d < 4; ++d)
        for (uint32_t k = 0; k < n; ++k) ASSERT_EQ(count[d][k], 1) << "dim " << d << " interval " << k;
    }
  }
}

// Dimensions 0 and 1 form a (0, m, 2)-net: every elementary box of area 2^-m
// (2^a x 2^(m - a) cells) holds exactly one of the first 2^m points.
TEST(Sobol, FirstTwoDimensionsFormANet) {
  const uint32_t m = 8, n = 1u << m;
  std::vector<float> x(n), y(n);
  for (uint32_t i = 0; i < n; ++i) {
    float u[2];
    plm::sobol_group(i, 777u, 3, 2, u);
    x[i] = u[0], y[i] = u[1];
  }
  for (uint32_t a = 0; a <= m; ++a) {
    const uint32_t cx = 1u << a, cy = 1u << (m - a);
    std::vector<int> count(n, 0);
    for (uint32_t i = 0; i < n; ++i) ++count[uint32_t(x[i] * cx) * cy + uint32_t(y[i] * cy)];
    for (uint32_t k = 0; k < n; ++k) ASSERT_EQ(count[k], 1) << "boxes " << cx << " x " << cy;
  }
}

// Different keys give different (independent) point sets; the same key the same.
TEST(Sobol, KeysRandomiseDeterministically) {
  float a[4], b[4], c[4];
  plm::sobol_group(5, 1, 0, 4, a);
  plm::sobol_group(5, 1, 0, 4, b);
  plm::sobol_group(5, 2, 0, 4, c);
  for (int d = 0; d < 4; ++d) EXPECT_EQ(a[d], b[d]);
  EXPECT_TRUE(a[0] != c[0] || a[1] != c[1] || a[2] != c[2] || a[3] != c[3]);
  // Over many keys, a point's coordinate is uniform: its mean is 1/2.
  double sum = 0.0;
  for (uint32_t key = 0; key < 20000; ++key) {
    float u[4];
    plm::sobol_group(3, key, 0, 4, u);
    sum += u[2];
  }
  EXPECT_NEAR(sum / 20000.0, 0.5, 4.0 * 0.2887 / std::sqrt(20000.0));
}

}  // namespace

// The byte tables give exactly the XOR of the direction numbers of the
// index's set bits (the definition), for every dimension and any index.
TEST(Sobol, ByteTablesMatchTheDirectionNumbers) {
  using namespace plm::sobol_detail;
  plm::Rng rng(7, 1);
  for (int n = 0; n < 20000; ++n) {
    const uint32_t index = n < 1000 ? uint32_t(n) : rng.next_u32();
    for (int dim = 1; dim < 4; ++dim) {
      uint32_t x = 0;
      for (int k = 0; k < 32; ++k)
        if ((index >> k) & 1u) x ^= kDirections[dim - 1][k];
      ASSERT_EQ(sobol(index, dim), x) << "index " << index << " dimension " << dim;
    }
  }
  // Known start of dimension 2 (x_k = x_{k-1} ^ v_{gray change}): 1/2, 3/4, 1/4.
  EXPECT_EQ(sobol(1, 1), 0x80000000u);
  EXPECT_EQ(sobol(2, 1), 0xC0000000u);
  EXPECT_EQ(sobol(3, 1), 0x40000000u);
}

// SobolGroup::point works on reversed bits (no reversal between the index
// shuffle and the scrambles): the same floats as the plain definition.
TEST(Sobol, PointsMatchThePlainDefinition) {
  using namespace plm::sobol_detail;
  plm::Rng rng(11, 2);
  for (uint32_t x : {0u, 1u, 0x80000000u, 0x12345678u, 0xFFFFFFFFu, rng.next_u32()}) {
    uint32_t r = 0;
    for (int bit = 0; bit < 32; ++bit) r |= ((x >> bit) & 1u) << (31 - bit);
    ASSERT_EQ(reverse_bits(x), r) << x;
  }
  for (uint32_t key : {0u, 1u, 0xDEADBEEFu, rng.next_u32()})
    for (uint32_t group = 0; group < 4; ++group) {
      const plm::SobolGroup points(key, group);
      const uint32_t index_key = hash(key, group);
      for (int n = 0; n < 5000; ++n) {
        const uint32_t index = n < 4096 ? uint32_t(n) : rng.next_u32();
        float fast[4];
        points.point(index, 4, fast);
        const uint32_t i = owen_scramble(index, index_key);
        for (int d = 0; d < 4; ++d)
          ASSERT_EQ(fast[d], to_float(owen_scramble(sobol(i, d), hash(index_key, uint32_t(d) + 1))))
              << "key " << key << " group " << group << " index " << index << " dimension " << d;
      }
    }
}
