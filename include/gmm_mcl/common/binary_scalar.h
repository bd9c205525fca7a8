// The binary scalars of the file formats the package reads (PLY, PCD): their types, sizes and
// decoding from either byte order; and the words of a header line.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace gmm_mcl {

enum class ScalarType { kI8, kU8, kI16, kU16, kI32, kU32, kI64, kU64, kF32, kF64 };

inline size_t scalarSize(ScalarType t) {
  switch (t) {
    case ScalarType::kI8:
    case ScalarType::kU8:
      return 1;
    case ScalarType::kI16:
    case ScalarType::kU16:
      return 2;
    case ScalarType::kI32:
    case ScalarType::kU32:
    case ScalarType::kF32:
      return 4;
    case ScalarType::kI64:
    case ScalarType::kU64:
    case ScalarType::kF64:
      return 8;
  }
  return 0;
}

inline bool isIntegerScalar(ScalarType t) { return t != ScalarType::kF32 && t != ScalarType::kF64; }

namespace binary_detail {
template <typename T>
double as(const unsigned char* b) {
  T v;
  std::memcpy(&v, b, sizeof(T));
  return static_cast<double>(v);
}
}  // namespace binary_detail

// The scalar of type t at p (big_endian: most significant byte first) as a double.
inline double decodeScalar(const void* p, ScalarType t, bool big_endian) {
  using binary_detail::as;
  const size_t n = scalarSize(t);
  unsigned char b[8];
  std::memcpy(b, p, n);
  if (big_endian) {
    for (size_t i = 0; i < n / 2; ++i) std::swap(b[i], b[n - 1 - i]);
  }
  switch (t) {
    case ScalarType::kI8:
      return as<int8_t>(b);
    case ScalarType::kU8:
      return b[0];
    case ScalarType::kI16:
      return as<int16_t>(b);
    case ScalarType::kU16:
      return as<uint16_t>(b);
    case ScalarType::kI32:
      return as<int32_t>(b);
    case ScalarType::kU32:
      return as<uint32_t>(b);
    case ScalarType::kI64:
      return as<int64_t>(b);
    case ScalarType::kU64:
      return as<uint64_t>(b);
    case ScalarType::kF32:
      return as<float>(b);
    case ScalarType::kF64:
      return as<double>(b);
  }
  return 0.0;
}

// The whitespace-separated words of a line.
inline std::vector<std::string> splitWords(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  std::string word;
  while (in >> word) out.push_back(word);
  return out;
}

}  // namespace gmm_mcl
