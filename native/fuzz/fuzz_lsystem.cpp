// libFuzzer target for the L-system language (lsystem/language/lsystem.h): the input
// bytes are the system's text, parsed, derived (depth at most 6, at most
// 20000 modules and 100000 parameters, a seed from the input's length) and
// interpreted by the turtle. Any plm::Error is a correct answer; a crash,
// hang, leak or sanitizer report is a bug. A successful run must give finite
// transforms and consistent counts. Build and run: scripts/fuzz.sh [seconds].
#include <stddef.h>
#include <stdint.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string_view>

#include "lsystem/language/lsystem.h"
#include "lsystem/language/turtle.h"
#include "util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const plm::lsystem::LSystem sys = plm::lsystem::parse(text);
    plm::lsystem::DeriveOptions opt;
    opt.depth = std::min(sys.depth, 6);
    opt.seed = size;
    opt.max_modules = 20000;
    opt.max_params = 100000;
    const plm::lsystem::ModuleString s = plm::lsystem::derive(sys, opt);
    if (s.modules.size() > opt.max_modules || s.params.size() > opt.max_params) abort();
    for (double v : s.params)
      if (!std::isfinite(v)) abort();
    (void)plm::lsystem::to_string(sys, s);
    const plm::lsystem::TurtleResult t = plm::lsystem::interpret(sys, s);
    size_t total = 0;
    for (size_t c : t.count) total += c;
    if (total != t.primitives.size() || total > s.modules.size()) abort();
    for (const auto& p : t.primitives)
      for (double v : p.to_world)
        if (!std::isfinite(v)) abort();
  } catch (const plm::Error&) {
  }
  return 0;
}
