// gmm_mcl_fit: point cloud or mesh -> GMM map file (see docs/map_builder.md).
#include <omp.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/fit/cloud_filter.h"
#include "gmm_mcl/fit/em_fitter.h"
#include "gmm_mcl/fit/fit_error.h"
#include "gmm_mcl/fit/map_inspect.h"
#include "gmm_mcl/fit/point_cloud_io.h"
#include "gmm_mcl/fit/seven_scenes_cloud.h"
#include "gmm_mcl/map/gmm_map_io.h"

namespace gmm_mcl {
namespace {

const char* kUsage =
    "usage: gmm_mcl_fit INPUT -o MAP [options]\n"
    "       gmm_mcl_fit --7scenes DATA_DIR -o MAP [options]\n"
    "       gmm_mcl_fit --import MAP.csv -o MAP          (a map made elsewhere, e.g. "
    "scikit-learn)\n"
    "\n"
    "INPUT is a point cloud (.pcd ascii/binary/binary_compressed, .ply vertices, .xyz/.txt) or a\n"
    "PLY triangle mesh (faces present: points are sampled area-uniformly on its surface).\n"
    "\n"
    "output:\n"
    "  -o, --output PATH        map file to write (gmm_mcl map format)\n"
    "  --save-cloud PATH        also write the prepared cloud (.pcd binary or .xyz)\n"
    "  --stats-json PATH        write fit statistics (times, iterations, log-likelihood) as JSON\n"
    "  -q, --quiet              no progress or summary (errors only)\n"
    "EM:\n"
    "  -m, --components M       mixture components (1000)\n"
    "  --max-iter N             EM iteration cap (100)\n"
    "  --tol T                  stop when the mean log-likelihood per point changes < T (1e-3)\n"
    "  --reg-covar V            added to covariance diagonals, m^2 (1e-6, as scikit-learn)\n"
    "  --init kmeans|kmeans++   k-means++ seeding with/without Lloyd refinement (kmeans)\n"
    "  --kmeans-iter N          Lloyd iterations for --init kmeans (10)\n"
    "  --init-means FILE        start from these M means (.xyz/.pcd), as scikit-learn means_init\n"
    "  --seed S                 random seed (1); same seed, same map\n"
    "  --prune-sigma S          E-step skips components beyond S sigma (6); 0 = exact\n"
    "  --cell-size M            pruning grid cell, m (automatic)\n"
    "  --threads N              OpenMP threads (OMP_NUM_THREADS or all cores)\n"
    "cloud preparation (in this order):\n"
    "  --crop-box X0 Y0 Z0 X1 Y1 Z1   keep points inside the box (m)\n"
    "  --crop-range MIN MAX     keep MIN <= |p - centre| <= MAX (MAX 0 = no limit)\n"
    "  --range-centre X Y Z     centre for --crop-range (origin)\n"
    "  --voxel M                voxel-grid centroids at M metres (off)\n"
    "  --mesh-samples N         points sampled on a mesh (1000000)\n"
    "  --use-vertices           for a PLY mesh, fit its vertices instead of sampling faces\n"
    "import:\n"
    "  --import FILE.csv        a mixture as CSV, one component per row, header naming weight,\n"
    "                           mean_x_m, mean_y_m, mean_z_m, cov_xx_m2 .. cov_zz_m2 "
    "(gmm_mcl_inspect\n"
    "                           --csv writes one; scripts/sklearn_to_gmm_csv.py converts a\n"
    "                           scikit-learn GaussianMixture); validated and written, no fitting\n"
    "7-Scenes (DESIGN.md accuracy protocol):\n"
    "  --7scenes DIR            stitch DIR/frame-NNNNNN.depth.png with frame-NNNNNN.pose.txt\n"
    "  --first F --last L --step S    frames F, F+S, ..., <= L (0, 990, 10)\n"
    "  --min-depth M --max-depth M    keep depth in (min, max] (0.1, 4.0); voxel default 0.02\n";

[[noreturn]] void usageError(const std::string& what) {
  std::cerr << "gmm_mcl_fit: " << what << "\n\n" << kUsage;
  std::exit(2);
}

std::string jsonNumber(double v) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream o;
  o.precision(10);
  o << v;
  return o.str();
}

struct Options {
  std::string input, output, save_cloud, stats_json, init_means_path, seven_dir, import_path;
  bool quiet = false, use_vertices = false, voxel_set = false;
  long mesh_samples = 1000000;
  int threads = 0;
  EmParams em;
  CloudFilterParams filter;
  SevenScenesCloudParams seven;
};

// The command line, checked (a usage error exits with status 2).
Options parseOptions(int argc, char** argv) {
  Options o;
  std::string init = "kmeans";
  std::vector<double> crop_box, crop_range, range_centre;
  EmParams& em = o.em;
  cli::CommandLine cl("gmm_mcl_fit", kUsage);
  // clang-format off
  cl.flags({{"input", &o.input}, {"import", &o.import_path}, {"output,o", &o.output},
            {"save-cloud", &o.save_cloud}, {"stats-json", &o.stats_json}, {"quiet,q", &o.quiet},
            {"components,m", &em.components}, {"max-iter", &em.max_iterations},
            {"tol", &em.tolerance}, {"reg-covar", &em.reg_covar_m2}, {"init", &init},
            {"kmeans-iter", &em.kmeans_iterations}, {"init-means", &o.init_means_path},
            {"seed", &em.seed}, {"prune-sigma", &em.prune_sigma}, {"cell-size", &em.cell_size_m},
            {"threads", &o.threads}, {"voxel", &o.filter.voxel_m},
            {"mesh-samples", &o.mesh_samples}, {"use-vertices", &o.use_vertices},
            {"7scenes", &o.seven_dir}, {"first", &o.seven.first_frame},
            {"last", &o.seven.last_frame}, {"step", &o.seven.frame_step},
            {"min-depth", &o.seven.min_depth_m}, {"max-depth", &o.seven.max_depth_m}});
  // clang-format on
  cl.addNumbers("crop-box", 6, &crop_box);
  cl.addNumbers("crop-range", 2, &crop_range);
  cl.addNumbers("range-centre", 3, &range_centre);
  cl.alias("range-center", "range-centre");
  cl.positional("input");
  cl.parse(argc, argv);
  o.voxel_set = cl.given("voxel");
  if (init == "kmeans")
    em.init = EmInit::kKMeans;
  else if (init == "kmeans++" || init == "k-means++")
    em.init = EmInit::kKMeansPlusPlus;
  else
    usageError("--init must be kmeans or kmeans++");
  if (o.mesh_samples < 1) usageError("--mesh-samples must be >= 1");
  CloudFilterParams& filter = o.filter;
  if (!crop_box.empty()) {
    filter.use_box = true;
    for (int k = 0; k < 3; ++k) filter.box_min_m[k] = static_cast<float>(crop_box[k]);
    for (int k = 0; k < 3; ++k) filter.box_max_m[k] = static_cast<float>(crop_box[3 + k]);
  }
  if (!crop_range.empty()) {
    filter.min_range_m = static_cast<float>(crop_range[0]);
    filter.max_range_m = static_cast<float>(crop_range[1]);
  }
  for (size_t k = 0; k < range_centre.size(); ++k) {
    filter.range_centre_m[k] = static_cast<float>(range_centre[k]);
  }
  return o;
}

// --import: a CSV mixture validated and written.
int importMap(const Options& o) {
  if (!o.input.empty() || !o.seven_dir.empty()) usageError("--import takes no INPUT or --7scenes");
  if (o.output.empty()) usageError("no output: give -o MAP");
  const GmmMap map = readMapCsv(o.import_path);
  saveMap(map, o.output);
  loadMap(o.output);  // read back: the file validates as every consumer will see it
  if (!o.quiet) {
    std::cerr << o.import_path << ": " << map.size() << " components -> " << o.output << "\n";
  }
  return 0;
}

// The input's points: the stitched 7-Scenes frames, a mesh's surface samples or a file's points.
PointCloud loadCloud(Options* o) {
  PointCloud cloud;
  if (!o->seven_dir.empty()) {
    SevenScenesCloudParams& seven = o->seven;
    if (o->voxel_set) seven.voxel_m = o->filter.voxel_m;
    o->filter.voxel_m = 0.f;  // downsampled while stitching
    SevenScenesCloudStats st;
    cloud = buildSevenScenesCloud(o->seven_dir, seven, &st);
    if (!o->quiet) {
      std::cerr << "7-Scenes: " << st.frames << " frames, " << st.points_back_projected
                << " points in (" << seven.min_depth_m << ", " << seven.max_depth_m << "] m -> "
                << st.voxels << " voxels of " << seven.voxel_m << " m\n";
    }
    return cloud;
  }
  CloudFile file = readCloudFile(o->input);
  if (file.hasFaces() && !o->use_vertices) {
    cloud = sampleMeshSurface(file.mesh, o->mesh_samples, o->em.seed);
    if (!o->quiet) {
      std::cerr << o->input << ": mesh with " << file.mesh.vertices_m.size() << " vertices, "
                << file.mesh.triangles.size() << " triangles -> " << cloud.size()
                << " surface samples\n";
    }
  } else {
    cloud = std::move(file.points);
    if (!o->quiet) std::cerr << o->input << ": " << cloud.size() << " points\n";
  }
  return cloud;
}

// The cloud filtered (crops, voxel grid) and, with --save-cloud, written.
PointCloud prepareCloud(const PointCloud& input, const Options& o) {
  CloudFilterStats fs;
  PointCloud cloud = filterCloud(input, o.filter, &fs);
  if (!o.quiet && (fs.non_finite || fs.cropped || o.filter.voxel_m > 0.f)) {
    std::cerr << "prepared cloud: " << fs.output << " points (dropped " << fs.non_finite
              << " NaN/Inf, " << fs.cropped << " cropped";
    if (o.filter.voxel_m > 0.f) std::cerr << "; voxel " << o.filter.voxel_m << " m";
    std::cerr << ")\n";
  }
  if (cloud.empty())
    throw FitError((o.input.empty() ? o.seven_dir : o.input) + ": no usable points");
  const std::string& save_cloud = o.save_cloud;
  if (!save_cloud.empty()) {
    if (save_cloud.size() > 4 && save_cloud.substr(save_cloud.size() - 4) == ".pcd") {
      writePcd(cloud, save_cloud);
    } else {
      writeXyz(cloud, save_cloud);
    }
    if (!o.quiet) std::cerr << "wrote cloud " << save_cloud << "\n";
  }
  return cloud;
}

void writeStatsJson(const std::string& path, size_t points, const GmmMap& map, const EmResult& fit,
                    size_t bytes, const EmParams& em) {
  std::ofstream js(path);
  js << "{\"points\": " << points << ", \"components\": " << map.size()
     << ", \"iterations\": " << fit.iterations
     << ", \"converged\": " << (fit.converged ? "true" : "false")
     << ", \"final_mean_log_likelihood\": " << jsonNumber(fit.final_mean_log_likelihood)
     << ", \"init_s\": " << jsonNumber(fit.init_s) << ", \"total_s\": " << jsonNumber(fit.total_s)
     << ", \"file_bytes\": " << bytes << ", \"reg_covar_m2\": " << jsonNumber(em.reg_covar_m2)
     << ", \"threads\": " << omp_get_max_threads() << ", \"history\": [";
  for (size_t i = 0; i < fit.history.size(); ++i) {
    const EmIteration& h = fit.history[i];
    js << (i ? ", " : "") << "{\"iteration\": " << h.iteration
       << ", \"mean_log_likelihood\": " << jsonNumber(h.mean_log_likelihood)
       << ", \"elapsed_s\": " << jsonNumber(h.elapsed_s)
       << ", \"mean_candidates\": " << jsonNumber(h.mean_candidates) << "}";
  }
  js << "]}\n";
  if (!js) throw FitError(path + ": write failed");
}

// EM on the cloud (--init-means read here), the map written and read back, the summary.
void fitAndWrite(const PointCloud& cloud, Options* o, bool tty) {
  EmParams& em = o->em;
  if (!o->init_means_path.empty()) {
    const CloudFile means = readCloudFile(o->init_means_path);
    em.init = EmInit::kGivenMeans;
    em.initial_means_m.clear();
    for (const auto& p : means.points) em.initial_means_m.push_back(p.cast<double>());
    if (em.initial_means_m.size() != static_cast<size_t>(em.components)) {
      throw FitError(o->init_means_path + ": has " + std::to_string(em.initial_means_m.size()) +
                     " means but --components is " + std::to_string(em.components));
    }
  }
  const bool quiet = o->quiet;
  if (!quiet) {
    std::cerr << "EM: M=" << em.components << ", " << cloud.size() << " points, tol "
              << em.tolerance << ", max " << em.max_iterations << " iterations, reg_covar "
              << em.reg_covar_m2 << " m^2, prune " << em.prune_sigma << " sigma, "
              << omp_get_max_threads() << " threads, seed " << em.seed << "\n";
  }
  EmProgress progress;
  if (!quiet) {
    progress = [&](const EmIteration& it) {
      char line[160];
      std::snprintf(line, sizeof(line), "iter %4d/%d  mean log-lik %12.6f  %8.2f s  %6.1f comps/pt",
                    it.iteration, em.max_iterations, it.mean_log_likelihood, it.elapsed_s,
                    it.mean_candidates);
      if (tty) {
        std::cerr << "\r" << line << std::flush;
      } else {
        std::cerr << line << "\n";
      }
    };
  }
  const EmResult fit = fitGmm(cloud, em, progress);
  if (!quiet && tty) std::cerr << "\n";
  int repaired = 0;
  const GmmMap map = makeStorableMap(fit.components, em.reg_covar_m2, o->output, &repaired);
  saveMap(map, o->output);
  loadMap(o->output);  // read back: the file validates as every consumer will see it
  const size_t bytes = encodeMap(map).size();
  if (!quiet) {
    std::cerr << (fit.converged ? "converged" : "stopped at the iteration cap") << " after "
              << fit.iterations << " iterations; final mean log-lik "
              << fit.final_mean_log_likelihood << "; init " << fit.init_s << " s, total "
              << fit.total_s << " s\n";
    if (fit.regularised_components || repaired || fit.empty_components) {
      std::cerr << "note: " << fit.regularised_components
                << " covariances needed extra diagonal loading, " << repaired
                << " were repaired for float32 storage, " << fit.empty_components
                << " components are (numerically) empty\n";
    }
    std::cerr << "wrote " << o->output << " (" << map.size() << " components, " << bytes
              << " bytes)\n";
  }
  if (!o->stats_json.empty()) writeStatsJson(o->stats_json, cloud.size(), map, fit, bytes, em);
}

int run(int argc, char** argv) {
  Options o = parseOptions(argc, argv);
  if (!o.import_path.empty()) return importMap(o);
  if (o.input.empty() == o.seven_dir.empty()) usageError("give one INPUT file or --7scenes DIR");
  if (o.output.empty() && o.save_cloud.empty()) {
    usageError("no output: give -o MAP (or --save-cloud)");
  }
  if (o.threads < 0) usageError("--threads must be >= 1");
  if (o.threads > 0) omp_set_num_threads(o.threads);
  const bool tty = isatty(fileno(stderr)) != 0;
  try {
    const PointCloud cloud = prepareCloud(loadCloud(&o), o);
    if (o.output.empty()) return 0;
    fitAndWrite(cloud, &o, tty);
  } catch (const std::exception&) {
    if (tty && !o.quiet) std::cerr << "\n";  // end the progress line before the error
    throw;
  }
  return 0;
}

}  // namespace
}  // namespace gmm_mcl

int main(int argc, char** argv) {
  return gmm_mcl::cli::reportErrors("gmm_mcl_fit", [&] { return gmm_mcl::run(argc, argv); });
}
