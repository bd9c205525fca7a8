// The common ending of the offline tools' main(): their work, with a failure reported by name.
#pragma once

#include <cstdio>
#include <exception>

namespace gmm_mcl {
namespace cli {

// Runs `body` (returning the exit status); an exception is printed as "<tool>: <what>" on stderr
// and gives exit status 1.
template <class Body>
int reportErrors(const char* tool, Body body) {
  try {
    return body();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", tool, e.what());
    return 1;
  }
}

}  // namespace cli
}  // namespace gmm_mcl
