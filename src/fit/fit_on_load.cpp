#include "gmm_mcl/fit/fit_on_load.h"

#include <dirent.h>
#include <omp.h>
#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <vector>

#include "gmm_mcl/common/timing.h"
#include "gmm_mcl/fit/block_fitter.h"
#include "gmm_mcl/fit/cloud_filter.h"
#include "gmm_mcl/fit/em_fitter.h"
#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/point_cloud_io.h"
#include "gmm_mcl/map/gmm_map_io.h"

namespace gmm_mcl {
namespace {

// Bump when the procedure changes the map it makes for the same input and parameters: every
// cache made before is then refitted.
constexpr int kFitOnLoadVersion = 1;
constexpr double kProgressLineS = 2.0;
// A cloud whose points lie within this of one plane (RMS) is reported as planar.
constexpr double kPlanarRmsM = 0.005;

constexpr uint64_t kFnvOffset = 0xcbf29ce484222325ull;
constexpr uint64_t kFnvPrime = 0x100000001b3ull;

uint64_t fnv1a(const char* data, size_t size, uint64_t h) {
  for (size_t i = 0; i < size; ++i) {
    h ^= static_cast<uint8_t>(data[i]);
    h *= kFnvPrime;
  }
  return h;
}

// FNV-1a 64 of the file's bytes; throws FitError naming the file when it cannot be read.
uint64_t hashFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FitError(path + ": cannot open: " + std::strerror(errno));
  std::vector<char> buf(1 << 20);
  uint64_t h = kFnvOffset;
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    h = fnv1a(buf.data(), static_cast<size_t>(in.gcount()), h);
  }
  if (in.bad()) throw FitError(path + ": read error");
  return h;
}

std::string hex16(uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

// What the map depends on besides the input's bytes.
std::string fitKeyText(const FitOnLoadParams& p) {
  std::ostringstream s;
  s << "gmm_mcl fit-on-load v" << kFitOnLoadVersion << "; components " << p.components << "; seed "
    << p.seed << "; per m^2 " << kFitComponentsPerM2 << "; voxel " << kFitSurfaceVoxelM
    << "; points per component " << kFitPointsPerComponent << "; min " << kFitMinComponents;
  return s.str();
}

std::string folderOf(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? "." : path.substr(0, slash);
}

std::string baseName(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

// The input's caches other than `keep` (`<input>.fit-<16 hex>.gmm`), removed.
void removeStaleCaches(const std::string& input, const std::string& keep) {
  const std::string folder = folderOf(input);
  const std::string prefix = baseName(input) + ".fit-";
  DIR* dir = opendir(folder.c_str());
  if (!dir) return;
  while (const dirent* e = readdir(dir)) {
    const std::string name = e->d_name;
    if (name.size() != prefix.size() + 16 + 4 || name.compare(0, prefix.size(), prefix) != 0 ||
        name.compare(name.size() - 4, 4, ".gmm") != 0 || name == baseName(keep)) {
      continue;
    }
    std::remove((folder + "/" + name).c_str());
  }
  closedir(dir);
}

bool fileExists(const std::string& path) { return access(path.c_str(), F_OK) == 0; }

std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), s < 10 ? "%.2f s" : "%.0f s", s);
  return buf;
}

// Distinct positions (exact duplicates removed), counted on a sorted copy.
size_t distinctCount(const PointCloud& points) {
  PointCloud sorted = points;
  auto less = [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  };
  std::sort(sorted.begin(), sorted.end(), less);
  return static_cast<size_t>(std::unique(sorted.begin(), sorted.end()) - sorted.begin());
}

// RMS distance of the points from their best-fitting plane (smallest principal axis).
double planeRmsM(const PointCloud& points) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p.cast<double>();
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) {
    const Eigen::Vector3d d = p.cast<double>() - mean;
    cov += d * d.transpose();
  }
  cov /= static_cast<double>(points.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, eig.eigenvalues()[0]));
}

// The surface a cloud covers: its occupied voxels of kFitSurfaceVoxelM times the voxel's face,
// the fewer of two grids offset by half a voxel (a surface lying on one grid's voxel boundary
// occupies two layers of it, and the middle of the other's).
double surfaceM2(const PointCloud& points) {
  const float a = kFitSurfaceVoxelM;
  PointCloud shifted = points;
  for (auto& p : shifted) p.array() += 0.5f * a;
  const size_t voxels =
      std::min(voxelDownsample(points, a).size(), voxelDownsample(shifted, a).size());
  return static_cast<double>(voxels) * a * a;
}

// Lines at most every kProgressLineS (and the first) to log.info.
class ProgressLines {
 public:
  ProgressLines(const FitOnLoadLog& log, const std::string& name) : log_(log), name_(name) {}
  void line(double elapsed_s, const std::string& text, bool always = false) {
    if (!log_.info) return;
    if (!always && last_s_ >= 0 && elapsed_s - last_s_ < kProgressLineS) return;
    last_s_ = elapsed_s;
    log_.info(name_ + ": " + text + ", " + seconds(elapsed_s));
  }

 private:
  const FitOnLoadLog& log_;
  std::string name_;
  double last_s_ = -1.0;
};

// The points to fit: the file's valid points, or a mesh's surface samples. Fills the counts,
// the surface and the component count of *r.
PointCloud prepare(const std::string& path, const FitOnLoadParams& params, FitOnLoadResult* r) {
  CloudFile file = readCloudFile(path);
  PointCloud points;
  if (file.hasFaces()) {
    const std::string fault = file.mesh.check();
    if (!fault.empty()) throw FitError(path + ": bad mesh: " + fault);
    r->points_read = file.mesh.vertices_m.size();
    r->triangles = file.mesh.triangles.size();
    r->surface_m2 = file.mesh.area_m2();
    r->components = params.components;
    if (r->components == 0) {
      r->components_from_extent = true;
      r->components = std::max(kFitMinComponents,
                               static_cast<int>(std::lround(r->surface_m2 * kFitComponentsPerM2)));
    }
    const size_t samples = kFitPointsPerComponent * static_cast<size_t>(r->components);
    points = sampleMeshSurface(file.mesh, samples, params.seed);
    r->duplicates = 0;
    return points;
  }
  r->points_read = file.points.size();
  CloudFilterStats stats;
  points = filterCloud(file.points, CloudFilterParams(), &stats);  // NaN/Inf dropped
  r->non_finite = stats.non_finite;
  const size_t distinct = distinctCount(points);
  r->duplicates = points.size() - distinct;
  if (distinct < kFitMinPoints) {
    std::ostringstream msg;
    msg << path << ": " << distinct << " distinct valid points (" << r->points_read << " read, "
        << r->non_finite << " NaN/Inf dropped, " << r->duplicates
        << " duplicates): too few to fit a map, at least " << kFitMinPoints << " are needed";
    throw FitError(msg.str());
  }
  r->surface_m2 = surfaceM2(points);
  r->components = params.components;
  if (r->components == 0) {
    r->components_from_extent = true;
    const long by_area = std::lround(r->surface_m2 * kFitComponentsPerM2);
    const long by_points = static_cast<long>(distinct / kFitMinPointsPerComponent);
    r->components = static_cast<int>(
        std::max<long>(std::min<long>(kFitMinComponents, by_points), std::min(by_area, by_points)));
  } else if (distinct < kFitMinPointsPerComponent * static_cast<size_t>(r->components)) {
    std::ostringstream msg;
    msg << path << ": " << distinct << " distinct valid points are too few for " << r->components
        << " components (map_fit_components): at least " << kFitMinPointsPerComponent
        << " points per component are needed";
    throw FitError(msg.str());
  }
  const size_t cap = kFitPointsPerComponent * static_cast<size_t>(r->components);
  if (points.size() > cap) {  // a seeded random subset of about `cap` points
    PointCloud kept, rest;
    splitHoldout(points, 1.0 - static_cast<double>(cap) / static_cast<double>(points.size()),
                 params.seed, &kept, &rest);
    points.swap(kept);
  }
  return points;
}

GmmMap fit(const PointCloud& points, int components_wanted, const FitOnLoadParams& params,
           const std::string& path, const FitOnLoadLog& log, std::string* how) {
  ProgressLines progress(log, "fitting " + baseName(path));
  EmParams em;  // the map builder's defaults
  em.components = components_wanted;
  em.seed = params.seed;
  BlockFitParams bp;
  bp.em = em;
  const int blocks = autoBlockCount(points.size(), bp);
  std::vector<GaussianComponent> components;
  std::ostringstream h;
  if (blocks > 1) {
    bp.blocks = blocks;
    BlockFitResult res = fitGmmBlocks(points, bp, [&](const BlockProgress& p) {
      std::ostringstream s;
      if (p.stage == BlockStage::kBlocks) {
        s << "block " << p.blocks_done << " of " << p.blocks_total;
      } else if (p.stage == BlockStage::kReconcile) {
        s << "reconciling iteration " << p.iteration << " (at most " << p.iterations_total
          << "), mean log-likelihood " << p.mean_log_likelihood;
      } else {
        s << "scoring";
      }
      progress.line(p.elapsed_s, s.str());
    });
    components = std::move(res.components);
    h << blocks << " blocks, " << res.reconcile.iterations << " reconciling iterations";
  } else {
    EmResult res = fitGmm(points, em, [&](const EmIteration& it) {
      std::ostringstream s;
      s << "EM iteration " << it.iteration << " (at most " << em.max_iterations
        << "), mean log-likelihood " << it.mean_log_likelihood;
      progress.line(it.elapsed_s, s.str());
    });
    components = std::move(res.components);
    h << (res.converged ? "converged after " : "stopped at the cap of ") << res.iterations
      << " EM iterations";
  }
  *how = h.str();
  return makeStorableMap(components, em.reg_covar_m2, path);
}

// Writes the cache atomically (temporary file, then rename); false with *why on failure.
bool writeCache(const GmmMap& map, const std::string& cache, std::string* why) {
  const std::string tmp = cache + ".tmp" + std::to_string(getpid());
  try {
    saveMap(map, tmp);
  } catch (const std::exception& e) {
    std::remove(tmp.c_str());
    *why = e.what();
    return false;
  }
  if (std::rename(tmp.c_str(), cache.c_str()) != 0) {
    *why = cache + ": " + std::strerror(errno);
    std::remove(tmp.c_str());
    return false;
  }
  return true;
}

}  // namespace

double estimateFitSeconds(size_t points, int components, int threads) {
  // gmm_mcl_fit with 2 threads (docs/map_builder.md): the k-means initialisation 4e-9 to
  // 7e-9 s per point and component (1e-8 here: it runs mostly on one thread, so a loaded
  // machine slows it most), the EM iterations to convergence about 1.1e-5 s per point
  // times sqrt(M / 1000); the block fit (M > 5000 or more than 2 million points) 1.2e-5 s per
  // point. Fewer threads: proportionally slower.
  const double n = static_cast<double>(points), m = static_cast<double>(components);
  BlockFitParams bp;
  bp.em.components = components;
  const double two_threads = autoBlockCount(points, bp) > 1
                                 ? 1.2e-5 * n
                                 : 1e-8 * n * m + 1.1e-5 * n * std::sqrt(m / 1000.0);
  return two_threads * 2.0 / std::max(1, std::min(threads, 2));
}

FitOnLoadResult loadOrFitMap(const std::string& path, const FitOnLoadParams& params,
                             const FitOnLoadLog& log) {
  const Clock::time_point t0 = Clock::now();
  FitOnLoadResult r;
  if (!isCloudMapPath(path)) {
    r.map = loadMap(path);
    r.components = static_cast<int>(r.map.size());
    r.seconds = msSince(t0) * 1e-3;
    r.summary = std::to_string(r.components) + " components from " + path;
    return r;
  }
  const std::string fault = params.validate();
  if (!fault.empty()) throw FitError(path + ": map fit parameters: " + fault);
  if (params.cache) {
    const uint64_t content = hashFile(path);
    const std::string key = fitKeyText(params);
    r.cache_path = path + ".fit-" + hex16(fnv1a(key.data(), key.size(), content)) + ".gmm";
    if (fileExists(r.cache_path)) {
      try {
        r.map = loadMap(r.cache_path);
        r.from_cache = true;
        r.components = static_cast<int>(r.map.size());
        r.seconds = msSince(t0) * 1e-3;
        r.summary = std::to_string(r.components) + " components from " + r.cache_path +
                    " (the cached fit of " + path + ", " + seconds(r.seconds) + ")";
        return r;
      } catch (const std::exception& e) {
        if (log.warn) log.warn(std::string("cache not used, fitting again: ") + e.what());
      }
    }
  }
  const PointCloud points = prepare(path, params, &r);
  r.points_fitted = points.size();
  const int threads = omp_get_max_threads();
  r.estimate_s = estimateFitSeconds(points.size(), r.components, threads);
  std::ostringstream head;
  if (r.triangles) {
    head << path << ": mesh of " << r.points_read << " vertices, " << r.triangles
         << " triangles; surface " << std::lround(r.surface_m2) << " m^2 -> " << r.components;
  } else {
    head << path << ": " << r.points_read << " points";
    if (r.non_finite) head << ", " << r.non_finite << " NaN/Inf dropped";
    if (r.duplicates) head << ", " << r.duplicates << " duplicates (kept)";
    head << "; surface about " << std::lround(r.surface_m2) << " m^2 -> " << r.components;
  }
  head << " components"
       << (r.components_from_extent ? " (from the extent; map_fit_components sets them)" : "")
       << "; fitting " << points.size() << (r.triangles ? " surface samples" : " points")
       << " with " << threads << " threads, about " << seconds(r.estimate_s);
  if (log.info) log.info(head.str());
  if (r.estimate_s > params.time_limit_s) {
    std::ostringstream msg;
    msg << path << ": fitting " << r.components << " components to " << points.size()
        << " points would take about " << seconds(r.estimate_s) << " here, more than map_fit_"
        << "time_limit (" << seconds(params.time_limit_s) << "): build the map offline with "
        << "`gmm_mcl_fit " << path << " -o MAP.gmm -m " << r.components
        << "` and give MAP.gmm as the map (or raise map_fit_time_limit)";
    throw FitError(msg.str());
  }
  std::string how;
  r.map = fit(points, r.components, params, path, log, &how);
  r.fitted = true;
  const double fit_s = msSince(t0) * 1e-3;
  std::ostringstream sum;
  sum << "fitted " << r.map.size() << " components to " << points.size() << " points of " << path
      << " in " << seconds(fit_s) << " (" << how << ")";
  const double plane_rms_m = planeRmsM(points);
  if (plane_rms_m < kPlanarRmsM) {
    sum << "; note: the cloud is a single plane (RMS " << plane_rms_m * 1e3
        << " mm off it): its components are flat, and one plane cannot fix a pose";
  }
  if (params.cache) {
    std::string why;
    r.cache_written = writeCache(r.map, r.cache_path, &why);
    if (r.cache_written) {
      removeStaleCaches(path, r.cache_path);
      sum << "; cached as " << r.cache_path;
    } else if (log.warn) {
      log.warn("the fitted map is not cached (it is fitted again at the next start): " + why);
    }
  }
  r.seconds = msSince(t0) * 1e-3;
  r.summary = sum.str();
  if (log.info) log.info(r.summary);
  return r;
}

}  // namespace gmm_mcl
