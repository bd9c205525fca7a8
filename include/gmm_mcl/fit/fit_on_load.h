// A point cloud or mesh given as the map: the GMM fitted when it is loaded, with the map
// builder's EM defaults, and cached beside the input (docs/map_builder.md, "Maps given as point
// clouds"). ROS-free: the nodelet calls loadOrFitMap() with its ~map and ~map_fit_* parameters.
//
// Cache: `<input>.fit-<key>.gmm` in the input's folder, <key> 16 hex digits of a 64-bit FNV-1a
// hash of the input's bytes followed by the fit parameters that change the map (component count,
// seed, the fixed densities below, the procedure's version). A key that matches is loaded
// without reading the cloud; otherwise the map is fitted, written to a temporary file and
// renamed over the cache (atomic), and the input's caches of other keys are removed. A folder
// that cannot be written gives a warning and a map without a cache.
//
// Kept header-only apart from loadOrFitMap (in gmm_mcl_fit), so that the nodelet's options can
// hold FitOnLoadParams where the map builder is not built.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <sstream>
#include <string>

#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {

// Automatic component count: this many per m^2 of surface (the evaluation's maps: the Replica
// office's 101 m^2 with M = 1000; the 81-room building's 8,181 m^2 with M = 100,000).
constexpr double kFitComponentsPerM2 = 10.0;
// A cloud's surface: its occupied voxels of this edge times the edge squared (the fewer of
// two grids offset by half a voxel).
constexpr float kFitSurfaceVoxelM = 0.1f;
constexpr int kFitMinComponents = 10;             // automatic count: at least this
constexpr size_t kFitMinPoints = 100;             // fewer distinct valid points: an error
constexpr size_t kFitMinPointsPerComponent = 10;  // a given count needs this many points each
// At most this many points per component are fitted (a seeded random subset of a denser cloud;
// a mesh gets this many surface samples per component): the Replica script's 250,000 samples
// for M = 1000, rounded up.
constexpr size_t kFitPointsPerComponent = 300;
constexpr double kDefaultFitTimeLimitS = 30.0;

struct FitOnLoadParams {
  int components = 0;  // 0 = from the cloud's surface (kFitComponentsPerM2)
  // A fit estimated to take longer on this machine is refused with a message naming
  // gmm_mcl_fit (build the map offline instead).
  double time_limit_s = kDefaultFitTimeLimitS;
  bool cache = true;  // read and write `<input>.fit-<key>.gmm`
  uint64_t seed = 1;  // the EM's and the subsampling's seed

  // Empty when valid, otherwise every fault found.
  std::string validate() const {
    std::ostringstream err;
    if (components < 0) err << "components must be >= 0 (0 = from the extent); ";
    if (!(time_limit_s > 0.0)) err << "time_limit_s must be > 0; ";
    std::string s = err.str();
    if (s.size() >= 2) s.resize(s.size() - 2);
    return s;
  }
};

// True for the extensions loadOrFitMap fits (.pcd, .ply, .xyz, .txt; any case); every other
// path is read as a map file.
inline bool isCloudMapPath(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return false;
  std::string ext = path.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
  return ext == "pcd" || ext == "ply" || ext == "xyz" || ext == "txt";
}

struct FitOnLoadLog {
  std::function<void(const std::string&)> info;  // progress: at most one line every 2 s
  std::function<void(const std::string&)> warn;  // the cache could not be written or read
};

struct FitOnLoadResult {
  GmmMap map;
  bool fitted = false;      // false: a map file, or the cache
  bool from_cache = false;  // the cache file was loaded
  std::string cache_path;   // the cache file (read or written); empty without one
  bool cache_written = false;
  size_t points_read = 0, non_finite = 0, duplicates = 0, points_fitted = 0;
  size_t triangles = 0;     // a mesh's (its points_read are its vertices, points_fitted samples)
  double surface_m2 = 0.0;  // the surface estimate (clouds) or area (meshes)
  int components = 0;
  bool components_from_extent = false;
  double estimate_s = 0.0;  // the fit's time estimated before it ran
  double seconds = 0.0;     // the whole load (hash, read, fit, cache)
  std::string summary;      // one line for the log
};

// A map file (any path isCloudMapPath rejects) is loaded as loadMap does. A cloud or mesh is
// fitted or taken from its cache (above). Throws FitError or MapError naming the file and the
// fault: unreadable or malformed input, fewer than kFitMinPoints distinct valid points, a given
// component count without kFitMinPointsPerComponent points each, or a fit estimated longer
// than params.time_limit_s (the message names gmm_mcl_fit). NaN/Inf points are dropped and
// counted; duplicated points are kept (counted); a single plane fits (its components flat) and
// the summary says so.
FitOnLoadResult loadOrFitMap(const std::string& path, const FitOnLoadParams& params,
                             const FitOnLoadLog& log = FitOnLoadLog());

// The fit's wall time estimated for `points` points and `components` components with `threads`
// OpenMP threads, from timings of gmm_mcl_fit on a 2-core AMD EPYC (docs/map_builder.md).
double estimateFitSeconds(size_t points, int components, int threads);

}  // namespace gmm_mcl
