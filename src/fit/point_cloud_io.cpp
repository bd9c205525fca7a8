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

#include "gmm_mcl/fit/fit_error.h"

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

std::vector<std::string> split(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> out;
  std::string tok;
  while (in >> tok) out.push_back(tok);
  return out;
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

// ---- scalar decoding (PCD TYPE/SIZE and PLY types) ----------------------------------------

enum class Scalar { kI8, kU8, kI16, kU16, kI32, kU32, kF32, kF64, kI64, kU64 };

size_t scalarSize(Scalar s) {
  switch (s) {
    case Scalar::kI8:
    case Scalar::kU8:
      return 1;
    case Scalar::kI16:
    case Scalar::kU16:
      return 2;
    case Scalar::kI32:
    case Scalar::kU32:
    case Scalar::kF32:
      return 4;
    default:
      return 8;
  }
}

double decodeScalar(const uint8_t* p, Scalar s, bool big_endian) {
  uint8_t buf[8];
  const size_t n = scalarSize(s);
  for (size_t i = 0; i < n; ++i) buf[i] = big_endian ? p[n - 1 - i] : p[i];
  switch (s) {
    case Scalar::kI8: {
      int8_t v;
      std::memcpy(&v, buf, 1);
      return v;
    }
    case Scalar::kU8:
      return buf[0];
    case Scalar::kI16: {
      int16_t v;
      std::memcpy(&v, buf, 2);
      return v;
    }
    case Scalar::kU16: {
      uint16_t v;
      std::memcpy(&v, buf, 2);
      return v;
    }
    case Scalar::kI32: {
      int32_t v;
      std::memcpy(&v, buf, 4);
      return v;
    }
    case Scalar::kU32: {
      uint32_t v;
      std::memcpy(&v, buf, 4);
      return v;
    }
    case Scalar::kF32: {
      float v;
      std::memcpy(&v, buf, 4);
      return v;
    }
    case Scalar::kF64: {
      double v;
      std::memcpy(&v, buf, 8);
      return v;
    }
    case Scalar::kI64: {
      int64_t v;
      std::memcpy(&v, buf, 8);
      return static_cast<double>(v);
    }
    case Scalar::kU64: {
      uint64_t v;
      std::memcpy(&v, buf, 8);
      return static_cast<double>(v);
    }
  }
  return 0.0;
}

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

}  // namespace

PointCloud readPcd(const std::string& path) {
  const std::vector<uint8_t> b = readAll(path);
  size_t pos = 0;
  std::string line, data_kind;
  std::vector<PcdField> fields;
  std::vector<std::string> sizes, types, counts;
  size_t width = 0, height = 1, points = 0;
  bool have_points = false;
  while (nextLine(b, &pos, &line)) {
    const std::vector<std::string> t = split(line);
    if (t.empty() || t[0][0] == '#') continue;
    const std::string key = lower(t[0]);
    if (key == "fields") {
      for (size_t i = 1; i < t.size(); ++i) {
        fields.emplace_back();
        fields.back().name = lower(t[i]);
      }
    } else if (key == "size") {
      sizes.assign(t.begin() + 1, t.end());
    } else if (key == "type") {
      types.assign(t.begin() + 1, t.end());
    } else if (key == "count") {
      counts.assign(t.begin() + 1, t.end());
    } else if (key == "width") {
      if (t.size() < 2 || !parseSize(t[1], &width)) fail(path, "bad WIDTH line: " + line);
    } else if (key == "height") {
      if (t.size() < 2 || !parseSize(t[1], &height)) fail(path, "bad HEIGHT line: " + line);
    } else if (key == "points") {
      if (t.size() < 2 || !parseSize(t[1], &points)) fail(path, "bad POINTS line: " + line);
      have_points = true;
    } else if (key == "data") {
      if (t.size() < 2) fail(path, "DATA line names no encoding");
      data_kind = lower(t[1]);
      break;
    } else if (key != "version" && key != "viewpoint") {
      fail(path, "not a PCD file (unexpected header line '" + line + "')");
    }
  }
  if (data_kind.empty()) fail(path, "not a PCD file (no DATA line)");
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
  if (!have_points) points = width * height;
  if (width * height != points) fail(path, "PCD header: WIDTH * HEIGHT differs from POINTS");
  int ix = -1, iy = -1, iz = -1;
  for (size_t i = 0; i < fields.size(); ++i) {
    if (fields[i].name == "x") ix = static_cast<int>(i);
    if (fields[i].name == "y") iy = static_cast<int>(i);
    if (fields[i].name == "z") iz = static_cast<int>(i);
  }
  if (ix < 0 || iy < 0 || iz < 0) fail(path, "PCD has no x, y and z fields");
  auto scalarOf = [&](const PcdField& f) {
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
  };
  for (const auto& f : fields) scalarOf(f);
  const int xyz[3] = {ix, iy, iz};
  for (int a : xyz) {
    if (fields[a].count != 1) fail(path, "PCD field " + fields[a].name + " has COUNT != 1");
  }
  PointCloud out(points);
  if (data_kind == "ascii") {
    size_t token_index[3];
    size_t tokens_per_point = 0;
    for (size_t i = 0; i < fields.size(); ++i) {
      for (int a = 0; a < 3; ++a) {
        if (static_cast<int>(i) == xyz[a]) token_index[a] = tokens_per_point;
      }
      tokens_per_point += fields[i].count;
    }
    size_t n = 0;
    while (n < points && nextLine(b, &pos, &line)) {
      const std::vector<std::string> t = split(line);
      if (t.empty()) continue;
      if (t.size() < tokens_per_point) {
        fail(path, "ascii point " + std::to_string(n) + " has " + std::to_string(t.size()) +
                       " values, expected " + std::to_string(tokens_per_point));
      }
      for (int a = 0; a < 3; ++a) {
        double v;
        if (!parseDouble(t[token_index[a]], &v)) {
          fail(path,
               "ascii point " + std::to_string(n) + ": bad number '" + t[token_index[a]] + "'");
        }
        out[n][a] = static_cast<float>(v);
      }
      ++n;
    }
    if (n != points) {
      fail(path, "truncated: header says " + std::to_string(points) + " points, found " +
                     std::to_string(n));
    }
  } else if (data_kind == "binary" || data_kind == "binary_compressed") {
    size_t record = 0;
    size_t offset[3] = {0, 0, 0};
    std::vector<size_t> field_offset(fields.size());
    for (size_t i = 0; i < fields.size(); ++i) {
      field_offset[i] = record;
      for (int a = 0; a < 3; ++a) {
        if (static_cast<int>(i) == xyz[a]) offset[a] = record;
      }
      record += fields[i].size * fields[i].count;
    }
    if (data_kind == "binary") {
      if (b.size() - pos < record * points) {
        fail(path, "truncated binary data: need " + std::to_string(record * points) +
                       " bytes, have " + std::to_string(b.size() - pos));
      }
      for (size_t n = 0; n < points; ++n) {
        const uint8_t* r = b.data() + pos + n * record;
        for (int a = 0; a < 3; ++a) {
          out[n][a] =
              static_cast<float>(decodeScalar(r + offset[a], scalarOf(fields[xyz[a]]), false));
        }
      }
    } else {
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
      // Decompressed layout is per field: all points' values of field 0, then field 1, ...
      for (int a = 0; a < 3; ++a) {
        const PcdField& f = fields[xyz[a]];
        const size_t base = field_offset[xyz[a]] * points;
        for (size_t n = 0; n < points; ++n) {
          out[n][a] =
              static_cast<float>(decodeScalar(raw.data() + base + n * f.size, scalarOf(f), false));
        }
      }
    }
  } else {
    fail(path, "unsupported PCD DATA encoding '" + data_kind + "'");
  }
  return out;
}

// ---- PLY ------------------------------------------------------------------------------------

namespace {

bool plyScalar(const std::string& name, Scalar* s) {
  static const std::pair<const char*, Scalar> kTypes[] = {
      {"char", Scalar::kI8},    {"int8", Scalar::kI8},     {"uchar", Scalar::kU8},
      {"uint8", Scalar::kU8},   {"short", Scalar::kI16},   {"int16", Scalar::kI16},
      {"ushort", Scalar::kU16}, {"uint16", Scalar::kU16},  {"int", Scalar::kI32},
      {"int32", Scalar::kI32},  {"uint", Scalar::kU32},    {"uint32", Scalar::kU32},
      {"float", Scalar::kF32},  {"float32", Scalar::kF32}, {"double", Scalar::kF64},
      {"float64", Scalar::kF64}};
  for (const auto& t : kTypes) {
    if (name == t.first) {
      *s = t.second;
      return true;
    }
  }
  return false;
}

struct PlyProperty {
  std::string name;
  bool is_list = false;
  Scalar count_type = Scalar::kU8;
  Scalar type = Scalar::kF32;
};

struct PlyElement {
  std::string name;
  size_t count = 0;
  std::vector<PlyProperty> props;
};

// Sequential reader over the body, ascii or binary.
class PlyBody {
 public:
  PlyBody(const std::string& path, const std::vector<uint8_t>& b, size_t pos, int format)
      : path_(path), b_(b), pos_(pos), format_(format) {}
  double read(Scalar s) {
    if (format_ == 0) {  // ascii
      while (pos_ < b_.size() && std::isspace(b_[pos_])) ++pos_;
      const size_t start = pos_;
      while (pos_ < b_.size() && !std::isspace(b_[pos_])) ++pos_;
      if (start == pos_) fail(path_, "truncated ascii PLY body");
      double v;
      if (!parseDouble(std::string(reinterpret_cast<const char*>(b_.data()) + start, pos_ - start),
                       &v)) {
        fail(path_, "bad number in ascii PLY body");
      }
      return v;
    }
    const size_t n = scalarSize(s);
    if (b_.size() - pos_ < n) fail(path_, "truncated binary PLY body");
    const double v = decodeScalar(b_.data() + pos_, s, format_ == 2);
    pos_ += n;
    return v;
  }

 private:
  const std::string& path_;
  const std::vector<uint8_t>& b_;
  size_t pos_;
  int format_;  // 0 ascii, 1 binary little endian, 2 binary big endian
};

}  // namespace

CloudFile readPly(const std::string& path) {
  const std::vector<uint8_t> b = readAll(path);
  size_t pos = 0;
  std::string line;
  if (!nextLine(b, &pos, &line) || line != "ply") fail(path, "not a PLY file (no 'ply' magic)");
  int format = -1;
  std::vector<PlyElement> elements;
  bool ended = false;
  while (nextLine(b, &pos, &line)) {
    const std::vector<std::string> t = split(line);
    if (t.empty()) continue;
    if (t[0] == "comment" || t[0] == "obj_info") continue;
    if (t[0] == "end_header") {
      ended = true;
      break;
    }
    if (t[0] == "format" && t.size() >= 2) {
      if (t[1] == "ascii")
        format = 0;
      else if (t[1] == "binary_little_endian")
        format = 1;
      else if (t[1] == "binary_big_endian")
        format = 2;
      else
        fail(path, "unknown PLY format '" + t[1] + "'");
    } else if (t[0] == "element" && t.size() == 3) {
      elements.emplace_back();
      elements.back().name = t[1];
      if (!parseSize(t[2], &elements.back().count)) fail(path, "bad element line: " + line);
    } else if (t[0] == "property" && !elements.empty()) {
      PlyProperty p;
      if (t.size() == 5 && t[1] == "list") {
        p.is_list = true;
        p.name = t[4];
        if (!plyScalar(t[2], &p.count_type) || !plyScalar(t[3], &p.type)) {
          fail(path, "unknown PLY list types: " + line);
        }
      } else if (t.size() == 3) {
        p.name = t[2];
        if (!plyScalar(t[1], &p.type)) fail(path, "unknown PLY property type: " + line);
      } else {
        fail(path, "bad PLY property line: " + line);
      }
      elements.back().props.push_back(p);
    } else {
      fail(path, "bad PLY header line: " + line);
    }
  }
  if (!ended) fail(path, "PLY header has no end_header");
  if (format < 0) fail(path, "PLY header has no format line");
  CloudFile out;
  PlyBody body(path, b, pos, format);
  bool have_vertices = false;
  for (const PlyElement& e : elements) {
    if (e.name == "vertex") {
      int ix = -1, iy = -1, iz = -1;
      for (size_t i = 0; i < e.props.size(); ++i) {
        if (e.props[i].is_list) continue;
        if (e.props[i].name == "x") ix = static_cast<int>(i);
        if (e.props[i].name == "y") iy = static_cast<int>(i);
        if (e.props[i].name == "z") iz = static_cast<int>(i);
      }
      if (ix < 0 || iy < 0 || iz < 0) fail(path, "PLY vertex element has no x, y, z");
      out.points.resize(e.count);
      for (size_t n = 0; n < e.count; ++n) {
        for (size_t i = 0; i < e.props.size(); ++i) {
          const PlyProperty& p = e.props[i];
          if (p.is_list) {
            const double c = body.read(p.count_type);
            for (size_t k = 0; k < static_cast<size_t>(c); ++k) body.read(p.type);
            continue;
          }
          const double v = body.read(p.type);
          if (static_cast<int>(i) == ix) out.points[n].x() = static_cast<float>(v);
          if (static_cast<int>(i) == iy) out.points[n].y() = static_cast<float>(v);
          if (static_cast<int>(i) == iz) out.points[n].z() = static_cast<float>(v);
        }
      }
      have_vertices = true;
    } else if (e.name == "face") {
      for (size_t n = 0; n < e.count; ++n) {
        for (const PlyProperty& p : e.props) {
          if (!p.is_list) {
            body.read(p.type);
            continue;
          }
          const double c = body.read(p.count_type);
          if (!(c >= 0.0) || c > 1e6) fail(path, "bad face vertex count");
          std::vector<double> idx(static_cast<size_t>(c));
          for (double& v : idx) v = body.read(p.type);
          if (p.name != "vertex_indices" && p.name != "vertex_index") continue;
          if (!have_vertices) fail(path, "PLY faces come before vertices");
          for (double v : idx) {
            if (!(v >= 0.0) || v >= static_cast<double>(out.points.size())) {
              fail(path, "face " + std::to_string(n) + " has vertex index " +
                             std::to_string(static_cast<long long>(v)) + " out of range");
            }
          }
          for (size_t k = 2; k < idx.size(); ++k) {  // fan triangulation
            out.mesh.triangles.push_back({static_cast<uint32_t>(idx[0]),
                                          static_cast<uint32_t>(idx[k - 1]),
                                          static_cast<uint32_t>(idx[k])});
          }
        }
      }
    } else {
      for (size_t n = 0; n < e.count; ++n) {
        for (const PlyProperty& p : e.props) {
          if (p.is_list) {
            const double c = body.read(p.count_type);
            for (size_t k = 0; k < static_cast<size_t>(c); ++k) body.read(p.type);
          } else {
            body.read(p.type);
          }
        }
      }
    }
  }
  if (!have_vertices) fail(path, "PLY has no vertex element");
  if (out.hasFaces()) out.mesh.vertices_m = out.points;
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
    const std::vector<std::string> t = split(line);
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
