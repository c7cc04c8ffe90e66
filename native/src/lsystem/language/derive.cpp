// Parallel rewriting of L-system strings (lsystem/language/lsystem.h).
#include <algorithm>
#include <charconv>
#include <new>

#include "lsystem/language/expr.h"
#include "lsystem/language/lsystem.h"
#include "util/error.h"

namespace plm::lsystem {
namespace {

struct Deriver {
  Deriver(const LSystem& system, const DeriveOptions& options) : sys(system), opt(options) {}

  const LSystem& sys;
  const DeriveOptions& opt;
  int step = 0;
  const ModuleString* cur = nullptr;
  std::vector<int64_t> partner;  // matching bracket of each '[' / ']', -1 if none
  std::vector<double> vars;
  std::vector<std::pair<int32_t, double>> lottery;

  [[noreturn]] void eval_failed(const Production& p, const EvalError& e, const std::string& where) const {
    fail(PLM_ERROR_INVALID_ARGUMENT, "step ", step, ": line ", p.line, ": production '", p.text, "': ", e.what,
         " in ", where);
  }

  bool bind(const Pattern& pat, const Module& m) {
    if (pat.symbol != m.symbol || pat.slots.size() != m.num_params) return false;
    for (size_t k = 0; k < pat.slots.size(); ++k) vars[size_t(pat.slots[k])] = cur->params[m.first_param + k];
    return true;
  }

  bool is_open(uint32_t s) const { return sys.symbols[s].op == TurtleOp::Push; }
  bool is_close(uint32_t s) const { return sys.symbols[s].op == TurtleOp::Pop; }

  bool match_left(const Production& p, int64_t i) {
    int64_t j = i - 1;
    const auto& ms = cur->modules;
    for (size_t k = p.left.size(); k-- > 0;) {
      for (;;) {
        if (j < 0) return false;
        const uint32_t s = ms[size_t(j)].symbol;
        if (is_close(s)) {
          j = partner[size_t(j)] < 0 ? -1 : partner[size_t(j)] - 1;  // skip a whole branch
        } else if (is_open(s) || sys.symbols[s].ignored) {
          --j;  // step out of the branch to its parent
        } else {
          break;
        }
      }
      if (!bind(p.left[k], ms[size_t(j)])) return false;
      --j;
    }
    return true;
  }

  bool match_right(const Production& p, int64_t i) {
    const int64_t n = int64_t(cur->modules.size());
    const auto& ms = cur->modules;
    int64_t j = i + 1;
    for (const Pattern& pat : p.right) {
      for (;;) {
        if (j >= n) return false;
        const uint32_t s = ms[size_t(j)].symbol;
        if (is_open(s)) {
          j = partner[size_t(j)] < 0 ? n : partner[size_t(j)] + 1;  // skip a side branch
        } else if (is_close(s)) {
          return false;  // the end of this branch
        } else if (sys.symbols[s].ignored) {
          ++j;
        } else {
          break;
        }
      }
      if (!bind(pat, ms[size_t(j)])) return false;
      ++j;
    }
    return true;
  }

  bool matches(const Production& p, int64_t i) {
    return bind(p.pred, cur->modules[size_t(i)]) && (p.left.empty() || match_left(p, i)) &&
           (p.right.empty() || match_right(p, i));
  }

  // The production applied to module i, or -1.
  int32_t choose(int64_t i) {
    const auto& list = sys.productions_of[cur->modules[size_t(i)].symbol];
    if (list.empty()) return -1;
    RandomStream rng{stream_key(opt.seed, uint64_t(step), uint64_t(i), 0)};
    lottery.clear();
    for (const int32_t pi : list) {
      const Production& p = sys.productions[size_t(pi)];
      if (!matches(p, i)) continue;
      if (p.condition >= 0) {
        double c;
        try {
          c = evaluate(sys.nodes, p.condition, vars.data(), &rng);
        } catch (const EvalError& e) {
          eval_failed(p, e, "the condition");
        }
        if (c == 0) continue;
      }
      if (p.probability < 0) return pi;
      double w;
      try {
        w = evaluate(sys.nodes, p.probability, vars.data(), &rng);
      } catch (const EvalError& e) {
        eval_failed(p, e, "the probability");
      }
      if (w < 0) fail(PLM_ERROR_INVALID_ARGUMENT, "step ", step, ": line ", p.line, ": production '", p.text,
                      "': the probability is negative (", w, ")");
      lottery.emplace_back(pi, w);
    }
    double total = 0;
    for (const auto& [pi, w] : lottery) total += w;
    if (!(total > 0)) return -1;
    double u = rng.uniform() * total;
    for (const auto& [pi, w] : lottery) {
      if (u < w) return pi;
      u -= w;
    }
    for (size_t k = lottery.size(); k-- > 0;)  // rounding: the last one with a weight
      if (lottery[k].second > 0) return lottery[k].first;
    return -1;
  }

  void find_partners() {
    const auto& ms = cur->modules;
    partner.assign(ms.size(), -1);
    std::vector<int64_t> open;
    for (size_t j = 0; j < ms.size(); ++j) {
      if (is_open(ms[j].symbol)) {
        open.push_back(int64_t(j));
      } else if (is_close(ms[j].symbol) && !open.empty()) {
        partner[j] = open.back();
        partner[size_t(open.back())] = int64_t(j);
        open.pop_back();
      }
    }
  }

  void check_size(uint64_t modules, uint64_t params, uint64_t before) const {
    if (modules > opt.max_modules)
      fail(PLM_ERROR_OUT_OF_MEMORY, "step ", step, ": the string grows to at least ", modules,
           " modules (from ", before, "), over the limit of ", opt.max_modules, " modules");
    if (params > opt.max_params)
      fail(PLM_ERROR_OUT_OF_MEMORY, "step ", step, ": the string's parameters grow to at least ", params,
           " values (", params * 8, " bytes), over the limit of ", opt.max_params, " parameters");
  }

  void append(ModuleString& out, const Production* p, const ModuleTemplate& t, size_t index, RandomStream* rng) {
    out.modules.push_back(Module{t.symbol, uint32_t(t.args.size()), out.params.size()});
    for (size_t k = 0; k < t.args.size(); ++k) {
      try {
        out.params.push_back(evaluate(sys.nodes, t.args[k], vars.data(), rng));
      } catch (const EvalError& e) {
        const std::string where = "parameter " + std::to_string(k + 1) + " of module '" +
                                  sys.symbols[t.symbol].name + "' (successor module " +
                                  std::to_string(index + 1) + ")";
        if (p) eval_failed(*p, e, where);
        fail(PLM_ERROR_INVALID_ARGUMENT, "line ", sys.axiom_line, ": axiom: ", e.what, " in parameter ", k + 1,
             " of module '", sys.symbols[t.symbol].name, "'");
      }
    }
  }

  ModuleString run() {
    const int depth = opt.depth >= 0 ? opt.depth : sys.depth;
    if (depth > opt.max_depth)
      fail(PLM_ERROR_INVALID_ARGUMENT, "derivation depth ", depth, " is over the limit of ", opt.max_depth);
    size_t slots = 0;
    bool context = false;
    for (const Production& p : sys.productions) {
      slots = std::max(slots, size_t(p.num_slots));
      context = context || !p.left.empty() || !p.right.empty();
    }
    vars.assign(slots + 1, 0.0);

    ModuleString s;
    uint64_t axiom_params = 0;
    for (const ModuleTemplate& t : sys.axiom) axiom_params += t.args.size();
    check_size(sys.axiom.size(), axiom_params, 0);
    for (size_t i = 0; i < sys.axiom.size(); ++i) {
      RandomStream rng{stream_key(opt.seed, 0, i, 2)};
      append(s, nullptr, sys.axiom[i], i, &rng);
    }

    for (step = 1; step <= depth && !s.modules.empty(); ++step) {
      cur = &s;
      if (context) find_partners();
      const size_t n = s.modules.size();
      std::vector<int32_t> choice(n);
      uint64_t modules = 0, params = 0;
      for (size_t i = 0; i < n; ++i) {
        choice[i] = choose(int64_t(i));
        if (choice[i] < 0) {
          modules += 1;
          params += s.modules[i].num_params;
        } else {
          for (const ModuleTemplate& t : sys.productions[size_t(choice[i])].successor) {
            modules += 1;
            params += t.args.size();
          }
        }
        check_size(modules, params, n);
      }
      ModuleString next;
      try {
        next.modules.reserve(modules);
        next.params.reserve(params);
      } catch (const std::bad_alloc&) {
        fail(PLM_ERROR_OUT_OF_MEMORY, "step ", step, ": out of memory for ", modules, " modules");
      }
      for (size_t i = 0; i < n; ++i) {
        const Module& m = s.modules[i];
        if (choice[i] < 0) {
          next.modules.push_back(Module{m.symbol, m.num_params, next.params.size()});
          for (uint32_t k = 0; k < m.num_params; ++k) next.params.push_back(s.params[m.first_param + k]);
          continue;
        }
        const Production& p = sys.productions[size_t(choice[i])];
        matches(p, int64_t(i));  // binds the parameters
        RandomStream rng{stream_key(opt.seed, uint64_t(step), i, 1)};
        for (size_t k = 0; k < p.successor.size(); ++k) append(next, &p, p.successor[k], k, &rng);
      }
      s = std::move(next);
    }
    s.steps = step - 1;
    return s;
  }
};

}  // namespace

ModuleString derive(const LSystem& system, const DeriveOptions& options) {
  return Deriver(system, options).run();
}

std::string to_string(const LSystem& system, const ModuleString& string) {
  std::string out;
  for (const Module& m : string.modules) {
    out += system.symbols[m.symbol].name;
    if (m.num_params == 0) continue;
    out += '(';
    for (uint32_t k = 0; k < m.num_params; ++k) {
      if (k) out += ',';
      char buf[32];
      const auto r = std::to_chars(buf, buf + sizeof buf, string.params[m.first_param + k]);
      out.append(buf, r.ptr);
    }
    out += ')';
  }
  return out;
}

}  // namespace plm::lsystem
