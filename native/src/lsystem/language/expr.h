// Evaluation of L-system expressions (lsystem/language/lsystem.h): a tree walk over
// the system's node pool with the production's parameter values and a keyed
// random stream, so that rand() depends only on (seed, step, module, draw).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lsystem/language/lsystem.h"
#include "util/rng.h"

namespace plm::lsystem {

// Counter-based stream: draw k of key is a pure function of (key, k).
struct RandomStream {
  uint64_t key = 0;
  uint64_t counter = 0;
  double uniform() { return double(splitmix64(key + counter++) >> 11) * (1.0 / 9007199254740992.0); }
};

inline uint64_t stream_key(uint64_t seed, uint64_t step, uint64_t position, uint64_t domain) {
  return splitmix64(splitmix64(splitmix64(seed) + step) + position * 4 + domain);
}

// What went wrong inside an expression; callers add where (line, production).
struct EvalError {
  std::string what;
};

// Throws EvalError on division by zero or a NaN / infinite result. rng may be
// null (constants): rand() then throws.
double evaluate(const std::vector<ExprNode>& nodes, int32_t root, const double* vars, RandomStream* rng);

}  // namespace plm::lsystem
