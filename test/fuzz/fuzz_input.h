// Shared by the fuzz targets, their corpus generator and the replay runner: a byte reader that
// turns the fuzzer's input into typed fields (reading past the end yields zeros, so every input
// is a valid one), the matching writer, and FUZZ_CHECK for the targets' invariants.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <string>
#include <vector>

#ifdef GMM_MCL_LIBFUZZER
extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);
#endif
// The libFuzzer entry point each target defines; replay_main.cpp calls it without libFuzzer.
extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

// An invariant of a target: violated, the input is a bug; abort() so that libFuzzer saves the
// input and the replay test fails.
#define FUZZ_CHECK(cond)                                                                 \
  do {                                                                                   \
    if (!(cond)) {                                                                       \
      std::fprintf(stderr, "%s:%d: FUZZ_CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                                      \
    }                                                                                    \
  } while (0)

namespace gmm_mcl {
namespace fuzz {

// Selector bytes below kSpecialCount pick a value from these tables (what a mutator rarely
// builds from raw bits); larger selectors read the raw value that follows.
constexpr uint8_t kSpecialCount = 16;

inline double specialDouble(uint8_t i) {
  const double table[kSpecialCount] = {0.0,
                                       -1.0,
                                       std::numeric_limits<double>::quiet_NaN(),
                                       std::numeric_limits<double>::infinity(),
                                       -std::numeric_limits<double>::infinity(),
                                       1e300,
                                       1e-300,
                                       2.0 * std::numeric_limits<float>::max(),
                                       std::numeric_limits<double>::denorm_min(),
                                       1.0,
                                       0.1,
                                       4.0,
                                       525.0,
                                       319.5,
                                       -0.0,
                                       1e20};
  return table[i % kSpecialCount];
}

class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : data_(data), size_(size) {}

  uint8_t u8() {
    uint8_t v = 0;
    take(&v, 1);
    return v;
  }
  uint32_t u32() {
    uint8_t b[4] = {0, 0, 0, 0};
    take(b, 4);
    return uint32_t{b[0]} | (uint32_t{b[1]} << 8) | (uint32_t{b[2]} << 16) | (uint32_t{b[3]} << 24);
  }
  int32_t i32() {
    const uint32_t u = u32();
    int32_t v;
    std::memcpy(&v, &u, 4);
    return v;
  }
  double f64() {
    uint8_t b[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    take(b, 8);
    double v;
    std::memcpy(&v, b, 8);
    return v;
  }
  // A selector byte, then a table value or a raw little-endian double.
  double number() {
    const uint8_t sel = u8();
    return sel < kSpecialCount ? specialDouble(sel) : f64();
  }
  // A length byte (at most max_len), then the characters.
  // One of `names` chosen by a selector byte (modulo 8), else (selectors past the names) a
  // string of the input: the encodings and formats a harness tries.
  std::string nameOrString(std::initializer_list<const char*> names, size_t max_len) {
    const size_t sel = u8() % 8;
    return sel < names.size() ? std::string(names.begin()[sel]) : str(max_len);
  }
  std::string str(size_t max_len) {
    const size_t n = std::min<size_t>(u8(), max_len);
    std::string s(n, '\0');
    take(&s[0], n);
    return s;
  }
  // What is left.
  const uint8_t* rest() const { return data_ + pos_; }
  size_t restSize() const { return size_ - pos_; }

 private:
  void take(void* out, size_t n) {
    const size_t k = std::min(n, size_ - pos_);
    if (k > 0) std::memcpy(out, data_ + pos_, k);
    pos_ += k;
  }
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
};

// Writes what Reader reads (corpus generator, tests).
class Writer {
 public:
  void u8(uint8_t v) { bytes.push_back(v); }
  void u32(uint32_t v) {
    for (int k = 0; k < 4; ++k) bytes.push_back(static_cast<uint8_t>(v >> (8 * k)));
  }
  void i32(int32_t v) {
    uint32_t u;
    std::memcpy(&u, &v, 4);
    u32(u);
  }
  void f64(double v) {
    uint8_t b[8];
    std::memcpy(b, &v, 8);
    bytes.insert(bytes.end(), b, b + 8);
  }
  // A special-table entry (sel < kSpecialCount) or a raw value (selector 0xFF).
  void special(uint8_t sel) { u8(sel); }
  void number(double v) {
    u8(0xFF);
    f64(v);
  }
  void str(const std::string& s) {
    u8(static_cast<uint8_t>(s.size()));
    bytes.insert(bytes.end(), s.begin(), s.end());
  }
  void raw(const std::vector<uint8_t>& b) { bytes.insert(bytes.end(), b.begin(), b.end()); }

  std::vector<uint8_t> bytes;
};

#ifdef GMM_MCL_LIBFUZZER
// libFuzzer's own mutation of the input, then after every other one (odd seeds) `repair` on the
// mutated bytes (data, size): checksums recomputed, so that half of the inputs get past them.
template <typename Repair>
size_t mutateAndRepair(uint8_t* data, size_t size, size_t max_size, unsigned int seed,
                       Repair repair) {
  size = LLVMFuzzerMutate(data, size, max_size);
  if ((seed & 1u) != 0) repair(data, size);
  return size;
}
#endif

}  // namespace fuzz
}  // namespace gmm_mcl
