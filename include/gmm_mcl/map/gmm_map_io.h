// The map file (DESIGN.md "Map file"): little-endian, versioned, checksummed.
//
//   offset  size  field
//   0       8     magic "GMMMCL\0\x1a"
//   8       4     uint32 format version (kMapFormatVersion)
//   12      4     uint32 component count M (> 0)
//   16      4     uint32 scalar type (1 = float32)
//   20      4     uint32 reserved, 0
//   24      4M    weights lambda_i
//   ..      12M   means (x, y, z) in metres, map frame
//   ..      24M   covariances, upper triangle (xx, xy, xz, yy, yz, zz) in m^2
//   end-4   4     uint32 CRC-32 (IEEE) of every byte before it
//
// 40 bytes of payload per component: a 1000-component map is 40,028 bytes.
#pragma once

#include <cstdint>
#include <istream>
#include <string>
#include <vector>

#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {

constexpr uint32_t kMapFormatVersion = 1;
constexpr size_t kMapHeaderBytes = 24;
constexpr size_t kMapBytesPerComponent = 40;

// CRC-32 (IEEE 802.3, reflected, as zlib's crc32).
uint32_t crc32(const uint8_t* data, size_t size, uint32_t crc = 0);

// Serialises a map to bytes (no validation beyond what GmmMap already did).
std::vector<uint8_t> encodeMap(const GmmMap& map);
// Parses and validates bytes; throws MapError("<source>: <fault>"). Beyond GmmMap's own checks
// it rejects covariances so close to singular that their inverse overflows float32 (the
// backends' precision), which would otherwise load as a map with infinite precisions.
GmmMap decodeMap(const std::vector<uint8_t>& bytes, const std::string& source);
// Reads the whole stream, then decodeMap; throws MapError naming `source` on a read error.
GmmMap readMap(std::istream& in, const std::string& source);

// Writes the map; throws MapError naming the path when it cannot be written.
void saveMap(const GmmMap& map, const std::string& path);
// Loads and validates; throws MapError naming the path and the fault.
GmmMap loadMap(const std::string& path);

}  // namespace gmm_mcl
