// The 3D turtle against drawings with exact answers.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "lsystem/language/lsystem.h"
#include "lsystem/language/turtle.h"
#include "util/error.h"

namespace {

using namespace plm::lsystem;

TurtleResult draw(const std::string& text, int depth = -1) {
  const LSystem sys = parse(text);
  DeriveOptions opt;
  opt.depth = depth;
  return interpret(sys, derive(sys, opt));
}

// Checks a 3x4 row-major matrix against columns x, y, z, t.
void expect_matrix(const TurtlePrimitive& p, const double (&cols)[4][3], double tol = 1e-12) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 3; ++r) EXPECT_NEAR(p.to_world[4 * r + c], cols[c][r], tol) << "row " << r << " col " << c;
}

TEST(LSystemTurtle, SquareClosesExactly) {
  const TurtleResult t = draw("angle: 90\nwidth: 0.2\naxiom: F+F+F+F\n");
  ASSERT_EQ(t.primitives.size(), 4u);
  EXPECT_EQ(t.count[int(ShapeKind::Cylinder)], 4u);
  for (double v : t.end_position) EXPECT_NEAR(v, 0.0, 1e-12);
  // Heading +Z, '+' turns towards L = -X: the square is in the XZ plane, x <= 0.
  const double r = 0.1;
  const double expected[4][4][3] = {
      {{-r, 0, 0}, {0, -r, 0}, {0, 0, 0.5}, {0, 0, 0.5}},     // up
      {{0, 0, -r}, {0, -r, 0}, {-0.5, 0, 0}, {-0.5, 0, 1}},   // left
      {{r, 0, 0}, {0, -r, 0}, {0, 0, -0.5}, {-1, 0, 0.5}},    // down
      {{0, 0, r}, {0, -r, 0}, {0.5, 0, 0}, {-0.5, 0, 0}}};    // right, back home
  for (int i = 0; i < 4; ++i) {
    SCOPED_TRACE(i);
    expect_matrix(t.primitives[i], expected[i]);
  }
  EXPECT_NEAR(t.lo[0], -1.1, 1e-12);
  EXPECT_NEAR(t.hi[0], 0.1, 1e-12);
  EXPECT_NEAR(t.lo[1], -0.1, 1e-12);
  EXPECT_NEAR(t.hi[1], 0.1, 1e-12);
  EXPECT_NEAR(t.lo[2], -0.1, 1e-12);
  EXPECT_NEAR(t.hi[2], 1.1, 1e-12);
}

TEST(LSystemTurtle, KochIslandClosesAtAnyDepth) {
  // ABOP fig. 1.7a quadratic Koch island.
  const TurtleResult t = draw("angle: 90\naxiom: F-F-F-F\nF -> F-F+F+FF-F-F+F\n", 2);
  EXPECT_EQ(t.primitives.size(), 4u * 64u);
  for (double v : t.end_position) EXPECT_NEAR(v, 0.0, 1e-9);
}

TEST(LSystemTurtle, OrientationCommands3D) {
  // Pitch, roll, yaw and turn-around at a non-trivial angle keep the frame orthonormal.
  const TurtleResult t = draw("angle: 37\naxiom: F&F/F+F^F\\F-F|f(0)\n");
  EXPECT_EQ(t.primitives.size(), 7u);
  // Every cylinder's frame stays orthonormal: the x, y, z columns have lengths r, r, l/2.
  for (const TurtlePrimitive& p : t.primitives) {
    double len[3] = {0, 0, 0}, d01 = 0, d02 = 0, d12 = 0;
    for (int r = 0; r < 3; ++r) {
      const double* m = p.to_world + 4 * r;
      for (int c = 0; c < 3; ++c) len[c] += m[c] * m[c];
      d01 += m[0] * m[1];
      d02 += m[0] * m[2];
      d12 += m[1] * m[2];
    }
    EXPECT_NEAR(std::sqrt(len[0]), 0.05, 1e-12);
    EXPECT_NEAR(std::sqrt(len[1]), 0.05, 1e-12);
    EXPECT_NEAR(std::sqrt(len[2]), 0.5, 1e-12);
    EXPECT_NEAR(d01, 0, 1e-14);
    EXPECT_NEAR(d02, 0, 1e-14);
    EXPECT_NEAR(d12, 0, 1e-14);
  }
  // & pitches down: H = +Z turns towards -U = +Y.
  const TurtleResult p = draw("angle: 90\naxiom: &F\n");
  EXPECT_NEAR(p.end_position[1], 1.0, 1e-15);
  // \ rolls left by 90 (L -> U_old = -Y, U -> -L_old = +X); & then heads towards -U = -X.
  const TurtleResult q = draw("angle: 90\naxiom: \\&F\n");
  EXPECT_NEAR(q.end_position[0], -1.0, 1e-15);
  // | reverses the heading.
  const TurtleResult r = draw("axiom: F|F(2)\n");
  EXPECT_NEAR(r.end_position[2], -1.0, 1e-15);
}

TEST(LSystemTurtle, PushPopRestoresState) {
  const TurtleResult t = draw("angle: 45\naxiom: F[+F!(0.5)'(3)F]F[-F]F\n");
  ASSERT_EQ(t.primitives.size(), 6u);
  EXPECT_EQ(t.max_stack_depth, 1u);
  // After ']' the turtle is back at (0,0,1) heading +Z with width 0.1, material 0.
  const TurtlePrimitive& after = t.primitives[3];
  EXPECT_NEAR(after.to_world[11], 1.5, 1e-12);
  EXPECT_NEAR(after.to_world[3], 0.0, 1e-12);
  EXPECT_NEAR(after.to_world[0], -0.05, 1e-12);
  EXPECT_EQ(after.material, 0);
  // Inside the branch: width 0.5 (radius 0.25) and material 3 for the third cylinder.
  const TurtlePrimitive& inner = t.primitives[2];
  EXPECT_EQ(inner.material, 3);
  EXPECT_NEAR(std::hypot(inner.to_world[0], inner.to_world[4], inner.to_world[8]), 0.25, 1e-12);
  EXPECT_EQ(t.primitives[1].material, 0);
  for (double v : {t.end_position[0], t.end_position[1]}) EXPECT_NEAR(v, 0.0, 1e-12);
  EXPECT_NEAR(t.end_position[2], 3.0, 1e-12);
}

TEST(LSystemTurtle, WidthMaterialAndEmitters) {
  const TurtleResult t = draw("axiom: !(0.4) ' ' F(2) @O(0.5) @C(3, 0.25) @L(1) @B(1, 2, 4) '(7) @O\n");
  ASSERT_EQ(t.primitives.size(), 6u);
  EXPECT_EQ(t.count[int(ShapeKind::Cylinder)], 1u);
  EXPECT_EQ(t.count[int(ShapeKind::Sphere)], 2u);
  EXPECT_EQ(t.count[int(ShapeKind::Cone)], 1u);
  EXPECT_EQ(t.count[int(ShapeKind::Box)], 2u);
  const double cyl[4][3] = {{-0.2, 0, 0}, {0, -0.2, 0}, {0, 0, 1}, {0, 0, 1}};
  expect_matrix(t.primitives[0], cyl);
  EXPECT_EQ(t.primitives[0].material, 2);
  const double sphere[4][3] = {{-0.5, 0, 0}, {0, -0.5, 0}, {0, 0, 0.5}, {0, 0, 2}};
  expect_matrix(t.primitives[1], sphere);
  const double cone[4][3] = {{-0.25, 0, 0}, {0, -0.25, 0}, {0, 0, 1.5}, {0, 0, 3.5}};  // base z=2, apex z=5
  expect_matrix(t.primitives[2], cone);
  const double leaf[4][3] = {{-0.25, 0, 0}, {0, -0.01, 0}, {0, 0, 0.5}, {0, 0, 2.5}};
  expect_matrix(t.primitives[3], leaf);
  const double box[4][3] = {{-0.5, 0, 0}, {0, -1, 0}, {0, 0, 2}, {0, 0, 2}};
  expect_matrix(t.primitives[4], box);
  EXPECT_EQ(t.primitives[5].material, 7);
  const double dflt[4][3] = {{-0.2, 0, 0}, {0, -0.2, 0}, {0, 0, 0.2}, {0, 0, 2}};  // radius width/2
  expect_matrix(t.primitives[5], dflt);
  EXPECT_NEAR(t.hi[2], 5.0, 1e-12);  // the cone's apex
  EXPECT_NEAR(t.lo[2], 0.0, 1e-12);
}

TEST(LSystemTurtle, ParametricTreeIsFiniteAndBounded) {
  const TurtleResult t = draw(
      "#define R 0.7\nangle: 30\ndepth: 8\naxiom: A(1, 0.2)\n"
      "A(l, w) : l > 0.1 -> !(w) F(l) [+ A(l*R, w*R)] [- A(l*R, w*R)] [& A(l*R, w*R)]\n"
      "A(l, w) : l <= 0.1 -> @L(0.2)\n");
  EXPECT_GT(t.primitives.size(), 100u);
  for (const TurtlePrimitive& p : t.primitives) {
    for (double v : p.to_world) ASSERT_TRUE(std::isfinite(v));
    for (int r = 0; r < 3; ++r) {
      EXPECT_GE(p.to_world[4 * r + 3], t.lo[r]);
      EXPECT_LE(p.to_world[4 * r + 3], t.hi[r]);
    }
  }
}

TEST(LSystemTurtle, Errors) {
  auto msg = [](const std::string& text) -> std::string {
    try {
      draw(text);
    } catch (const plm::Error& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(msg("axiom: F ] F\n"), "turtle: module 2 (']'): ']' without a matching '['");
  EXPECT_EQ(msg("axiom: !(-1)\n"), "turtle: module 1 ('!'): the width must be >= 0, got -1");
  EXPECT_EQ(msg("axiom: '(1.5)\n"), "turtle: module 1 ('''): the material index must be a whole number in [0, 2^31), got 1.5");
  EXPECT_NE(msg("axiom: F(1e308) F(1e308)\n").find("overflowed"), std::string::npos);
  // Empty string: no primitives, empty bounds.
  const TurtleResult e = draw("axiom:\n");
  EXPECT_TRUE(e.primitives.empty());
  EXPECT_GT(e.lo[0], e.hi[0]);
}

}  // namespace
