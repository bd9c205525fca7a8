// Comma-separated numbers as options and data-set files write them ("0.1,-2,3e-3").
#pragma once

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

namespace gmm_mcl {

// The finite numbers of a comma-separated list; empty when any item is not one.
inline std::vector<double> parseNumberList(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string tok;
  while (std::getline(ss, tok, ',')) {
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (tok.empty() || end == tok.c_str() || *end != '\0' || !std::isfinite(x)) return {};
    v.push_back(x);
  }
  return v;
}

}  // namespace gmm_mcl
