// Numbers as options write them (comma-separated: "0.1,-2,3e-3") and as data-set and trajectory
// files write them (whitespace-separated lines, '#' comments).
#pragma once

#include <cmath>
#include <cstdlib>
#include <istream>
#include <sstream>
#include <string>
#include <vector>

namespace gmm_mcl {

// True when the whole of `tok` is a finite number (then *x is it).
inline bool parseFiniteNumber(const std::string& tok, double* x) {
  char* end = nullptr;
  *x = std::strtod(tok.c_str(), &end);
  return end != tok.c_str() && *end == '\0' && std::isfinite(*x);
}

// The finite numbers of a comma-separated list; empty when any item is not one.
inline std::vector<double> parseNumberList(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string tok;
  while (std::getline(ss, tok, ',')) {
    double x = 0.0;
    if (!parseFiniteNumber(tok, &x)) return {};
    v.push_back(x);
  }
  return v;
}

// Appends the whitespace-separated numbers of `line` to *out; false at the first token that is
// not a finite number (then *bad is that token).
inline bool parseNumberLine(const std::string& line, std::vector<double>* out, std::string* bad) {
  std::istringstream ls(line);
  std::string tok;
  while (ls >> tok) {
    double x = 0.0;
    if (!parseFiniteNumber(tok, &x)) {
      *bad = tok;
      return false;
    }
    out->push_back(x);
  }
  return true;
}

// Calls on_line(line_no, numbers) for each line of `in` (numbered from 1; '#' starts a comment,
// so a blank or comment line gives no numbers); false at the first token that is not a finite
// number (then *why names the line and the token).
template <class OnLine>
bool forEachNumberLine(std::istream& in, OnLine on_line, std::string* why) {
  std::string line;
  std::vector<double> numbers;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    numbers.clear();
    std::string tok;
    if (!parseNumberLine(line, &numbers, &tok)) {
      *why = "line " + std::to_string(line_no) + ": '" + tok + "' is not a finite number";
      return false;
    }
    on_line(line_no, numbers);
  }
  return true;
}

}  // namespace gmm_mcl
