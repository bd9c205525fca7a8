// Writing the experiments' CSV files (private to src/experiments/figures).
#pragma once

#include <fstream>
#include <stdexcept>
#include <string>

namespace gmm_mcl {
namespace figures {

// Writes `path`: the header line, then write_rows(out) at `precision` significant digits; throws
// std::runtime_error naming the file when it cannot be opened or written.
template <class WriteRows>
void writeCsvFile(const std::string& path, const char* header, int precision,
                  WriteRows write_rows) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  out << header << '\n';
  out.precision(precision);
  write_rows(out);
  if (!out) throw std::runtime_error(path + ": write failed");
}

}  // namespace figures
}  // namespace gmm_mcl
