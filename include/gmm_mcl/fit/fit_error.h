// Errors of the map builder (point-cloud input, fitting, inspection).
#pragma once

#include <stdexcept>

namespace gmm_mcl {

// Thrown for unreadable or malformed input and for fits that cannot be done; the message names
// the file (where there is one) and the fault.
class FitError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace gmm_mcl
