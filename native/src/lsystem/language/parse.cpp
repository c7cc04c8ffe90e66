// Parser of the L-system language described in lsystem/language/lsystem.h.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <string>

#include "lsystem/language/expr.h"
#include "lsystem/language/lsystem.h"
#include "util/error.h"

namespace plm::lsystem {
namespace {

constexpr int kMaxExprDepth = 200;  // evaluation recursion is bounded by this
constexpr int kMaxNesting = 100;    // parser recursion (parentheses, unary operators)

struct FunctionInfo {
  const char* name;
  ExprNode::Kind kind;
  int args;
};
constexpr FunctionInfo kFunctions[] = {
    {"sin", ExprNode::Sin, 1},     {"cos", ExprNode::Cos, 1},     {"tan", ExprNode::Tan, 1},
    {"asin", ExprNode::Asin, 1},   {"acos", ExprNode::Acos, 1},   {"atan", ExprNode::Atan, 1},
    {"atan2", ExprNode::Atan2, 2}, {"sqrt", ExprNode::Sqrt, 1},   {"abs", ExprNode::Abs, 1},
    {"min", ExprNode::Min, 2},     {"max", ExprNode::Max, 2},     {"floor", ExprNode::Floor, 1},
    {"ceil", ExprNode::Ceil, 1},   {"exp", ExprNode::Exp, 1},     {"log", ExprNode::Log, 1},
    {"pow", ExprNode::PowFn, 2},   {"rand", ExprNode::Rand, 0}};

TurtleOp op_of_name(const std::string& name) {
  static const std::map<std::string, TurtleOp> ops = {
      {"F", TurtleOp::Forward},    {"f", TurtleOp::Move},       {"+", TurtleOp::Left},
      {"-", TurtleOp::Right},      {"&", TurtleOp::PitchDown},  {"^", TurtleOp::PitchUp},
      {"\\", TurtleOp::RollLeft},  {"/", TurtleOp::RollRight},  {"|", TurtleOp::TurnAround},
      {"[", TurtleOp::Push},       {"]", TurtleOp::Pop},        {"!", TurtleOp::Width},
      {"'", TurtleOp::Material},   {"@O", TurtleOp::Sphere},    {"@C", TurtleOp::Cone},
      {"@L", TurtleOp::Leaf},      {"@B", TurtleOp::Box}};
  const auto it = ops.find(name);
  return it == ops.end() ? TurtleOp::Other : it->second;
}

bool is_ident_start(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_'; }
bool is_ident_char(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

class Parser {
 public:
  explicit Parser(std::string_view text) : text_(text) {}

  LSystem run() {
    size_t start = 0;
    while (start <= text_.size()) {
      size_t end = text_.find('\n', start);
      if (end == std::string_view::npos) end = text_.size();
      line_ = text_.substr(start, end - start);
      if (!line_.empty() && line_.back() == '\r') line_.remove_suffix(1);
      ++line_no_;
      pos_ = 0;
      statement();
      start = end + 1;
    }
    finish();
    return std::move(sys_);
  }

 private:
  struct Use {
    uint32_t symbol, count;
    int line, column;
    bool predecessor;
  };

  std::string_view text_, line_;
  size_t pos_ = 0;
  int line_no_ = 0;
  LSystem sys_;
  std::map<std::string, uint32_t> symbol_ids_;
  std::map<std::string, double> constants_;
  std::vector<std::string> words_;  // declared multi-letter names, longest first
  std::vector<std::string> formals_;
  std::vector<int> node_depth_;
  std::vector<Use> uses_;
  int nesting_ = 0;
  bool have_axiom_ = false, have_depth_ = false;

  template <typename... Args>
  [[noreturn]] void error_at(size_t column0, const Args&... args) const {
    fail(PLM_ERROR_INVALID_ARGUMENT, "line ", line_no_, ", column ", column0 + 1, ": ", args...);
  }
  template <typename... Args>
  [[noreturn]] void error(const Args&... args) const {
    error_at(pos_, args...);
  }

  char peek(size_t k = 0) const { return pos_ + k < line_.size() ? line_[pos_ + k] : '\0'; }
  bool at_end() const { return pos_ >= line_.size(); }
  void skip_ws() {
    while (!at_end() && (line_[pos_] == ' ' || line_[pos_] == '\t')) ++pos_;
  }
  bool accept(std::string_view token) {
    skip_ws();
    if (line_.substr(pos_, token.size()) == token) {
      pos_ += token.size();
      return true;
    }
    return false;
  }
  std::string describe_here() const {
    if (at_end()) return "the end of the line";
    const unsigned char c = static_cast<unsigned char>(line_[pos_]);
    if (std::isprint(c)) return std::string("'") + char(c) + "'";
    char buf[16];
    std::snprintf(buf, sizeof buf, "byte 0x%02x", unsigned(c));
    return buf;
  }
  std::string ident() {
    skip_ws();
    if (!is_ident_start(peek())) return {};
    const size_t b = pos_;
    while (is_ident_char(peek())) ++pos_;
    return std::string(line_.substr(b, pos_ - b));
  }

  void strip_comment() {
    size_t from = 0;
    while (from < line_.size() && (line_[from] == ' ' || line_[from] == '\t')) ++from;
    if (line_.substr(from, 7) == "#define") from += 7;
    for (size_t i = from; i < line_.size(); ++i) {
      if (line_[i] == '#' || (line_[i] == '/' && i + 1 < line_.size() && line_[i + 1] == '/')) {
        line_ = line_.substr(0, i);
        return;
      }
    }
  }

  void statement() {
    strip_comment();
    skip_ws();
    if (at_end()) return;
    if (line_.substr(pos_, 8) == "#define " || line_.substr(pos_, 8) == "#define\t") {
      pos_ += 7;
      define_constant(false);
      return;
    }
    const size_t save = pos_;
    const std::string word = ident();
    if (word == "const" && (peek() == ' ' || peek() == '\t')) {
      define_constant(true);
      return;
    }
    skip_ws();
    if (peek() == ':' && !word.empty()) {
      const size_t key_col = save;
      ++pos_;
      if (word == "axiom") return axiom(key_col);
      if (word == "depth") return depth(key_col);
      if (word == "angle") return setting(&sys_.angle, "angle");
      if (word == "step") return setting(&sys_.step, "step");
      if (word == "width") return setting(&sys_.width, "width");
      if (word == "ignore") return ignore();
      if (word == "modules") return declare_words();
    }
    pos_ = save;
    production();
  }

  void define_constant(bool with_equals) {
    const size_t col = (skip_ws(), pos_);
    const std::string name = ident();
    if (name.empty()) error("expected a constant name, found ", describe_here());
    if (with_equals && !accept("=")) error("expected '=' after the name of constant '", name, "'");
    if (constants_.count(name)) error_at(col, "constant '", name, "' is defined twice");
    for (const FunctionInfo& f : kFunctions)
      if (name == f.name) error_at(col, "'", name, "' is a function and cannot be a constant");
    formals_.clear();
    const double v = constant_expression("constant '" + name + "'");
    constants_[name] = v;
  }

  double constant_expression(const std::string& what) {
    skip_ws();
    const size_t col = pos_;
    const int32_t root = expression();
    end_of_line();
    try {
      return evaluate(sys_.nodes, root, nullptr, nullptr);
    } catch (const EvalError& e) {
      error_at(col, what, ": ", e.what);
    }
  }

  void end_of_line() {
    skip_ws();
    if (!at_end()) error("unexpected ", describe_here(), " after the end of the statement");
  }

  void setting(double* out, const char* name) {
    formals_.clear();
    skip_ws();
    const size_t col = pos_;
    const double v = constant_expression(name);
    if (!(v > 0) && !(std::string(name) == "angle")) error_at(col, name, " must be > 0, got ", v);
    *out = v;
  }

  void axiom(size_t col) {
    if (have_axiom_) error_at(col, "a second 'axiom:' line (the first is enough)");
    have_axiom_ = true;
    sys_.axiom_line = line_no_;
    formals_.clear();
    sys_.axiom = modules("axiom");
  }

  void depth(size_t col) {
    if (have_depth_) error_at(col, "a second 'depth:' line");
    have_depth_ = true;
    formals_.clear();
    skip_ws();
    const size_t vcol = pos_;
    const double v = constant_expression("depth");
    if (!(v >= 0 && v <= 1e9 && v == std::floor(v)))
      error_at(vcol, "depth must be a whole number in [0, 1e9], got ", v);
    sys_.depth = int(v);
  }

  void ignore() {
    for (;;) {
      skip_ws();
      if (at_end()) return;
      const size_t col = pos_;
      const std::string name = module_name();
      if (name.empty()) error("expected a module name in 'ignore:', found ", describe_here());
      if (name == "[" || name == "]") error_at(col, "brackets cannot be ignored in context matching");
      sys_.symbols[intern(name)].ignored = true;
    }
  }

  void declare_words() {
    for (;;) {
      skip_ws();
      if (at_end()) break;
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      const size_t col = pos_;
      const std::string w = ident();
      if (w.size() < 2) error_at(col, "expected a module name of two or more letters in 'modules:', found ",
                                 describe_here());
      if (std::find(words_.begin(), words_.end(), w) == words_.end()) words_.push_back(w);
    }
    std::stable_sort(words_.begin(), words_.end(),
                     [](const std::string& a, const std::string& b) { return a.size() > b.size(); });
  }

  uint32_t intern(const std::string& name) {
    const auto it = symbol_ids_.find(name);
    if (it != symbol_ids_.end()) return it->second;
    const uint32_t id = uint32_t(sys_.symbols.size());
    sys_.symbols.push_back(Symbol{name, op_of_name(name), false});
    sys_.productions_of.emplace_back();
    symbol_ids_[name] = id;
    return id;
  }

  // A module name at pos_ (consumed), or "" if there is none.
  std::string module_name() {
    skip_ws();
    const char c = peek();
    if (c == '@') {
      const char d = peek(1);
      if (d == 'O' || d == 'C' || d == 'L' || d == 'B') {
        pos_ += 2;
        return std::string("@") + d;
      }
      ++pos_;
      error("expected O (sphere), C (cone), L (leaf) or B (box) after '@'");
    }
    for (const std::string& w : words_) {
      if (line_.substr(pos_, w.size()) == w) {
        pos_ += w.size();
        return w;
      }
    }
    if (std::isalpha(static_cast<unsigned char>(c))) {
      ++pos_;
      return std::string(1, c);
    }
    if (c != '\0' && std::string_view("+-&^\\/|[]!'").find(c) != std::string_view::npos) {
      ++pos_;
      return std::string(1, c);
    }
    return {};
  }

  // A module with `count` parameters at column col: checked against its turtle
  // command's limit and recorded for the consistency checks of finish().
  void use_module(uint32_t symbol, size_t count, size_t col) {
    const int most = max_turtle_params(sys_.symbols[symbol].op);
    if (most >= 0 && count > size_t(most))
      error_at(col, "module '", sys_.symbols[symbol].name, "' takes at most ", most, " parameter",
               most == 1 ? "" : "s", ", found ", count);
    uses_.push_back(Use{symbol, uint32_t(count), line_no_, int(col), false});
  }

  // An optional parenthesised, comma-separated list after module `name`;
  // item() reads one entry.
  template <typename Item>
  void parameter_list(const std::string& name, Item&& item) {
    skip_ws();
    if (peek() != '(') return;
    ++pos_;
    for (;;) {
      item();
      skip_ws();
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      if (peek() == ')') {
        ++pos_;
        return;
      }
      error("expected ')' after parameters of module '", name, "'");
    }
  }

  std::vector<ModuleTemplate> modules(const char* where) {
    std::vector<ModuleTemplate> out;
    for (;;) {
      skip_ws();
      if (at_end()) return out;
      const size_t col = pos_;
      const std::string name = module_name();
      if (name.empty()) error("expected a module in the ", where, ", found ", describe_here());
      ModuleTemplate m;
      m.symbol = intern(name);
      parameter_list(name, [&] { m.args.push_back(expression()); });
      use_module(m.symbol, m.args.size(), col);
      out.push_back(std::move(m));
    }
  }

  Pattern pattern() {
    skip_ws();
    const size_t col = pos_;
    const std::string name = module_name();
    if (name.empty()) error("expected a predecessor module, found ", describe_here());
    Pattern p;
    p.symbol = intern(name);
    if (name == "[" || name == "]")
      error_at(col, "brackets cannot be rewritten or used as a context");
    parameter_list(name, [&] {
      skip_ws();
      const size_t pcol = pos_;
      const std::string f = ident();
      if (f.empty()) error("expected a parameter name in module '", name, "', found ", describe_here());
      if (std::find(formals_.begin(), formals_.end(), f) != formals_.end())
        error_at(pcol, "parameter '", f, "' is declared twice in this production");
      if (constants_.count(f)) error_at(pcol, "parameter '", f, "' hides the constant of that name");
      p.slots.push_back(int32_t(formals_.size()));
      formals_.push_back(f);
    });
    use_module(p.symbol, p.slots.size(), col);
    return p;
  }

  void production() {
    formals_.clear();
    Production prod;
    prod.line = line_no_;
    prod.text = std::string(line_);
    while (!prod.text.empty() && (prod.text.back() == ' ' || prod.text.back() == '\t')) prod.text.pop_back();
    const size_t first = prod.text.find_first_not_of(" \t");
    prod.text = prod.text.substr(first == std::string::npos ? 0 : first);

    // Up to three groups: left context '<' predecessor '>' right context.
    std::vector<Pattern> groups[3];
    std::vector<size_t> group_cols[3];
    int g = 0;
    bool saw_lt = false, saw_gt = false;
    size_t pred_use = 0;  // index in uses_ of the first pattern of the predecessor group
    size_t group_start_use[3] = {uses_.size(), 0, 0};
    for (;;) {
      skip_ws();
      if (at_end()) error("expected '->' after the predecessor");
      if (line_.substr(pos_, 2) == "->" || peek() == ':') break;
      if (peek() == '<') {
        if (saw_lt || saw_gt || groups[g].empty()) error("unexpected '<' (a left context comes before the predecessor)");
        saw_lt = true;
        ++pos_;
        ++g;
        group_start_use[g] = uses_.size();
        continue;
      }
      if (peek() == '>') {
        if (saw_gt || groups[g].empty()) error("unexpected '>' (a right context comes after the predecessor)");
        saw_gt = true;
        ++pos_;
        ++g;
        group_start_use[g] = uses_.size();
        continue;
      }
      group_cols[g].push_back((skip_ws(), pos_));
      groups[g].push_back(pattern());
    }
    const int pred_group = saw_lt ? 1 : 0;
    if (groups[pred_group].size() != 1) {
      if (groups[pred_group].empty()) error("expected a predecessor module before ", describe_here());
      error_at(group_cols[pred_group][1], "expected one predecessor module, found ", groups[pred_group].size(),
               " (use '<' and '>' to give a context)");
    }
    if (saw_gt && groups[pred_group + 1].empty()) error("expected a right context after '>'");
    pred_use = group_start_use[pred_group];
    uses_[pred_use].predecessor = true;
    if (saw_lt) prod.left = std::move(groups[0]);
    prod.pred = std::move(groups[pred_group][0]);
    if (saw_gt) prod.right = std::move(groups[pred_group + 1]);
    if (accept(":")) {
      skip_ws();
      if (line_.substr(pos_, 2) == "->") error("expected a condition after ':'");
      prod.condition = expression();
    }
    if (!accept("->")) error("expected '->' after the ", prod.condition >= 0 ? "condition" : "predecessor",
                             ", found ", describe_here());
    skip_ws();
    if (peek() == '(') {
      ++pos_;
      prod.probability = expression();
      if (!accept(")")) error("expected ')' after the probability");
    }
    prod.successor = modules("successor");
    prod.num_slots = int(formals_.size());
    const uint32_t sym = prod.pred.symbol;
    sys_.productions_of[sym].push_back(int32_t(sys_.productions.size()));
    sys_.productions.push_back(std::move(prod));
  }

  // ---- expressions ----

  int32_t add_node(ExprNode n) {
    int d = 1;
    if (n.kind != ExprNode::Var && n.kind != ExprNode::Const) {
      if (n.a >= 0) d = std::max(d, node_depth_[size_t(n.a)] + 1);
      if (n.b >= 0) d = std::max(d, node_depth_[size_t(n.b)] + 1);
    }
    if (d > kMaxExprDepth) error("expression is nested too deeply (more than ", kMaxExprDepth, " levels)");
    sys_.nodes.push_back(n);
    node_depth_.push_back(d);
    return int32_t(sys_.nodes.size() - 1);
  }
  int32_t binary(ExprNode::Kind k, int32_t a, int32_t b) {
    ExprNode n;
    n.kind = k;
    n.a = a;
    n.b = b;
    return add_node(n);
  }

  struct NestGuard {
    Parser& p;
    explicit NestGuard(Parser& parser) : p(parser) {
      if (++p.nesting_ > kMaxNesting) p.error("expression is nested too deeply (more than ", kMaxNesting, " levels)");
    }
    ~NestGuard() { --p.nesting_; }
  };

  int32_t expression() {
    NestGuard guard(*this);
    int32_t a = and_expr();
    while (accept("||")) a = binary(ExprNode::Or, a, and_expr());
    return a;
  }
  int32_t and_expr() {
    int32_t a = comparison();
    while (accept("&&")) a = binary(ExprNode::And, a, comparison());
    return a;
  }
  int32_t comparison() {
    const int32_t a = sum();
    skip_ws();
    static const std::pair<const char*, ExprNode::Kind> ops[] = {{"<=", ExprNode::Le}, {">=", ExprNode::Ge},
                                                                  {"==", ExprNode::Eq}, {"!=", ExprNode::Ne},
                                                                  {"<", ExprNode::Lt},  {">", ExprNode::Gt}};
    for (const auto& [tok, kind] : ops) {
      if (line_.substr(pos_, std::char_traits<char>::length(tok)) == tok) {
        pos_ += std::char_traits<char>::length(tok);
        return binary(kind, a, sum());
      }
    }
    return a;
  }
  // A left-associative chain operand (op operand)* of two operators; the
  // second is no operator when `not_before` follows it ("->", "//").
  int32_t chain(int32_t (Parser::*operand)(), char op1, ExprNode::Kind k1, char op2, char not_before,
                ExprNode::Kind k2) {
    int32_t a = (this->*operand)();
    for (;;) {
      skip_ws();
      if (peek() == op1) {
        ++pos_;
        a = binary(k1, a, (this->*operand)());
      } else if (peek() == op2 && peek(1) != not_before) {
        ++pos_;
        a = binary(k2, a, (this->*operand)());
      } else {
        return a;
      }
    }
  }
  int32_t sum() { return chain(&Parser::product, '+', ExprNode::Add, '-', '>', ExprNode::Sub); }
  int32_t product() { return chain(&Parser::unary, '*', ExprNode::Mul, '/', '/', ExprNode::Div); }
  int32_t unary() {
    NestGuard guard(*this);
    skip_ws();
    if (peek() == '-' && peek(1) != '>') {
      ++pos_;
      return binary(ExprNode::Neg, unary(), -1);
    }
    if (peek() == '+') {
      ++pos_;
      return unary();
    }
    if (peek() == '!' && peek(1) != '=') {
      ++pos_;
      return binary(ExprNode::Not, unary(), -1);
    }
    const int32_t base = primary();
    if (accept("^")) return binary(ExprNode::Pow, base, unary());
    return base;
  }
  int32_t primary() {
    skip_ws();
    const size_t col = pos_;
    const char c = peek();
    if (c == '(') {
      ++pos_;
      const int32_t e = expression();
      if (!accept(")")) error("expected ')' to close the '(' at column ", col + 1, ", found ", describe_here());
      return e;
    }
    if (std::isdigit(static_cast<unsigned char>(c)) || (c == '.' && std::isdigit(static_cast<unsigned char>(peek(1))))) {
      double v = 0;
      const char* b = line_.data() + pos_;
      const auto r = std::from_chars(b, line_.data() + line_.size(), v);
      if (r.ec == std::errc::result_out_of_range) {
        pos_ += size_t(r.ptr - b);
        error_at(col, "number '", std::string(b, r.ptr), "' is out of the range of a double");
      }
      if (r.ec != std::errc()) error("expected a number");
      pos_ += size_t(r.ptr - b);
      if (!std::isfinite(v)) error_at(col, "number is not finite");
      ExprNode n;
      n.kind = ExprNode::Const;
      n.value = v;
      return add_node(n);
    }
    if (is_ident_start(c)) {
      const std::string name = ident();
      skip_ws();
      if (peek() == '(') return call(name, col);
      const auto f = std::find(formals_.begin(), formals_.end(), name);
      ExprNode n;
      if (f != formals_.end()) {
        n.kind = ExprNode::Var;
        n.a = int32_t(f - formals_.begin());
        return add_node(n);
      }
      const auto k = constants_.find(name);
      if (k != constants_.end()) {
        n.kind = ExprNode::Const;
        n.value = k->second;
        return add_node(n);
      }
      error_at(col, "unknown identifier '", name, "' (not a parameter of this production or a constant)");
    }
    error("expected an expression, found ", describe_here());
  }
  int32_t call(const std::string& name, size_t col) {
    const FunctionInfo* fn = nullptr;
    for (const FunctionInfo& f : kFunctions)
      if (name == f.name) fn = &f;
    if (!fn) error_at(col, "unknown function '", name, "'");
    ++pos_;  // '('
    std::vector<int32_t> args;
    skip_ws();
    if (peek() != ')') {
      for (;;) {
        args.push_back(expression());
        if (accept(",")) continue;
        break;
      }
    }
    if (!accept(")")) error("expected ')' after the arguments of ", name, "()");
    if (fn->kind == ExprNode::Rand) {
      if (args.empty()) return binary(ExprNode::Rand, -1, -1);
      if (args.size() == 2) return binary(ExprNode::RandRange, args[0], args[1]);
      error_at(col, "rand takes 0 or 2 arguments, found ", args.size());
    }
    if (int(args.size()) != fn->args)
      error_at(col, name, " takes ", fn->args, " argument", fn->args == 1 ? "" : "s", ", found ", args.size());
    return binary(fn->kind, args[0], fn->args == 2 ? args[1] : -1);
  }

  // ---- whole-system checks ----

  void finish() {
    if (!have_axiom_) fail(PLM_ERROR_INVALID_ARGUMENT, "line ", line_no_, ", column 1: the system has no 'axiom:' line");
    // The first predecessor of a symbol fixes its parameter count.
    std::vector<const Use*> pred_of(sys_.symbols.size(), nullptr);
    for (const Use& u : uses_)
      if (u.predecessor && !pred_of[u.symbol]) pred_of[u.symbol] = &u;
    for (const Use& u : uses_) {
      const Use* p = pred_of[u.symbol];
      if (p && p->count != u.count)
        fail(PLM_ERROR_INVALID_ARGUMENT, "line ", u.line, ", column ", u.column + 1, ": module '",
             sys_.symbols[u.symbol].name, "' has ", u.count, " parameter", u.count == 1 ? "" : "s",
             " here but ", p->count, " in the predecessor on line ", p->line);
    }
  }
};

}  // namespace

int max_turtle_params(TurtleOp op) {
  switch (op) {
    case TurtleOp::Other: return -1;
    case TurtleOp::TurnAround:
    case TurtleOp::Push:
    case TurtleOp::Pop: return 0;
    case TurtleOp::Cone:
    case TurtleOp::Leaf: return 2;
    case TurtleOp::Box: return 3;
    default: return 1;
  }
}

LSystem parse(std::string_view text) { return Parser(text).run(); }

}  // namespace plm::lsystem
