// The package's one PLY reader (ascii, binary little- and big-endian): a mesh's vertices and
// faces, or a point cloud's vertices, validated as it reads.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>

#include "gmm_mcl/common/binary_scalar.h"
#include "gmm_mcl/sim/mesh.h"

namespace gmm_mcl {
namespace sim {
namespace {

using PlyType = ScalarType;

bool parseType(const std::string& s, PlyType* t) {
  static const struct {
    const char* name;
    PlyType type;
  } kNames[] = {{"char", PlyType::kI8},    {"int8", PlyType::kI8},     {"uchar", PlyType::kU8},
                {"uint8", PlyType::kU8},   {"short", PlyType::kI16},   {"int16", PlyType::kI16},
                {"ushort", PlyType::kU16}, {"uint16", PlyType::kU16},  {"int", PlyType::kI32},
                {"int32", PlyType::kI32},  {"uint", PlyType::kU32},    {"uint32", PlyType::kU32},
                {"float", PlyType::kF32},  {"float32", PlyType::kF32}, {"double", PlyType::kF64},
                {"float64", PlyType::kF64}};
  for (const auto& n : kNames) {
    if (s == n.name) {
      *t = n.type;
      return true;
    }
  }
  return false;
}

struct Property {
  std::string name;
  bool is_list = false;
  PlyType count_type = PlyType::kU8;
  PlyType type = PlyType::kF32;
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;
};

enum class Format { kAscii, kBinaryLittle, kBinaryBig };

// Reads values of the body one by one, in either encoding, with bounds checks.
class BodyReader {
 public:
  BodyReader(const std::string& path, const std::string& data, size_t pos, Format format)
      : path_(path), data_(data), pos_(pos), format_(format) {}

  [[noreturn]] void fail(const std::string& what) const { throw MeshError(path_ + ": " + what); }

  double read(PlyType t, const char* what) {
    if (format_ == Format::kAscii) return readAscii(t, what);
    const size_t n = scalarSize(t);
    if (data_.size() - pos_ < n) fail(std::string("truncated binary data while reading ") + what);
    const double v = decodeScalar(data_.data() + pos_, t, format_ == Format::kBinaryBig);
    pos_ += n;
    return v;
  }

  // Skips n values of type t (binary: one bounds check).
  void skip(PlyType t, uint64_t n, const char* what) {
    if (format_ != Format::kAscii) {
      const uint64_t bytes = n * scalarSize(t);
      if (data_.size() - pos_ < bytes)
        fail(std::string("truncated binary data while reading ") + what);
      pos_ += bytes;
      return;
    }
    for (uint64_t i = 0; i < n; ++i) readAscii(t, what);
  }

  size_t remaining() const { return data_.size() - pos_; }

 private:
  double readAscii(PlyType t, const char* what) {
    while (pos_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[pos_]))) ++pos_;
    if (pos_ >= data_.size()) fail(std::string("truncated ascii data while reading ") + what);
    size_t end = pos_;
    while (end < data_.size() && !std::isspace(static_cast<unsigned char>(data_[end]))) ++end;
    const std::string tok = data_.substr(pos_, end - pos_);
    pos_ = end;
    char* stop = nullptr;
    const double v = std::strtod(tok.c_str(), &stop);
    if (stop == tok.c_str() || *stop != '\0') {
      fail(std::string("bad number '") + tok + "' while reading " + what);
    }
    if (isIntegerScalar(t) && v != std::floor(v)) {
      fail(std::string("non-integer '") + tok + "' for an integer property while reading " + what);
    }
    return v;
  }

  const std::string& path_;
  const std::string& data_;
  size_t pos_;
  Format format_;
};

constexpr uint64_t kMaxElements = 1ull << 28;  // 268 M: far beyond any mesh this tool renders

struct Header {
  Format format = Format::kAscii;
  std::vector<Element> elements;
  size_t body_pos = 0;  // the first byte after end_header
};

// The next line starting at *pos (without the newline); false at the end.
bool nextLine(const std::string& data, size_t* pos, std::string* line) {
  if (*pos >= data.size()) return false;
  size_t end = data.find('\n', *pos);
  if (end == std::string::npos) end = data.size();
  *line = data.substr(*pos, end - *pos);
  if (!line->empty() && line->back() == '\r') line->pop_back();
  *pos = end + 1 > data.size() ? data.size() : end + 1;
  return true;
}

Property parseProperty(const std::vector<std::string>& t, const std::string& line,
                       const std::function<void(const std::string&)>& fail) {
  Property p;
  if (t.size() == 5 && t[1] == "list") {
    p.is_list = true;
    if (!parseType(t[2], &p.count_type) || !parseType(t[3], &p.type)) {
      fail("unknown type in '" + line + "'");
    }
    if (!isIntegerScalar(p.count_type)) fail("list count type must be an integer: '" + line + "'");
    p.name = t[4];
  } else if (t.size() == 3) {
    if (!parseType(t[1], &p.type)) fail("unknown type in '" + line + "'");
    p.name = t[2];
  } else {
    fail("bad property line '" + line + "'");
  }
  return p;
}

Header readHeader(const std::string& path, const std::string& data) {
  const std::function<void(const std::string&)> fail = [&](const std::string& what) {
    throw MeshError(path + ": " + what);
  };
  Header h;
  std::string line;
  if (!nextLine(data, &h.body_pos, &line) || line != "ply") {
    fail("not a PLY file (first line is not 'ply')");
  }
  bool have_format = false, ended = false;
  while (nextLine(data, &h.body_pos, &line)) {
    const std::vector<std::string> t = splitWords(line);
    if (t.empty() || t[0] == "comment" || t[0] == "obj_info") continue;
    if (t[0] == "end_header") {
      ended = true;
      break;
    }
    if (t[0] == "format") {
      if (t.size() != 3) fail("bad format line '" + line + "'");
      if (t[1] == "ascii")
        h.format = Format::kAscii;
      else if (t[1] == "binary_little_endian")
        h.format = Format::kBinaryLittle;
      else if (t[1] == "binary_big_endian")
        h.format = Format::kBinaryBig;
      else
        fail("unknown format '" + t[1] + "'");
      have_format = true;
    } else if (t[0] == "element") {
      if (t.size() != 3) fail("bad element line '" + line + "'");
      char* stop = nullptr;
      const unsigned long long n = std::strtoull(t[2].c_str(), &stop, 10);
      if (*stop != '\0' || t[2][0] == '-') fail("bad element count in '" + line + "'");
      if (n > kMaxElements) fail("element count " + t[2] + " is implausibly large");
      h.elements.push_back(Element{t[1], n, {}});
    } else if (t[0] == "property") {
      if (h.elements.empty()) fail("property before any element: '" + line + "'");
      h.elements.back().properties.push_back(parseProperty(t, line, fail));
    } else {
      fail("unknown header line '" + line + "'");
    }
  }
  if (!ended) fail("header has no end_header");
  if (!have_format) fail("header has no format line");
  return h;
}

// The vertex element: x, y, z of each vertex (other properties skipped); the first vertex with
// a non-finite or huge coordinate is noted.
void readVertices(const Element& e, Format format, BodyReader* body, PlyContents* out) {
  int ix = -1, iy = -1, iz = -1;
  for (size_t i = 0; i < e.properties.size(); ++i) {
    const Property& p = e.properties[i];
    if (p.is_list) continue;
    if (p.name == "x") ix = static_cast<int>(i);
    if (p.name == "y") iy = static_cast<int>(i);
    if (p.name == "z") iz = static_cast<int>(i);
  }
  if (ix < 0 || iy < 0 || iz < 0) body->fail("vertex element has no x, y, z properties");
  if (format != Format::kAscii) {
    size_t row = 0;
    bool fixed = true;
    for (const Property& p : e.properties) {
      fixed = fixed && !p.is_list;
      row += scalarSize(p.type);
    }
    if (fixed && body->remaining() / row < e.count) {
      body->fail("truncated: " + std::to_string(e.count) + " vertices declared, data for " +
                 std::to_string(body->remaining() / row));
    }
  }
  std::vector<Eigen::Vector3f>& vertices = out->mesh.vertices_m;
  vertices.resize(e.count);
  for (uint64_t n = 0; n < e.count; ++n) {
    double xyz[3] = {0, 0, 0};
    for (size_t i = 0; i < e.properties.size(); ++i) {
      const Property& p = e.properties[i];
      if (p.is_list) {
        const double c = body->read(p.count_type, "a vertex list count");
        if (c < 0) body->fail("negative list count in vertex " + std::to_string(n));
        body->skip(p.type, static_cast<uint64_t>(c), "a vertex list");
        continue;
      }
      const double v = body->read(p.type, "vertices");
      if (static_cast<int>(i) == ix) xyz[0] = v;
      if (static_cast<int>(i) == iy) xyz[1] = v;
      if (static_cast<int>(i) == iz) xyz[2] = v;
    }
    for (double c : xyz) {
      if ((!std::isfinite(c) || std::abs(c) > 1e9) && out->first_bad_vertex < 0) {
        out->first_bad_vertex = static_cast<long long>(n);
      }
    }
    vertices[n] = Eigen::Vector3f(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]),
                                  static_cast<float>(xyz[2]));
  }
}

// The face element: each polygon's vertex_indices (3 to 1000, in range), fan-triangulated.
void readFaces(const Element& e, bool have_vertices, BodyReader* body, PlyContents* out) {
  int il = -1;
  for (size_t i = 0; i < e.properties.size(); ++i) {
    const Property& p = e.properties[i];
    if (p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
      il = static_cast<int>(i);
    }
  }
  if (il < 0) body->fail("face element has no vertex_indices list");
  if (!have_vertices) body->fail("face element comes before the vertex element");
  if (!isIntegerScalar(e.properties[il].type)) body->fail("vertex_indices must be integers");
  Mesh& mesh = out->mesh;
  mesh.triangles.reserve(e.count);
  std::vector<uint32_t> poly;
  for (uint64_t n = 0; n < e.count; ++n) {
    for (size_t i = 0; i < e.properties.size(); ++i) {
      const Property& p = e.properties[i];
      if (!p.is_list) {
        body->skip(p.type, 1, "faces");
        continue;
      }
      const double c = body->read(p.count_type, "a face vertex count");
      if (static_cast<int>(i) != il) {
        if (c < 0) body->fail("negative list count in face " + std::to_string(n));
        body->skip(p.type, static_cast<uint64_t>(c), "a face list");
        continue;
      }
      if (c < 3 || c > 1000) {
        body->fail("face " + std::to_string(n) + " has " +
                   std::to_string(static_cast<long long>(c)) + " vertices (expected 3 to 1000)");
      }
      poly.clear();
      for (int k = 0; k < static_cast<int>(c); ++k) {
        const double idx = body->read(p.type, "face vertex indices");
        if (idx < 0 || idx >= static_cast<double>(mesh.vertices_m.size())) {
          body->fail("face " + std::to_string(n) + " has vertex index " +
                     std::to_string(static_cast<long long>(idx)) + " (mesh has " +
                     std::to_string(mesh.vertices_m.size()) + " vertices)");
        }
        poly.push_back(static_cast<uint32_t>(idx));
      }
      for (size_t k = 1; k + 1 < poly.size(); ++k) {
        mesh.triangles.push_back({poly[0], poly[k], poly[k + 1]});
      }
    }
  }
}

// Any other element: read past.
void skipElement(const Element& e, BodyReader* body) {
  for (uint64_t n = 0; n < e.count; ++n) {
    for (const Property& p : e.properties) {
      if (p.is_list) {
        const double c = body->read(p.count_type, "a list count");
        if (c < 0) body->fail("negative list count in element '" + e.name + "'");
        body->skip(p.type, static_cast<uint64_t>(c), e.name.c_str());
      } else {
        body->skip(p.type, 1, e.name.c_str());
      }
    }
  }
}

}  // namespace

PlyContents readPlyFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw MeshError(path + ": cannot open file");
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw MeshError(path + ": read error");
  const Header header = readHeader(path, data);
  PlyContents out;
  bool have_vertices = false;
  BodyReader body(path, data, header.body_pos, header.format);
  for (const Element& e : header.elements) {
    if (e.name == "vertex") {
      readVertices(e, header.format, &body, &out);
      have_vertices = true;
    } else if (e.name == "face") {
      readFaces(e, have_vertices, &body, &out);
      out.has_faces = true;
    } else {
      skipElement(e, &body);
    }
  }
  if (!have_vertices) body.fail("no vertex element");
  return out;
}

}  // namespace sim
}  // namespace gmm_mcl
