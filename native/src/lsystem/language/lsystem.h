// Parametric, stochastic, context-sensitive L-systems ([Thesis §4.2.2]): a text
// language, its parser and parallel derivation. The turtle that turns a
// derived string into primitives is in lsystem/language/turtle.h.
//
// The language, one statement per line; `#` (except `#define`) and `//`
// start a comment that runs to the end of the line:
//
//   system     := { statement? comment? '\n' }
//   statement  := 'axiom' ':' modules
//               | 'depth' ':' integer               derivation steps (default 0; the caller may override)
//               | 'angle' ':' expr                  default turn angle in degrees (default 90)
//               | 'step'  ':' expr                  default F/f length (default 1)
//               | 'width' ':' expr                  initial width, a diameter (default 0.1)
//               | 'ignore'  ':' name { name }       symbols skipped when matching contexts
//               | 'modules' ':' word { ','? word }  declares multi-letter module names
//               | '#define' IDENT expr | 'const' IDENT '=' expr
//               | production
//   production := [ pattern { pattern } '<' ] pattern [ '>' pattern { pattern } ]
//                 [ ':' expr ] '->' [ '(' expr ')' ] modules
//   pattern    := name [ '(' IDENT { ',' IDENT } ')' ]        formal parameters
//   modules    := { module }                                  may be empty
//   module     := name [ '(' expr { ',' expr } ')' ]
//   name       := a letter | a declared word | '@O' | '@C' | '@L' | '@B'
//               | one of  F f + - & ^ \ / | [ ] ! '
//   expr       := or ;  or := and { '||' and } ;  and := cmp { '&&' cmp }
//   cmp        := sum [ ('<' | '<=' | '>' | '>=' | '==' | '!=') sum ]
//   sum        := product { ('+' | '-') product } ;  product := unary { ('*' | '/') unary }
//   unary      := ('-' | '+' | '!') unary | power ;  power := primary [ '^' unary ]
//   primary    := NUMBER | IDENT | IDENT '(' [ expr { ',' expr } ] ')' | '(' expr ')'
//
// A letter is one module: `FF+A` is four modules. A declared word (`modules:
// Apex Leaf`) is matched before single letters, longest first. IDENT in an
// expression is a formal parameter of the production (predecessor and context
// patterns) or a constant; anything else is an error. Functions: sin cos tan
// asin acos atan atan2 sqrt abs min max floor ceil exp log pow (radians), and
// rand() in [0,1) or rand(a, b) in [a,b), deterministic for a derivation seed.
// Truth values are 0 / not 0; comparisons give 1 or 0; `^` is a power and
// binds tighter than unary minus (-2^2 = -4). Division by zero, and any
// operation whose result is NaN or infinite, stops the derivation with an
// error naming the line and production.
//
// Productions are matched on symbol, parameter count, context and condition.
// Context matching follows Prusinkiewicz & Lindenmayer: a left context skips
// complete branches `[...]` and steps out of the current branch, a right
// context skips branches and stops at the end of its branch; symbols listed by
// `ignore:` are skipped. Among the matching productions of a module the first
// one without a probability (in file order) is applied; if every match has a
// probability `-> (p)`, one is drawn with probability p / (sum of p over the
// matches). A module that no production matches is copied unchanged.
//
// Every use of a symbol that is a predecessor must have the predecessor's
// parameter count, and turtle symbols take at most their documented number of
// parameters (lsystem/language/turtle.h). Parse errors read
// "line 3, column 14: expected ')' after parameters of module 'A'".
//
// Example (a parametric branching plant):
//   #define R 0.7
//   angle: 30
//   depth: 6
//   axiom: !(0.2) A(1, 0.2)
//   A(l, w) : l > 0.1 -> !(w) F(l) [+ A(l*R, w*R)] [- A(l*R, w*R)]
//   A(l, w) : l <= 0.1 -> @L(0.2)
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace plm::lsystem {

// Built-in meaning of a symbol for the turtle; Other for user symbols.
enum class TurtleOp : uint8_t {
  Other, Forward, Move, Left, Right, PitchDown, PitchUp, RollLeft, RollRight, TurnAround,
  Push, Pop, Width, Material, Sphere, Cone, Leaf, Box
};

// One node of an expression tree (all nodes of a system live in one pool).
struct ExprNode {
  enum Kind : uint8_t {
    Const, Var, Neg, Not, Add, Sub, Mul, Div, Pow, Lt, Le, Gt, Ge, Eq, Ne, And, Or,
    Sin, Cos, Tan, Asin, Acos, Atan, Atan2, Sqrt, Abs, Min, Max, Floor, Ceil, Exp, Log, PowFn,
    Rand, RandRange
  };
  Kind kind = Const;
  double value = 0;    // Const
  int32_t a = -1, b = -1;  // child node indices; Var: a = formal parameter slot
};

// A module of a successor or of the axiom: a symbol and one expression per parameter.
struct ModuleTemplate {
  uint32_t symbol = 0;
  std::vector<int32_t> args;  // expression roots
};

// A module of a predecessor or context pattern: a symbol and formal parameter slots.
struct Pattern {
  uint32_t symbol = 0;
  std::vector<int32_t> slots;
};

struct Production {
  std::vector<Pattern> left;   // left context, in string order
  Pattern pred;
  std::vector<Pattern> right;  // right context
  int32_t condition = -1;      // expression root, -1: always
  int32_t probability = -1;    // expression root, -1: deterministic
  std::vector<ModuleTemplate> successor;
  int num_slots = 0;           // formal parameters over contexts and predecessor
  int line = 0;
  std::string text;            // the source line, for error messages
};

struct Symbol {
  std::string name;
  TurtleOp op = TurtleOp::Other;
  bool ignored = false;        // skipped in context matching
};

struct LSystem {
  std::vector<Symbol> symbols;
  std::vector<ExprNode> nodes;
  std::vector<Production> productions;
  std::vector<std::vector<int32_t>> productions_of;  // per symbol, indices into productions
  std::vector<ModuleTemplate> axiom;
  int axiom_line = 0;
  int depth = 0;
  double angle = 90.0;  // degrees
  double step = 1.0;
  double width = 0.1;
};

// Throws plm::Error (PLM_ERROR_INVALID_ARGUMENT) with "line L, column C: ...".
LSystem parse(std::string_view text);

// A derived string: modules with their parameters in one flat array.
struct Module {
  uint32_t symbol;
  uint32_t num_params;
  uint64_t first_param;  // index into ModuleString::params
};

struct ModuleString {
  std::vector<Module> modules;
  std::vector<double> params;
  int steps = 0;  // derivation steps done
};

struct DeriveOptions {
  int depth = -1;                       // < 0: the system's `depth:`
  uint64_t seed = 0;                    // stochastic choices and rand()
  uint64_t max_modules = 10'000'000;    // the string may not grow beyond this
  uint64_t max_params = 32'000'000;     // total parameters (8 bytes each)
  int max_depth = 100'000;              // upper bound on depth (ours or the system's)
};

// Parallel rewriting for depth steps. Before each step's allocation the new
// size is computed and checked against the limits; exceeding one throws
// plm::Error naming the step and the size reached. Evaluation errors (division
// by zero, NaN, Inf) throw plm::Error naming the production's line and text.
ModuleString derive(const LSystem& system, const DeriveOptions& options = {});

// "A(1,2.5)F[+F]": modules in order, parameters in shortest round-trip form.
std::string to_string(const LSystem& system, const ModuleString& string);

// Number of parameters a turtle symbol accepts at most (-1 for Other: any count).
int max_turtle_params(TurtleOp op);

}  // namespace plm::lsystem
