// L-system parse errors name the line, the column and what was expected.
#include <gtest/gtest.h>

#include <string>

#include "lsystem/language/lsystem.h"
#include "util/error.h"

namespace {

using namespace plm::lsystem;

std::string parse_error(const std::string& text) {
  try {
    parse(text);
  } catch (const plm::Error& e) {
    EXPECT_EQ(e.status(), PLM_ERROR_INVALID_ARGUMENT);
    return e.what();
  }
  return "";
}

TEST(LSystemParse, ErrorsNameLineAndColumn) {
  EXPECT_EQ(parse_error("axiom: A(1, 2)\n\nA(l, w) -> F(l) A(l * 0.7, w\n"),
            "line 3, column 29: expected ')' after parameters of module 'A'");
  EXPECT_EQ(parse_error("axiom: A\nA B -> C\n"),
            "line 2, column 3: expected one predecessor module, found 2 (use '<' and '>' to give a context)");
  EXPECT_EQ(parse_error("axiom: A\nA : x > 1 -> B\n"),
            "line 2, column 5: unknown identifier 'x' (not a parameter of this production or a constant)");
  EXPECT_EQ(parse_error("axiom: A\nA -> B(1 +)\n"), "line 2, column 11: expected an expression, found ')'");
  EXPECT_EQ(parse_error("axiom: A\nA\n"), "line 2, column 2: expected '->' after the predecessor");
  EXPECT_EQ(parse_error("axiom: A(1)\nA(x) -> B(foo(x))\n"), "line 2, column 11: unknown function 'foo'");
  EXPECT_EQ(parse_error("axiom: A(1)\nA(x) -> B(min(x))\n"), "line 2, column 11: min takes 2 arguments, found 1");
  EXPECT_EQ(parse_error("axiom: A ~ B\n"), "line 1, column 10: expected a module in the axiom, found '~'");
  EXPECT_EQ(parse_error("axiom: A\naxiom: B\n"), "line 2, column 1: a second 'axiom:' line (the first is enough)");
  EXPECT_EQ(parse_error("A -> B\n"), "line 2, column 1: the system has no 'axiom:' line");
  EXPECT_EQ(parse_error("axiom: A(1e999)\n"), "line 1, column 10: number '1e999' is out of the range of a double");
  EXPECT_EQ(parse_error("axiom: A\n  A(x, x) -> B\n"),
            "line 2, column 8: parameter 'x' is declared twice in this production");
  EXPECT_EQ(parse_error("axiom: @X\n"), "line 1, column 9: expected O (sphere), C (cone), L (leaf) or B (box) after '@'");
  EXPECT_EQ(parse_error("depth: 2.5\naxiom: A\n"), "line 1, column 8: depth must be a whole number in [0, 1e9], got 2.5");
  EXPECT_EQ(parse_error("#define K 1/0\naxiom: A\n"), "line 1, column 11: constant 'K': division by zero");
  EXPECT_EQ(parse_error("axiom: A\n[ -> A\n"), "line 2, column 1: brackets cannot be rewritten or used as a context");
}

TEST(LSystemParse, ParameterCountsMustAgree) {
  EXPECT_EQ(parse_error("axiom: A(1)\nA(l, w) -> A(l, w)\n"),
            "line 1, column 8: module 'A' has 1 parameter here but 2 in the predecessor on line 2");
  EXPECT_EQ(parse_error("axiom: A(1)\nA(x) -> B A\n"),
            "line 2, column 11: module 'A' has 0 parameters here but 1 in the predecessor on line 2");
  EXPECT_EQ(parse_error("axiom: F(1, 2)\n"), "line 1, column 8: module 'F' takes at most 1 parameter, found 2");
  EXPECT_EQ(parse_error("axiom: [(1)\n"), "line 1, column 8: module '[' takes at most 0 parameters, found 1");
}

TEST(LSystemParse, CommentsSettingsAndWhitespace) {
  const LSystem sys = parse(
      "# a comment\r\n"
      "// another\n"
      "#define LEN 2 # trailing comment\n"
      "const W = LEN / 4\n"
      "angle: 22.5   // degrees\n"
      "step: LEN\n"
      "width: W\n"
      "depth: 3\n"
      "axiom: F ( LEN ) \t A\n"
      "\n"
      "A -> F A\n");
  EXPECT_EQ(sys.angle, 22.5);
  EXPECT_EQ(sys.step, 2.0);
  EXPECT_EQ(sys.width, 0.5);
  EXPECT_EQ(sys.depth, 3);
  ASSERT_EQ(sys.axiom.size(), 2u);
  EXPECT_EQ(to_string(sys, derive(sys)), "F(2)FFFA");
}

TEST(LSystemParse, ExpressionNestingIsBounded) {
  std::string deep = "axiom: A(";
  for (int i = 0; i < 1000; ++i) deep += "(";
  EXPECT_NE(parse_error(deep + "1)\n").find("nested too deeply"), std::string::npos);
  std::string chain = "axiom: A(1";
  for (int i = 0; i < 1000; ++i) chain += "+1";
  EXPECT_NE(parse_error(chain + ")\n").find("nested too deeply"), std::string::npos);
}

}  // namespace
