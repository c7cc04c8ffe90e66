#include "lsystem/language/expr.h"

#include <cmath>

namespace plm::lsystem {
namespace {

const char* kind_name(ExprNode::Kind k) {
  switch (k) {
    case ExprNode::Sin: return "sin";
    case ExprNode::Cos: return "cos";
    case ExprNode::Tan: return "tan";
    case ExprNode::Asin: return "asin";
    case ExprNode::Acos: return "acos";
    case ExprNode::Atan: return "atan";
    case ExprNode::Atan2: return "atan2";
    case ExprNode::Sqrt: return "sqrt";
    case ExprNode::Exp: return "exp";
    case ExprNode::Log: return "log";
    case ExprNode::PowFn: return "pow";
    case ExprNode::Pow: return "'^'";
    case ExprNode::Mul: return "'*'";
    case ExprNode::Add: return "'+'";
    case ExprNode::Sub: return "'-'";
    case ExprNode::Div: return "'/'";
    default: return "an operation";
  }
}

struct Evaluator {
  const std::vector<ExprNode>& nodes;
  const double* vars;
  RandomStream* rng;

  double checked(double v, ExprNode::Kind k) const {
    if (std::isnan(v)) throw EvalError{std::string(kind_name(k)) + " gave NaN"};
    if (std::isinf(v)) throw EvalError{std::string(kind_name(k)) + " overflowed to infinity"};
    return v;
  }

  double eval(int32_t i) const {
    const ExprNode& n = nodes[size_t(i)];
    switch (n.kind) {
      case ExprNode::Const: return n.value;
      case ExprNode::Var: return vars[n.a];
      case ExprNode::Neg: return -eval(n.a);
      case ExprNode::Not: return eval(n.a) == 0 ? 1.0 : 0.0;
      case ExprNode::And: return (eval(n.a) != 0 && eval(n.b) != 0) ? 1.0 : 0.0;
      case ExprNode::Or: return (eval(n.a) != 0 || eval(n.b) != 0) ? 1.0 : 0.0;
      case ExprNode::Rand:
        if (!rng) throw EvalError{"rand() is not allowed in a constant or setting"};
        return rng->uniform();
      case ExprNode::RandRange: {
        if (!rng) throw EvalError{"rand() is not allowed in a constant or setting"};
        const double lo = eval(n.a), hi = eval(n.b);
        return checked(lo + (hi - lo) * rng->uniform(), ExprNode::Add);
      }
      default: break;
    }
    const double x = eval(n.a);
    switch (n.kind) {
      case ExprNode::Sin: return checked(std::sin(x), n.kind);
      case ExprNode::Cos: return checked(std::cos(x), n.kind);
      case ExprNode::Tan: return checked(std::tan(x), n.kind);
      case ExprNode::Asin: return checked(std::asin(x), n.kind);
      case ExprNode::Acos: return checked(std::acos(x), n.kind);
      case ExprNode::Atan: return checked(std::atan(x), n.kind);
      case ExprNode::Sqrt: return checked(std::sqrt(x), n.kind);
      case ExprNode::Abs: return std::fabs(x);
      case ExprNode::Floor: return std::floor(x);
      case ExprNode::Ceil: return std::ceil(x);
      case ExprNode::Exp: return checked(std::exp(x), n.kind);
      case ExprNode::Log:
        if (x == 0) throw EvalError{"log(0) is -infinity"};
        return checked(std::log(x), n.kind);
      default: break;
    }
    const double y = eval(n.b);
    switch (n.kind) {
      case ExprNode::Add: return checked(x + y, n.kind);
      case ExprNode::Sub: return checked(x - y, n.kind);
      case ExprNode::Mul: return checked(x * y, n.kind);
      case ExprNode::Div:
        if (y == 0) throw EvalError{x == 0 ? "division by zero (0/0)" : "division by zero"};
        return checked(x / y, n.kind);
      case ExprNode::Pow:
      case ExprNode::PowFn:
        if (x == 0 && y < 0) throw EvalError{"division by zero (0 to a negative power)"};
        return checked(std::pow(x, y), n.kind);
      case ExprNode::Atan2: return checked(std::atan2(x, y), n.kind);
      case ExprNode::Min: return std::fmin(x, y);
      case ExprNode::Max: return std::fmax(x, y);
      case ExprNode::Lt: return x < y ? 1.0 : 0.0;
      case ExprNode::Le: return x <= y ? 1.0 : 0.0;
      case ExprNode::Gt: return x > y ? 1.0 : 0.0;
      case ExprNode::Ge: return x >= y ? 1.0 : 0.0;
      case ExprNode::Eq: return x == y ? 1.0 : 0.0;
      case ExprNode::Ne: return x != y ? 1.0 : 0.0;
      default: break;
    }
    throw EvalError{"internal error: unknown expression node"};
  }
};

}  // namespace

double evaluate(const std::vector<ExprNode>& nodes, int32_t root, const double* vars, RandomStream* rng) {
  return Evaluator{nodes, vars, rng}.eval(root);
}

}  // namespace plm::lsystem
