#include "gmm_mcl/fit/point_cloud_io.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

#include "gmm_mcl/common/binary_scalar.h"
#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/sim/mesh.h"

namespace gmm_mcl {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw FitError(path + ": " + what);
}

std::vector<uint8_t> readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, std::string("cannot open: ") + std::strerror(errno));
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
  if (in.bad()) fail(path, "read error");
  if (bytes.empty()) fail(path, "file is empty");
  return bytes;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string extensionOf(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  return lower(path.substr(dot + 1));
}

// Reads the next header line starting at *pos (without the newline); false at the end.
bool nextLine(const std::vector<uint8_t>& b, size_t* pos, std::string* line) {
  if (*pos >= b.size()) return false;
  const size_t start = *pos;
  while (*pos < b.size() && b[*pos] != '\n') ++*pos;
  line->assign(reinterpret_cast<const char*>(b.data()) + start, *pos - start);
  if (!line->empty() && line->back() == '\r') line->pop_back();
  if (*pos < b.size()) ++*pos;  // skip '\n'
  return true;
}

bool parseDouble(const std::string& tok, double* v) {
  const char* s = tok.c_str();
  char* end = nullptr;
  *v = std::strtod(s, &end);
  return end != s && *end == '\0';
}

bool parseSize(const std::string& tok, size_t* v) {
  const char* s = tok.c_str();
  char* end = nullptr;
  errno = 0;
  const unsigned long long x = std::strtoull(s, &end, 10);
  if (end == s || *end != '\0' || errno != 0 || tok[0] == '-') return false;
  *v = static_cast<size_t>(x);
  return true;
}

// ---- scalar types (PCD TYPE/SIZE; decoding in common/binary_scalar.h) ------------------------

using Scalar = ScalarType;

// ---- PCD ------------------------------------------------------------------------------------

// LZF decompression (liblzf format, as PCL's binary_compressed uses).
bool lzfDecompress(const uint8_t* in, size_t in_len, uint8_t* out, size_t out_len) {
  size_t ip = 0, op = 0;
  while (ip < in_len) {
    const unsigned ctrl = in[ip++];
    if (ctrl < 32) {
      const size_t len = ctrl + 1;
      if (op + len > out_len || ip + len > in_len) return false;
      std::memcpy(out + op, in + ip, len);
      op += len;
      ip += len;
    } else {
      size_t len = ctrl >> 5;
      if (len == 7) {
        if (ip >= in_len) return false;
        len += in[ip++];
      }
      if (ip >= in_len) return false;
      const size_t back = ((ctrl & 0x1f) << 8) + in[ip++] + 1;
      len += 2;
      if (back > op || op + len > out_len) return false;
      for (size_t i = 0; i < len; ++i, ++op) out[op] = out[op - back];
    }
  }
  return op == out_len;
}

struct PcdField {
  std::string name;
  size_t size = 4;
  char type = 'F';
  size_t count = 1;
};

struct PcdHeader {
  std::vector<PcdField> fields;
  std::string data_kind;  // ascii, binary, binary_compressed (lower case)
  size_t points = 0;
  size_t width = 0, height = 1;
  bool have_points = false;   // a POINTS line (else WIDTH * HEIGHT)
  int xyz[3] = {-1, -1, -1};  // the fields x, y, z
  size_t body_pos = 0;        // the first byte after the DATA line
};

Scalar pcdScalar(const PcdField& f, const std::string& path) {
  if (f.type == 'F' && f.size == 4) return Scalar::kF32;
  if (f.type == 'F' && f.size == 8) return Scalar::kF64;
  if (f.type == 'I' && f.size == 1) return Scalar::kI8;
  if (f.type == 'U' && f.size == 1) return Scalar::kU8;
  if (f.type == 'I' && f.size == 2) return Scalar::kI16;
  if (f.type == 'U' && f.size == 2) return Scalar::kU16;
  if (f.type == 'I' && f.size == 4) return Scalar::kI32;
  if (f.type == 'U' && f.size == 4) return Scalar::kU32;
  if (f.type == 'I' && f.size == 8) return Scalar::kI64;
  if (f.type == 'U' && f.size == 8) return Scalar::kU64;
  fail(path, "PCD field " + f.name + " has unsupported TYPE/SIZE");
}

// The header lines up to DATA: fields, their SIZE/TYPE/COUNT, the point count.
PcdHeader readPcdHeaderLines(const std::vector<uint8_t>& b, const std::string& path,
                             std::vector<std::string>* sizes, std::vector<std::string>* types,
                             std::vector<std::string>* counts) {
  PcdHeader h;
  std::string line;
  while (nextLine(b, &h.body_pos, &line)) {
    const std::vector<std::string> t = splitWords(line);
    if (t.empty() || t[0][0] == '#') continue;
    const std::string key = lower(t[0]);
    if (key == "fields") {
      for (size_t i = 1; i < t.size(); ++i) {
        h.fields.emplace_back();
        h.fields.back().name = lower(t[i]);
      }
    } else if (key == "size") {
      sizes->assign(t.begin() + 1, t.end());
    } else if (key == "type") {
      types->assign(t.begin() + 1, t.end());
    } else if (key == "count") {
      counts->assign(t.begin() + 1, t.end());
    } else if (key == "width") {
      if (t.size() < 2 || !parseSize(t[1], &h.width)) fail(path, "bad WIDTH line: " + line);
    } else if (key == "height") {
      if (t.size() < 2 || !parseSize(t[1], &h.height)) fail(path, "bad HEIGHT line: " + line);
    } else if (key == "points") {
      if (t.size() < 2 || !parseSize(t[1], &h.points)) fail(path, "bad POINTS line: " + line);
      h.have_points = true;
    } else if (key == "data") {
      if (t.size() < 2) fail(path, "DATA line names no encoding");
      h.data_kind = lower(t[1]);
      break;
    } else if (key != "version" && key != "viewpoint") {
      fail(path, "not a PCD file (unexpected header line '" + line + "')");
    }
  }
  if (h.data_kind.empty()) fail(path, "not a PCD file (no DATA line)");
  return h;
}

// The header, checked: every field's size, type and count; x, y and z present, one value each.
PcdHeader readPcdHeader(const std::vector<uint8_t>& b, const std::string& path) {
  std::vector<std::string> sizes, types, counts;
  PcdHeader h = readPcdHeaderLines(b, path, &sizes, &types, &counts);
  std::vector<PcdField>& fields = h.fields;
  if (fields.empty()) fail(path, "PCD header has no FIELDS");
  if (sizes.size() != fields.size() || types.size() != fields.size() ||
      (!counts.empty() && counts.size() != fields.size())) {
    fail(path, "PCD header: FIELDS, SIZE, TYPE and COUNT disagree in length");
  }
  for (size_t i = 0; i < fields.size(); ++i) {
    if (!parseSize(sizes[i], &fields[i].size) || types[i].size() != 1 ||
        (!counts.empty() && !parseSize(counts[i], &fields[i].count))) {
      fail(path, "PCD header: bad SIZE/TYPE/COUNT for field " + fields[i].name);
    }
    fields[i].type = static_cast<char>(std::toupper(types[i][0]));
  }
  if (!h.have_points) h.points = h.width * h.height;
  if (h.width * h.height != h.points) fail(path, "PCD header: WIDTH * HEIGHT differs from POINTS");
  for (size_t i = 0; i < fields.size(); ++i) {
    if (fields[i].name == "x") h.xyz[0] = static_cast<int>(i);
    if (fields[i].name == "y") h.xyz[1] = static_cast<int>(i);
    if (fields[i].name == "z") h.xyz[2] = static_cast<int>(i);
  }
  if (h.xyz[0] < 0 || h.xyz[1] < 0 || h.xyz[2] < 0) fail(path, "PCD has no x, y and z fields");
  for (const auto& f : fields) pcdScalar(f, path);
  for (int a : h.xyz) {
    if (fields[a].count != 1) fail(path, "PCD field " + fields[a].name + " has COUNT != 1");
  }
  return h;
}

void readPcdAscii(const std::vector<uint8_t>& b, const PcdHeader& h, const std::string& path,
                  PointCloud* out) {
  size_t token_index[3];
  size_t tokens_per_point = 0;
  for (size_t i = 0; i < h.fields.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      if (static_cast<int>(i) == h.xyz[a]) token_index[a] = tokens_per_point;
    }
    tokens_per_point += h.fields[i].count;
  }
  size_t pos = h.body_pos;
  std::string line;
  size_t n = 0;
  while (n < h.points && nextLine(b, &pos, &line)) {
    const std::vector<std::string> t = splitWords(line);
    if (t.empty()) continue;
    if (t.size() < tokens_per_point) {
      fail(path, "ascii point " + std::to_string(n) + " has " + std::to_string(t.size()) +
                     " values, expected " + std::to_string(tokens_per_point));
    }
    for (int a = 0; a < 3; ++a) {
      double v;
      if (!parseDouble(t[token_index[a]], &v)) {
        fail(path, "ascii point " + std::to_string(n) + ": bad number '" + t[token_index[a]] + "'");
      }
      (*out)[n][a] = static_cast<float>(v);
    }
    ++n;
  }
  if (n != h.points) {
    fail(path, "truncated: header says " + std::to_string(h.points) + " points, found " +
                   std::to_string(n));
  }
}

// binary (records of all fields) or binary_compressed (LZF; per field: all points' values).
void readPcdBinary(const std::vector<uint8_t>& b, const PcdHeader& h, const std::string& path,
                   PointCloud* out) {
  const std::vector<PcdField>& fields = h.fields;
  const size_t pos = h.body_pos, points = h.points;
  size_t record = 0;
  std::vector<size_t> field_offset(fields.size());
  for (size_t i = 0; i < fields.size(); ++i) {
    field_offset[i] = record;
    record += fields[i].size * fields[i].count;
  }
  if (h.data_kind == "binary") {
    if (b.size() - pos < record * points) {
      fail(path, "truncated binary data: need " + std::to_string(record * points) +
                     " bytes, have " + std::to_string(b.size() - pos));
    }
    for (size_t n = 0; n < points; ++n) {
      const uint8_t* r = b.data() + pos + n * record;
      for (int a = 0; a < 3; ++a) {
        (*out)[n][a] = static_cast<float>(
            decodeScalar(r + field_offset[h.xyz[a]], pcdScalar(fields[h.xyz[a]], path), false));
      }
    }
    return;
  }
  if (b.size() - pos < 8) fail(path, "truncated binary_compressed header");
  uint32_t csize, usize;
  std::memcpy(&csize, b.data() + pos, 4);
  std::memcpy(&usize, b.data() + pos + 4, 4);
  if (b.size() - pos - 8 < csize) fail(path, "truncated binary_compressed data");
  if (usize != record * points) {
    fail(path, "binary_compressed size " + std::to_string(usize) + " does not match " +
                   std::to_string(points) + " points of " + std::to_string(record) + " bytes");
  }
  std::vector<uint8_t> raw(usize);
  if (usize > 0 && !lzfDecompress(b.data() + pos + 8, csize, raw.data(), usize)) {
    fail(path, "corrupt binary_compressed (LZF) data");
  }
  for (int a = 0; a < 3; ++a) {
    const PcdField& f = fields[h.xyz[a]];
    const size_t base = field_offset[h.xyz[a]] * points;
    for (size_t n = 0; n < points; ++n) {
      (*out)[n][a] = static_cast<float>(
          decodeScalar(raw.data() + base + n * f.size, pcdScalar(f, path), false));
    }
  }
}

}  // namespace

PointCloud readPcd(const std::string& path) {
  const std::vector<uint8_t> b = readAll(path);
  const PcdHeader h = readPcdHeader(b, path);
  PointCloud out(h.points);
  if (h.data_kind == "ascii") {
    readPcdAscii(b, h, path, &out);
  } else if (h.data_kind == "binary" || h.data_kind == "binary_compressed") {
    readPcdBinary(b, h, path, &out);
  } else {
    fail(path, "unsupported PCD DATA encoding '" + h.data_kind + "'");
  }
  return out;
}

// ---- PLY (the package's one reader, sim/mesh.h) ---------------------------------------------

CloudFile readPly(const std::string& path) {
  sim::PlyContents ply;
  try {
    ply = sim::readPlyFile(path);
  } catch (const sim::MeshError& e) {
    throw FitError(e.what());
  }
  CloudFile out;
  out.points = ply.mesh.vertices_m;
  if (!ply.mesh.triangles.empty()) out.mesh = std::move(ply.mesh);
  return out;
}

PointCloud readXyz(const std::string& path) {
  const std::vector<uint8_t> b = readAll(path);
  size_t pos = 0;
  std::string line;
  PointCloud out;
  size_t line_no = 0;
  while (nextLine(b, &pos, &line)) {
    ++line_no;
    const std::vector<std::string> t = splitWords(line);
    if (t.empty() || t[0][0] == '#') continue;
    if (t.size() < 3) fail(path, "line " + std::to_string(line_no) + ": fewer than 3 numbers");
    Eigen::Vector3f p;
    for (int a = 0; a < 3; ++a) {
      double v;
      if (!parseDouble(t[a], &v)) {
        fail(path, "line " + std::to_string(line_no) + ": bad number '" + t[a] + "'");
      }
      p[a] = static_cast<float>(v);
    }
    out.push_back(p);
  }
  return out;
}

CloudFile readCloudFile(const std::string& path) {
  const std::string ext = extensionOf(path);
  CloudFile out;
  if (ext == "pcd") {
    out.points = readPcd(path);
  } else if (ext == "ply") {
    out = readPly(path);
  } else if (ext == "xyz" || ext == "txt") {
    out.points = readXyz(path);
  } else {
    fail(path, "unknown point-cloud extension '." + ext + "' (expected .pcd, .ply, .xyz, .txt)");
  }
  return out;
}

void writePcd(const PointCloud& points, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) fail(path, std::string("cannot open for writing: ") + std::strerror(errno));
  out << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\n"
      << "SIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " << points.size()
      << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << points.size() << "\nDATA binary\n";
  // Little-endian float32 (every supported target is little-endian).
  for (const auto& p : points) out.write(reinterpret_cast<const char*>(p.data()), 12);
  if (!out) fail(path, "write failed");
}

void writeXyz(const PointCloud& points, const std::string& path) {
  std::ofstream out(path, std::ios::trunc);
  if (!out) fail(path, std::string("cannot open for writing: ") + std::strerror(errno));
  out.precision(9);
  for (const auto& p : points) out << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  if (!out) fail(path, "write failed");
}

}  // namespace gmm_mcl
