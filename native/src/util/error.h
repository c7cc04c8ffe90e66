// The engine reports failures by throwing plm::Error with a status and a
// message that says what was wrong and where; the C API turns it into a code.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

#include "photonlm/photonlm.h"

namespace plm {

class Error : public std::runtime_error {
 public:
  Error(plm_status status, const std::string& message) : std::runtime_error(message), status_(status) {}
  plm_status status() const { return status_; }

 private:
  plm_status status_;
};

// Builds a message from pieces: fail(PLM_ERROR_INVALID_ARGUMENT, "mesh '", name, "': ...").
template <typename... Args>
[[noreturn]] void fail(plm_status status, const Args&... args) {
  std::ostringstream s;
  (s << ... << args);
  throw Error(status, s.str());
}

}  // namespace plm
