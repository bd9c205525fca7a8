#include "gmm_mcl/fit/map_inspect.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <vector>

#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/sim/mesh.h"

namespace gmm_mcl {
namespace {

constexpr double kPi = 3.14159265358979323846;

Stat statOf(std::vector<double> v) {
  Stat s;
  if (v.empty()) return s;
  for (double x : v) s.sum += x;
  std::sort(v.begin(), v.end());
  s.min = v.front();
  s.max = v.back();
  s.median = v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  return s;
}

// Eigen-decomposition with eigenvalues largest first.
void principalAxes(const Eigen::Matrix3d& cov, Eigen::Vector3d* eval, Eigen::Matrix3d* evec) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  for (int i = 0; i < 3; ++i) {
    (*eval)[i] = std::max(es.eigenvalues()[2 - i], 0.0);
    evec->col(i) = es.eigenvectors().col(2 - i);
  }
}

}  // namespace

MapSummary summarizeMap(const GmmMap& map) {
  MapSummary s;
  s.components = map.size();
  if (map.empty()) return s;
  std::vector<double> w, vol, smin, smax, cond;
  s.mean_min_m = map.minBound();
  s.mean_max_m = map.maxBound();
  s.extent_min_m.setConstant(std::numeric_limits<double>::infinity());
  s.extent_max_m.setConstant(-std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < map.size(); ++i) {
    const GaussianComponent& c = map.components()[i];
    w.push_back(c.weight);
    vol.push_back(4.0 / 3.0 * kPi * 27.0 * std::sqrt(std::max(c.cov_m2.determinant(), 0.0)));
    Eigen::Vector3d ev;
    Eigen::Matrix3d axes;
    principalAxes(c.cov_m2, &ev, &axes);
    smax.push_back(std::sqrt(ev[0]));
    smin.push_back(std::sqrt(ev[2]));
    cond.push_back(ev[2] > 0.0 ? ev[0] / ev[2] : std::numeric_limits<double>::infinity());
    s.extent_min_m = s.extent_min_m.cwiseMin(c.mean_m - map.threeSigmaHalfExtent(i));
    s.extent_max_m = s.extent_max_m.cwiseMax(c.mean_m + map.threeSigmaHalfExtent(i));
  }
  s.weight = statOf(w);
  s.volume_m3 = statOf(vol);
  s.sigma_min_m = statOf(smin);
  s.sigma_max_m = statOf(smax);
  s.condition = statOf(cond);
  return s;
}

void printMapSummary(const MapSummary& s, std::ostream& out, size_t file_bytes) {
  const std::ios::fmtflags flags = out.flags();
  const std::streamsize prec = out.precision();
  auto vec = [](const Eigen::Vector3d& v) {
    std::ostringstream o;
    o << std::fixed << std::setprecision(3) << "(" << v.x() << ", " << v.y() << ", " << v.z()
      << ")";
    return o.str();
  };
  auto stat = [](const Stat& st) {
    std::ostringstream o;
    o << std::setprecision(4) << "min " << st.min << "  median " << st.median << "  max " << st.max;
    return o.str();
  };
  out << "components        " << s.components << "\n";
  if (file_bytes > 0) out << "file size         " << file_bytes << " bytes\n";
  out << "means within      " << vec(s.mean_min_m) << " .. " << vec(s.mean_max_m) << " m\n";
  out << "3-sigma boxes     " << vec(s.extent_min_m) << " .. " << vec(s.extent_max_m) << " m\n";
  out << "weight            " << stat(s.weight) << "  sum " << std::setprecision(7) << s.weight.sum
      << "\n";
  out << "3-sigma volume    " << stat(s.volume_m3) << "  total " << std::setprecision(4)
      << s.volume_m3.sum << " m^3\n";
  out << "smallest sigma    " << stat(s.sigma_min_m) << " m\n";
  out << "largest sigma     " << stat(s.sigma_max_m) << " m\n";
  out << "condition number  " << stat(s.condition) << "\n";
  out.flags(flags);
  out.precision(prec);
}

std::string EllipsoidExportParams::validate() const {
  std::ostringstream err;
  if (!(sigma > 0.0) || !std::isfinite(sigma)) err << "sigma must be finite and > 0; ";
  if (rings < 2) err << "rings must be >= 2; ";
  if (segments < 3) err << "segments must be >= 3; ";
  std::string s = err.str();
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

void writeEllipsoidsPly(const GmmMap& map, const std::string& path,
                        const EllipsoidExportParams& params) {
  const std::string fault = params.validate();
  if (!fault.empty()) throw FitError("ellipsoid export parameters: " + fault);
  const int rings = params.rings, segs = params.segments;
  double wmax = 0.0;
  for (const auto& c : map.components()) wmax = std::max(wmax, c.weight);
  // Unit-sphere vertices: the poles then rings x segments.
  std::vector<Eigen::Vector3d> unit;
  unit.emplace_back(0, 0, 1);
  for (int r = 1; r < rings; ++r) {
    const double th = kPi * r / rings;
    for (int s = 0; s < segs; ++s) {
      const double ph = 2.0 * kPi * s / segs;
      unit.emplace_back(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
    }
  }
  unit.emplace_back(0, 0, -1);
  sim::Mesh mesh;
  std::vector<sim::VertexColour> colours;
  for (const auto& c : map.components()) {
    Eigen::Vector3d ev;
    Eigen::Matrix3d axes;
    principalAxes(c.cov_m2, &ev, &axes);
    const Eigen::Matrix3d A = axes * (params.sigma * ev.cwiseSqrt()).asDiagonal();
    const double t = std::sqrt(c.weight / wmax);
    const sim::VertexColour rgb = {static_cast<uint8_t>(255 * t), static_cast<uint8_t>(80),
                                   static_cast<uint8_t>(255 * (1.0 - t))};
    for (const auto& u : unit) {
      mesh.vertices_m.push_back((c.mean_m + A * u).cast<float>());
      colours.push_back(rgb);
    }
  }
  const uint32_t verts_per = static_cast<uint32_t>(unit.size()), south = verts_per - 1;
  for (uint32_t i = 0; i < map.size(); ++i) {
    const uint32_t base = i * verts_per;
    auto tri = [&](uint32_t a, uint32_t b, uint32_t c) {
      mesh.triangles.push_back({base + a, base + b, base + c});
    };
    auto ring = [&](int r, int s) { return 1 + static_cast<uint32_t>(r * segs + (s % segs)); };
    for (int s = 0; s < segs; ++s) tri(0, ring(0, s), ring(0, s + 1));
    for (int r = 0; r + 1 < rings - 1; ++r) {
      for (int s = 0; s < segs; ++s) {
        tri(ring(r, s), ring(r + 1, s), ring(r + 1, s + 1));
        tri(ring(r, s), ring(r + 1, s + 1), ring(r, s + 1));
      }
    }
    for (int s = 0; s < segs; ++s) tri(ring(rings - 2, s), south, ring(rings - 2, s + 1));
  }
  std::ostringstream comment;
  comment << "gmm_mcl map, " << params.sigma << "-sigma ellipsoids, " << map.size()
          << " components";
  try {
    sim::savePlyMesh(mesh, path, colours, comment.str());
  } catch (const sim::MeshError& e) {
    throw FitError(e.what());
  }
}

void writeEllipsoidsCsv(const GmmMap& map, const std::string& path,
                        const EllipsoidExportParams& params) {
  const std::string fault = params.validate();
  if (!fault.empty()) throw FitError("ellipsoid export parameters: " + fault);
  std::ofstream out(path, std::ios::trunc);
  if (!out) throw FitError(path + ": cannot open for writing: " + std::strerror(errno));
  out << "index,weight,mean_x_m,mean_y_m,mean_z_m,semi_axis_1_m,semi_axis_2_m,semi_axis_3_m,"
         "axis_1_x,axis_1_y,axis_1_z,axis_2_x,axis_2_y,axis_2_z,axis_3_x,axis_3_y,axis_3_z,"
         "cov_xx_m2,cov_xy_m2,cov_xz_m2,cov_yy_m2,cov_yz_m2,cov_zz_m2\n";
  out << std::setprecision(9);
  for (size_t i = 0; i < map.size(); ++i) {
    const GaussianComponent& c = map.components()[i];
    Eigen::Vector3d ev;
    Eigen::Matrix3d axes;
    principalAxes(c.cov_m2, &ev, &axes);
    out << i << ',' << c.weight << ',' << c.mean_m.x() << ',' << c.mean_m.y() << ','
        << c.mean_m.z();
    for (int a = 0; a < 3; ++a) out << ',' << params.sigma * std::sqrt(ev[a]);
    for (int a = 0; a < 3; ++a) {
      for (int k = 0; k < 3; ++k) out << ',' << axes(k, a);
    }
    const Eigen::Matrix3d& s = c.cov_m2;
    for (double v : {s(0, 0), s(0, 1), s(0, 2), s(1, 1), s(1, 2), s(2, 2)}) out << ',' << v;
    out << '\n';
  }
  if (!out) throw FitError(path + ": write failed");
}

GmmMap readMapCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw FitError(path + ": cannot open: " + std::strerror(errno));
  const char* kColumns[10] = {"weight",    "mean_x_m",  "mean_y_m",  "mean_z_m",  "cov_xx_m2",
                              "cov_xy_m2", "cov_xz_m2", "cov_yy_m2", "cov_yz_m2", "cov_zz_m2"};
  auto split = [](const std::string& line) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) {
      const size_t a = cell.find_first_not_of(" \t\r"), b = cell.find_last_not_of(" \t\r");
      cells.push_back(a == std::string::npos ? "" : cell.substr(a, b - a + 1));
    }
    return cells;
  };
  std::string line;
  if (!std::getline(in, line)) throw FitError(path + ": empty file (expected a header row)");
  const std::vector<std::string> header = split(line);
  int col[10];
  for (int k = 0; k < 10; ++k) {
    const auto it = std::find(header.begin(), header.end(), kColumns[k]);
    if (it == header.end()) throw FitError(path + ": header has no column '" + kColumns[k] + "'");
    col[k] = static_cast<int>(it - header.begin());
  }
  std::vector<GaussianComponent> comps;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::vector<std::string> cells = split(line);
    double v[10];
    for (int k = 0; k < 10; ++k) {
      const std::string where = path + ":" + std::to_string(line_no) + ": " + kColumns[k];
      if (col[k] >= static_cast<int>(cells.size())) throw FitError(where + ": missing");
      char* end = nullptr;
      v[k] = std::strtod(cells[col[k]].c_str(), &end);
      if (cells[col[k]].empty() || *end != '\0' || !std::isfinite(v[k])) {
        throw FitError(where + ": '" + cells[col[k]] + "' is not a finite number");
      }
    }
    GaussianComponent c;
    c.weight = v[0];
    c.mean_m = Eigen::Vector3d(v[1], v[2], v[3]);
    c.cov_m2 << v[4], v[5], v[6], v[5], v[7], v[8], v[6], v[8], v[9];
    comps.push_back(c);
  }
  if (comps.empty()) throw FitError(path + ": no components");
  double total = 0.0;
  for (const GaussianComponent& c : comps) total += c.weight;
  if (std::abs(total - 1.0) <= 1e-3 && total > 0.0) {
    for (GaussianComponent& c : comps) c.weight /= total;
  }
  return GmmMap(std::move(comps), path);
}

}  // namespace gmm_mcl
