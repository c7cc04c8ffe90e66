// L-system derivation against known strings: [Thesis]'s b -> a, a -> ab
// system (Fibonacci lengths), Lindenmayer's algae, the Koch curve, textbook
// bracketed and parametric systems, stochastic frequencies, context, limits.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

#include "lsystem/language/lsystem.h"
#include "util/error.h"

namespace {

using namespace plm::lsystem;

std::string derived(const std::string& text, int depth, uint64_t seed = 0) {
  const LSystem sys = parse(text);
  DeriveOptions opt;
  opt.depth = depth;
  opt.seed = seed;
  return to_string(sys, derive(sys, opt));
}

// The error message of f(), or "" if it did not throw plm::Error.
template <typename F>
std::string error_of(F f) {
  try {
    f();
  } catch (const plm::Error& e) {
    return e.what();
  }
  return "";
}

TEST(LSystemDerive, ThesisFibonacciExample) {
  // Axiom b, productions b -> a, a -> ab: b, a, ab, aba, abaab, abaababa, ...
  const char* text = "axiom: b\nb -> a\na -> ab\n";
  const char* expected[] = {"b", "a", "ab", "aba", "abaab", "abaababa", "abaababaabaab"};
  for (int n = 0; n < 7; ++n) EXPECT_EQ(derived(text, n), expected[n]) << "depth " << n;
  const LSystem sys = parse(text);
  uint64_t f0 = 1, f1 = 1;  // lengths are Fibonacci numbers 1 1 2 3 5 8 ...
  for (int n = 1; n <= 30; ++n) {
    DeriveOptions opt;
    opt.depth = n;
    EXPECT_EQ(derive(sys, opt).modules.size(), f1) << "depth " << n;
    const uint64_t f2 = f0 + f1;
    f0 = f1;
    f1 = f2;
  }
}

TEST(LSystemDerive, LindenmayerAlgae) {
  const char* text = "axiom: A\nA -> AB\nB -> A\n";
  EXPECT_EQ(derived(text, 0), "A");
  EXPECT_EQ(derived(text, 1), "AB");
  EXPECT_EQ(derived(text, 2), "ABA");
  EXPECT_EQ(derived(text, 3), "ABAAB");
  EXPECT_EQ(derived(text, 4), "ABAABABA");
  EXPECT_EQ(derived(text, 5), "ABAABABAABAAB");
}

TEST(LSystemDerive, KochCurve) {
  const char* text = "angle: 90\naxiom: F\nF -> F+F-F-F+F\n";
  EXPECT_EQ(derived(text, 1), "F+F-F-F+F");
  EXPECT_EQ(derived(text, 2),
            "F+F-F-F+F+F+F-F-F+F-F+F-F-F+F-F+F-F-F+F+F+F-F-F+F");
  // 5^n segments.
  const LSystem sys = parse(text);
  DeriveOptions opt;
  opt.depth = 5;
  const ModuleString s = derive(sys, opt);
  size_t forward = 0;
  for (const Module& m : s.modules) forward += sys.symbols[m.symbol].name == "F";
  EXPECT_EQ(forward, 3125u);
}

TEST(LSystemDerive, BracketedTextbookPlant) {
  // ABOP fig. 1.24a: F -> F[+F]F[-F]F.
  const char* text = "angle: 25.7\naxiom: F\nF -> F[+F]F[-F]F\n";
  EXPECT_EQ(derived(text, 1), "F[+F]F[-F]F");
  EXPECT_EQ(derived(text, 2),
            "F[+F]F[-F]F[+F[+F]F[-F]F]F[+F]F[-F]F[-F[+F]F[-F]F]F[+F]F[-F]F");
  // ABOP fig. 1.24d: X -> F[+X]F[-X]+X, F -> FF.
  EXPECT_EQ(derived("axiom: X\nX -> F[+X]F[-X]+X\nF -> FF\n", 2),
            "FF[+F[+X]F[-X]+X]FF[-F[+X]F[-X]+X]+F[+X]F[-X]+X");
}

TEST(LSystemDerive, ParametricCounter) {
  const char* text = "axiom: A(0)\nA(x) : x < 3 -> A(x+1) B\n";
  EXPECT_EQ(derived(text, 1), "A(1)B");
  EXPECT_EQ(derived(text, 2), "A(2)BB");
  EXPECT_EQ(derived(text, 3), "A(3)BBB");
  EXPECT_EQ(derived(text, 10), "A(3)BBB");  // the condition stops it
}

TEST(LSystemDerive, ConditionsAndSeveralProductions) {
  const char* text =
      "#define K 2\n"
      "const HALF = 1 / K\n"
      "axiom: A(4) A(1) A(-2)\n"
      "A(x) : x > 2 -> B(x * HALF)\n"
      "A(x) : x > 0 && x <= 2 -> C(x ^ 2, -x)\n"
      "A(x) : !(x > 0) -> D(abs(x), min(x, 7), max(x, 7), floor(2.5), sqrt(16))\n";
  EXPECT_EQ(derived(text, 1), "B(2)C(1,-1)D(2,-2,7,2,4)");
  // ABOP eq. 1.7-style parametric system (p. 43), two steps.
  const char* abop =
      "axiom: B(2) A(4, 4)\n"
      "A(x, y) : y <= 3 -> A(x * 2, x + y)\n"
      "A(x, y) : y > 3 -> B(x) A(x / y, 0)\n"
      "B(x) : x < 1 -> C\n"
      "B(x) : x >= 1 -> B(x - 1)\n";
  EXPECT_EQ(derived(abop, 1), "B(1)B(4)A(1,0)");
  EXPECT_EQ(derived(abop, 2), "B(0)B(3)A(2,1)");
  EXPECT_EQ(derived(abop, 3), "CB(2)A(4,3)");
  EXPECT_EQ(derived(abop, 4), "CB(1)A(8,7)");
}

TEST(LSystemDerive, OperatorsAndPrecedence) {
  EXPECT_EQ(derived("axiom: A(-2^2, 2^3^2, 1+2*3, (1+2)*3, 7-2-1, 8/2/2, 1<2, 2<=1, 3==3, 1!=1, 1||0, 1&&0)\n", 0),
            "A(-4,512,7,9,4,2,1,0,1,0,1,0)");
  EXPECT_EQ(derived("axiom: A(cos(0), sin(0), atan2(0, 1), pow(2, 10), ceil(0.2), exp(0), log(1))\n", 0),
            "A(1,0,0,1024,1,1,0)");
}

TEST(LSystemDerive, ContextSensitive) {
  // ABOP eq. 1.8 style signal propagation: b a a a a -> a b a a a -> ...
  const char* text = "axiom: baaaaaaaa\nb < a -> b\nb -> a\n";
  EXPECT_EQ(derived(text, 1), "abaaaaaaa");
  EXPECT_EQ(derived(text, 2), "aabaaaaaa");
  EXPECT_EQ(derived(text, 4), "aaaabaaaa");
  // Right context, and brackets skipped: B's right context is C across [D].
  EXPECT_EQ(derived("axiom: AB[D]C\nB > C -> X\n", 1), "AX[D]C");
  // A left context steps out of a branch: in A[B], B's left context is A.
  EXPECT_EQ(derived("axiom: A[B]C\nA < B -> Y\nA < C -> Z\n", 1), "A[Y]Z");
  // Ignored symbols are skipped; parameters of contexts are bound.
  EXPECT_EQ(derived("ignore: + -\naxiom: A(2)+-B(3)\nA(x) < B(y) -> B(x*y)\n", 1), "A(2)+-B(6)");
  // ']' ends the branch for a right context.
  EXPECT_EQ(derived("axiom: [B]C\nB > C -> X\n", 1), "[B]C");
}

TEST(LSystemDerive, MultiLetterModules) {
  EXPECT_EQ(derived("modules: Apex, Leaf\naxiom: Apex\nApex -> F Leaf Apex\n", 2), "FLeafFLeafApex");
}

TEST(LSystemDerive, StochasticIsDeterministicPerSeed) {
  const char* text = "axiom: A\nA -> (0.5) AB\nA -> (0.5) AC\n";
  EXPECT_EQ(derived(text, 20, 7), derived(text, 20, 7));
  EXPECT_NE(derived(text, 20, 7), derived(text, 20, 8));
  const char* rand_text = "axiom: A(0)\nA(x) -> A(rand()) B(rand(2, 3))\n";
  EXPECT_EQ(derived(rand_text, 3, 1), derived(rand_text, 3, 1));
  EXPECT_NE(derived(rand_text, 3, 1), derived(rand_text, 3, 2));
}

TEST(LSystemDerive, StochasticFrequenciesMatchProbabilities) {
  // One step over an axiom of N A's: each is rewritten independently.
  const int n = 20000;
  std::string axiom;
  for (int i = 0; i < n; ++i) axiom += 'A';
  const LSystem sys = parse("axiom: " + axiom + "\nA -> (0.2) X\nA -> (0.5) Y\nA -> (0.3) Z\n");
  const double p[3] = {0.2, 0.5, 0.3};
  for (uint64_t seed = 0; seed < 5; ++seed) {
    DeriveOptions opt;
    opt.depth = 1;
    opt.seed = seed;
    const std::string s = to_string(sys, derive(sys, opt));
    const double counts[3] = {double(std::count(s.begin(), s.end(), 'X')), double(std::count(s.begin(), s.end(), 'Y')),
                              double(std::count(s.begin(), s.end(), 'Z'))};
    for (int k = 0; k < 3; ++k) {
      const double sigma = std::sqrt(n * p[k] * (1 - p[k]));
      EXPECT_LT(std::fabs(counts[k] - n * p[k]), 4 * sigma) << "seed " << seed << " choice " << k;
    }
  }
  // rand() in a condition: P(x < 0.25) = 0.25.
  const LSystem cond = parse("axiom: " + axiom + "\nA : rand() < 0.25 -> X\n");
  DeriveOptions opt;
  opt.depth = 1;
  const std::string s = to_string(cond, derive(cond, opt));
  const double x = double(std::count(s.begin(), s.end(), 'X'));
  EXPECT_LT(std::fabs(x - n * 0.25), 4 * std::sqrt(n * 0.25 * 0.75));
}

TEST(LSystemDerive, DeterministicProductionWinsOverStochastic) {
  const char* text = "axiom: A(5) A(1)\nA(x) -> (1) S\nA(x) : x > 3 -> D\n";
  EXPECT_EQ(derived(text, 1), "DS");
}

TEST(LSystemDerive, RunawayGrowthFailsFast) {
  const LSystem sys = parse("axiom: A\nA -> AA\n");
  DeriveOptions opt;
  opt.depth = 60;
  opt.max_modules = 1'000'000;
  const std::string msg = error_of([&] { derive(sys, opt); });
  EXPECT_NE(msg.find("step 20:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("1000000"), std::string::npos) << msg;
  EXPECT_NE(msg.find("from 524288"), std::string::npos) << msg;
  // Parameter memory limit.
  const LSystem par = parse("axiom: A(1)\nA(x) -> A(x) A(x)\n");
  opt.max_params = 1000;
  const std::string pmsg = error_of([&] { derive(par, opt); });
  EXPECT_NE(pmsg.find("step 10:"), std::string::npos) << pmsg;
  EXPECT_NE(pmsg.find("parameters"), std::string::npos) << pmsg;
  // Depth limit.
  opt.depth = 2'000'000;
  EXPECT_NE(error_of([&] { derive(sys, opt); }).find("over the limit"), std::string::npos);
}

TEST(LSystemDerive, EdgeCases) {
  EXPECT_EQ(derived("axiom:\nA -> AA\n", 10), "");
  EXPECT_EQ(derived("axiom: A\nA ->\n", 3), "");
  // Deep brackets.
  const std::string deep = derived("axiom: A\nA -> [A]\n", 5000);
  EXPECT_EQ(deep.size(), 2 * 5000u + 1);
  // Huge but finite numbers pass; overflow does not.
  EXPECT_EQ(derived("axiom: A(1e308)\n", 0), "A(1e+308)");
  const std::string over = error_of([] { derived("axiom: A(1e308)\nA(x) -> A(x*10)\n", 1); });
  EXPECT_NE(over.find("line 2: production 'A(x) -> A(x*10)'"), std::string::npos) << over;
  EXPECT_NE(over.find("infinity"), std::string::npos) << over;
}

TEST(LSystemDerive, NaNAndDivisionByZeroNameTheProduction) {
  const std::string msg = error_of([] { derived("axiom: A(0)\n\nA(x) -> B(x / x)\n", 1); });
  EXPECT_EQ(msg,
            "step 1: line 3: production 'A(x) -> B(x / x)': division by zero (0/0) in parameter 1 of module 'B' "
            "(successor module 1)");
  const std::string cond = error_of([] { derived("axiom: A(-1)\nA(x) : sqrt(x) > 1 -> B\n", 1); });
  EXPECT_NE(cond.find("line 2: production 'A(x) : sqrt(x) > 1 -> B': sqrt gave NaN in the condition"),
            std::string::npos)
      << cond;
  const std::string ax = error_of([] { derived("axiom: A(1/0)\n", 0); });
  EXPECT_NE(ax.find("line 1: axiom: division by zero"), std::string::npos) << ax;
}

}  // namespace
