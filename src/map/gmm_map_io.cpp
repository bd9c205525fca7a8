#include "gmm_mcl/map/gmm_map_io.h"

#include <Eigen/LU>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>

namespace gmm_mcl {
namespace {

constexpr char kMagic[8] = {'G', 'M', 'M', 'M', 'C', 'L', '\0', '\x1a'};
constexpr uint32_t kScalarFloat32 = 1;

std::array<uint32_t, 256> makeCrcTable() {
  std::array<uint32_t, 256> table{};
  for (uint32_t n = 0; n < 256; ++n) {
    uint32_t c = n;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[n] = c;
  }
  return table;
}

void putU32(std::vector<uint8_t>* out, uint32_t v) {
  for (int k = 0; k < 4; ++k) out->push_back(static_cast<uint8_t>(v >> (8 * k)));
}

void putF32(std::vector<uint8_t>* out, double v) {
  const float f = static_cast<float>(v);
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  putU32(out, bits);
}

uint32_t getU32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

double getF32(const uint8_t* p) {
  const uint32_t bits = getU32(p);
  float f;
  std::memcpy(&f, &bits, 4);
  return static_cast<double>(f);
}

[[noreturn]] void fail(const std::string& source, const std::string& what) {
  throw MapError(source + ": " + what);
}

}  // namespace

uint32_t crc32(const uint8_t* data, size_t size, uint32_t crc) {
  static const std::array<uint32_t, 256> table = makeCrcTable();
  crc = ~crc;
  for (size_t i = 0; i < size; ++i) crc = table[(crc ^ data[i]) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

std::vector<uint8_t> encodeMap(const GmmMap& map) {
  const auto& comps = map.components();
  std::vector<uint8_t> out(kMagic, kMagic + sizeof(kMagic));
  out.reserve(kMapHeaderBytes + kMapBytesPerComponent * comps.size() + 4);
  putU32(&out, kMapFormatVersion);
  putU32(&out, static_cast<uint32_t>(comps.size()));
  putU32(&out, kScalarFloat32);
  putU32(&out, 0u);
  for (const auto& c : comps) putF32(&out, c.weight);
  for (const auto& c : comps) {
    for (int k = 0; k < 3; ++k) putF32(&out, c.mean_m[k]);
  }
  for (const auto& c : comps) {
    const Eigen::Matrix3d& s = c.cov_m2;
    for (double v : {s(0, 0), s(0, 1), s(0, 2), s(1, 1), s(1, 2), s(2, 2)}) putF32(&out, v);
  }
  putU32(&out, crc32(out.data(), out.size()));
  return out;
}

GmmMap decodeMap(const std::vector<uint8_t>& bytes, const std::string& source) {
  if (bytes.size() < kMapHeaderBytes + 4) {
    std::ostringstream msg;
    msg << "truncated: " << bytes.size() << " bytes is shorter than the " << kMapHeaderBytes + 4
        << "-byte header and checksum";
    fail(source, msg.str());
  }
  if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    fail(source, "bad magic: not a gmm_mcl map file");
  }
  const uint32_t version = getU32(bytes.data() + 8);
  if (version != kMapFormatVersion) {
    std::ostringstream msg;
    msg << "unsupported format version " << version << " (this build reads version "
        << kMapFormatVersion << ")";
    fail(source, msg.str());
  }
  const uint32_t count = getU32(bytes.data() + 12);
  const uint32_t scalar = getU32(bytes.data() + 16);
  if (scalar != kScalarFloat32) {
    fail(source, "unsupported scalar type " + std::to_string(scalar) + " (1 = float32)");
  }
  if (count == 0) fail(source, "component count is 0");
  const uint64_t expected = kMapHeaderBytes + uint64_t{kMapBytesPerComponent} * count + 4;
  if (bytes.size() != expected) {
    std::ostringstream msg;
    msg << (bytes.size() < expected ? "truncated" : "trailing bytes") << ": header says " << count
        << " components (" << expected << " bytes) but the file has " << bytes.size() << " bytes";
    fail(source, msg.str());
  }
  const uint32_t stored_crc = getU32(bytes.data() + bytes.size() - 4);
  const uint32_t actual_crc = crc32(bytes.data(), bytes.size() - 4);
  if (stored_crc != actual_crc) {
    std::ostringstream msg;
    msg << std::hex << "checksum mismatch: stored 0x" << stored_crc << ", computed 0x" << actual_crc
        << " (file corrupted)";
    fail(source, msg.str());
  }
  std::vector<GaussianComponent> comps(count);
  const uint8_t* w = bytes.data() + kMapHeaderBytes;
  const uint8_t* mu = w + 4 * count;
  const uint8_t* cov = mu + 12 * count;
  for (uint32_t i = 0; i < count; ++i) {
    GaussianComponent& c = comps[i];
    c.weight = getF32(w + 4 * i);
    for (int k = 0; k < 3; ++k) c.mean_m[k] = getF32(mu + 12 * i + 4 * k);
    const uint8_t* s = cov + 24 * i;
    const double xx = getF32(s), xy = getF32(s + 4), xz = getF32(s + 8);
    const double yy = getF32(s + 12), yz = getF32(s + 16), zz = getF32(s + 20);
    c.cov_m2 << xx, xy, xz, xy, yy, yz, xz, yz, zz;
  }
  // GmmMap's checks first, so that each fault keeps its own message; then the float32 range of
  // the precision that GmmMap packs for the backends: beyond it the cast gives infinity, and an
  // infinite precision turns the component's likelihood terms into NaN or -Inf.
  validateComponents(comps, source);
  for (uint32_t i = 0; i < count; ++i) {
    const double max_precision = comps[i].cov_m2.inverse().cwiseAbs().maxCoeff();
    if (!(max_precision <= std::numeric_limits<float>::max())) {
      std::ostringstream msg;
      msg << "component " << i << ": covariance is too close to singular (its inverse has an entry "
          << max_precision << ", beyond float32)";
      fail(source, msg.str());
    }
  }
  return GmmMap(std::move(comps), source);
}

GmmMap readMap(std::istream& in, const std::string& source) {
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
  if (in.bad()) fail(source, "read error");
  return decodeMap(bytes, source);
}

void saveMap(const GmmMap& map, const std::string& path) {
  const std::vector<uint8_t> bytes = encodeMap(map);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) fail(path, std::string("cannot open for writing: ") + std::strerror(errno));
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  if (!out) fail(path, "write failed");
}

GmmMap loadMap(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, std::string("cannot open: ") + std::strerror(errno));
  return readMap(in, path);
}

}  // namespace gmm_mcl
