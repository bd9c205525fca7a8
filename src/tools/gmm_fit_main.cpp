// gmm_mcl_fit: point cloud or mesh -> GMM map file (see docs/map_builder.md).
#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/common/number_list.h"
#include "gmm_mcl/fit/block_fitter.h"
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
    "  --holdout F              fit on a seeded random 1-F of the points and report the mean\n"
    "                           log-likelihood of the other F (0 = off; e.g. 0.1)\n"
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
    "large maps (EM per spatial block, then EM over all points; docs/map_builder.md):\n"
    "  --blocks auto|off|N      auto: blocks when M > 5000 or more than 2,000,000 points, then\n"
    "                           M / --block-components of them; off: one whole-map EM; N: N "
    "blocks\n"
    "  --block-components K     components per block for the automatic block count (250)\n"
    "  --block-margin M|auto    neighbours' points around each block, m (0); auto: --margin-radii\n"
    "                           times the block's component radius\n"
    "  --margin-radii R         the automatic margin in component radii (3)\n"
    "  --block-iter N           cap on each block's EM iterations (--max-iter)\n"
    "  --reconcile-iter N       cap on the EM iterations over all points after merging the "
    "blocks,\n"
    "                           which stop when converged (--tol) (100; 0 = none)\n"
    "cloud preparation (in this order):\n"
    "  --crop-box X0 Y0 Z0 X1 Y1 Z1   keep points inside the box (m)\n"
    "  --crop-range MIN MAX     keep MIN <= |p - centre| <= MAX (MAX 0 = no limit)\n"
    "  --range-centre X Y Z     centre for --crop-range (origin)\n"
    "  --voxel M                voxel-grid centroids at M metres (off)\n"
    "  --mesh-samples N         points sampled on a mesh (1000000)\n"
    "  --use-vertices           for a PLY mesh, fit its vertices instead of sampling faces\n"
    "  --tile NX[,NY]           NX x NY copies of the input on a grid in x, y, copy (i, j) turned\n"
    "                           by (i + j) x 90 degrees (a building-sized test scene); a mesh is\n"
    "                           tiled before sampling (--mesh-samples points over all copies)\n"
    "  --tile-spacing M         grid step of --tile, m (larger x/y extent of the input + 2 m)\n"
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
  double holdout = 0.0;
  std::string blocks = "auto", block_margin = "0";
  BlockFitParams block;
  TileParams tile;
  EmParams em;
  CloudFilterParams filter;
  SevenScenesCloudParams seven;
};

// The command line, checked (a usage error exits with status 2).
Options parseOptions(int argc, char** argv) {
  Options o;
  std::string init = "kmeans", tile;
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
            {"min-depth", &o.seven.min_depth_m}, {"max-depth", &o.seven.max_depth_m},
            {"holdout", &o.holdout}, {"blocks", &o.blocks},
            {"block-components", &o.block.components_per_block},
            {"block-margin", &o.block_margin}, {"margin-radii", &o.block.margin_radii},
            {"reconcile-iter", &o.block.reconcile_iterations},
            {"block-iter", &o.block.block_iterations}, {"tile", &tile},
            {"tile-spacing", &o.tile.spacing_m}});
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
  if (!(o.holdout >= 0.0 && o.holdout < 1.0)) usageError("--holdout must be in [0, 1)");
  if (o.blocks != "auto" && o.blocks != "off") {
    const std::vector<double> n = parseNumberList(o.blocks);
    if (n.size() != 1 || n[0] < 1 || n[0] != std::floor(n[0]) || n[0] > 1e7) {
      usageError("--blocks must be auto, off or a block count >= 1");
    }
  }
  if (o.block_margin == "auto") {
    o.block.margin_m = -1.0;
  } else {
    const std::vector<double> m = parseNumberList(o.block_margin);
    if (m.size() != 1 || m[0] < 0.0) usageError("--block-margin must be auto or >= 0 (m)");
    o.block.margin_m = m[0];
  }
  {
    BlockFitParams check = o.block;  // the block fit's own fields (EM faults: when fitting)
    check.em = EmParams();
    check.blocks = 0;
    const std::string fault = check.validate();
    if (!fault.empty()) usageError("block fit options: " + fault);
  }
  if (!tile.empty()) {
    const std::vector<double> t = parseNumberList(tile);  // NX or NX,NY
    if (t.empty() || t.size() > 2 || t[0] < 1 || t.back() < 1 || t[0] != std::floor(t[0]) ||
        t.back() != std::floor(t.back()) || t[0] * t.back() > 1e6) {
      usageError("--tile must be NX or NX,NY with whole numbers >= 1");
    }
    o.tile.nx = static_cast<int>(t[0]);
    o.tile.ny = static_cast<int>(t.back());
  }
  {
    const std::string fault = o.tile.validate();
    if (!fault.empty()) usageError("--tile-spacing: " + fault);
  }
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

// The input's points: the stitched 7-Scenes frames, a mesh's surface samples or a file's points
// (with --tile, of the tiled input).
PointCloud loadCloud(Options* o) {
  PointCloud cloud;
  const bool tiled = o->tile.nx * o->tile.ny > 1;
  const std::string copies =
      tiled ? " in " + std::to_string(o->tile.nx) + " x " + std::to_string(o->tile.ny) + " copies"
            : "";
  if (!o->seven_dir.empty()) {
    SevenScenesCloudParams& seven = o->seven;
    if (o->voxel_set) seven.voxel_m = o->filter.voxel_m;
    o->filter.voxel_m = 0.f;  // downsampled while stitching
    SevenScenesCloudStats st;
    cloud = buildSevenScenesCloud(o->seven_dir, seven, &st);
    if (!o->quiet) {
      std::cerr << "7-Scenes: " << st.frames << " frames, " << st.points_back_projected
                << " points in (" << seven.min_depth_m << ", " << seven.max_depth_m << "] m -> "
                << st.voxels << " voxels of " << seven.voxel_m << " m" << copies << "\n";
    }
    return tiled ? tileCloud(cloud, o->tile) : cloud;
  }
  CloudFile file = readCloudFile(o->input);
  if (file.hasFaces() && !o->use_vertices) {
    if (tiled) file.mesh = tileMesh(file.mesh, o->tile);
    cloud = sampleMeshSurface(file.mesh, o->mesh_samples, o->em.seed);
    if (!o->quiet) {
      std::cerr << o->input << ": mesh with " << file.mesh.vertices_m.size() << " vertices, "
                << file.mesh.triangles.size() << " triangles" << copies << " -> " << cloud.size()
                << " surface samples\n";
    }
  } else {
    cloud = tiled ? tileCloud(file.points, o->tile) : std::move(file.points);
    if (!o->quiet) std::cerr << o->input << ": " << cloud.size() << " points" << copies << "\n";
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

// What the summary and --stats-json report, from either fitter.
struct FitReport {
  EmResult fit;                            // whole-map EM; for blocks: the reconciliation's history
  const BlockFitResult* blocks = nullptr;  // block fit details
  size_t train_points = 0, holdout_points = 0;
  double holdout_mean_log_likelihood = std::nan("");
};

void writeStatsJson(const std::string& path, const FitReport& r, const GmmMap& map, size_t bytes,
                    const EmParams& em) {
  const EmResult& fit = r.fit;
  std::ofstream js(path);
  js << "{\"points\": " << r.train_points << ", \"components\": " << map.size()
     << ", \"iterations\": " << fit.iterations
     << ", \"converged\": " << (fit.converged ? "true" : "false")
     << ", \"final_mean_log_likelihood\": " << jsonNumber(fit.final_mean_log_likelihood)
     << ", \"holdout_points\": " << r.holdout_points
     << ", \"holdout_mean_log_likelihood\": " << jsonNumber(r.holdout_mean_log_likelihood)
     << ", \"init_s\": " << jsonNumber(fit.init_s) << ", \"total_s\": " << jsonNumber(fit.total_s)
     << ", \"file_bytes\": " << bytes << ", \"reg_covar_m2\": " << jsonNumber(em.reg_covar_m2)
     << ", \"threads\": " << omp_get_max_threads();
  if (r.blocks) {
    const BlockFitResult& b = *r.blocks;
    std::vector<double> margins, iterations;
    size_t margin_points = 0;
    int unconverged = 0;
    for (const BlockInfo& info : b.blocks) {
      if (info.components == 0) continue;
      margins.push_back(info.margin_m);
      iterations.push_back(info.iterations);
      margin_points += info.margin_points;
      unconverged += info.converged ? 0 : 1;
    }
    std::sort(margins.begin(), margins.end());
    std::sort(iterations.begin(), iterations.end());
    auto mid = [](const std::vector<double>& v) { return v.empty() ? 0.0 : v[v.size() / 2]; };
    js << ", \"blocks\": {\"count\": " << b.blocks.size()
       << ", \"margin_m_median\": " << jsonNumber(mid(margins))
       << ", \"margin_points\": " << margin_points
       << ", \"block_iterations_median\": " << jsonNumber(mid(iterations))
       << ", \"block_iterations_max\": " << jsonNumber(iterations.empty() ? 0.0 : iterations.back())
       << ", \"unconverged_blocks\": " << unconverged << ", \"kept_outside\": " << b.kept_outside
       << ", \"dropped_inside\": " << b.dropped_inside << ", \"split_s\": " << jsonNumber(b.split_s)
       << ", \"blocks_s\": " << jsonNumber(b.blocks_s)
       << ", \"reconcile_s\": " << jsonNumber(b.reconcile_s) << "}";
  }
  js << ", \"history\": [";
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

// "1h02m", "3m07s", "12s".
std::string clockText(double s) {
  if (!std::isfinite(s) || s < 0) return "--";
  const long t = static_cast<long>(std::lround(s));
  char buf[32];
  if (t >= 3600) {
    std::snprintf(buf, sizeof(buf), "%ldh%02ldm", t / 3600, (t / 60) % 60);
  } else if (t >= 60) {
    std::snprintf(buf, sizeof(buf), "%ldm%02lds", t / 60, t % 60);
  } else {
    std::snprintf(buf, sizeof(buf), "%lds", t);
  }
  return buf;
}

// The block fit's progress on stderr: a bar redrawn in place on a terminal, otherwise a plain
// line at most every kProgressLineS seconds (and at the end of each stage).
constexpr double kProgressLineS = 10.0;
BlockProgressFn blockProgress(bool tty) {
  auto last_line_s = std::make_shared<double>(-kProgressLineS);
  return [tty, last_line_s](const BlockProgress& p) {
    char line[200];
    if (p.stage == BlockStage::kBlocks) {
      const double done = p.points_total ? static_cast<double>(p.points_done) / p.points_total : 1;
      const double rate = p.elapsed_s > 0 ? static_cast<double>(p.points_done) / p.elapsed_s : 0;
      const double eta = done > 0 ? p.elapsed_s * (1.0 - done) / done : NAN;
      const bool last = p.blocks_done == p.blocks_total;
      if (tty) {
        constexpr int kWidth = 30;
        const int filled = static_cast<int>(done * kWidth);
        const std::string bar = std::string(filled, '#') + std::string(kWidth - filled, '.');
        std::snprintf(line, sizeof(line), "\rblocks [%s] %d/%d %3.0f%%  %.2f Mpt/s  %s  ETA %s ",
                      bar.c_str(), p.blocks_done, p.blocks_total, 100.0 * done, rate * 1e-6,
                      clockText(p.elapsed_s).c_str(), clockText(eta).c_str());
        std::cerr << line << (last ? "\n" : "") << std::flush;
      } else if (last || p.elapsed_s - *last_line_s >= kProgressLineS) {
        *last_line_s = p.elapsed_s;
        std::snprintf(line, sizeof(line),
                      "blocks %d/%d (%.0f%% of the points), %.2f M points/s, elapsed %s, ETA %s",
                      p.blocks_done, p.blocks_total, 100.0 * done, rate * 1e-6,
                      clockText(p.elapsed_s).c_str(), clockText(eta).c_str());
        std::cerr << line << "\n";
      }
    } else if (p.stage == BlockStage::kReconcile) {
      std::snprintf(line, sizeof(line),
                    "reconcile iter %d (at most %d) over all points: mean log-lik %.6f, "
                    "elapsed %s",
                    p.iteration, p.iterations_total, p.mean_log_likelihood,
                    clockText(p.elapsed_s).c_str());
      std::cerr << (tty ? "\r" : "") << line << (tty ? " " : "\n") << std::flush;
    } else {
      std::cerr << "scoring all points, elapsed " << clockText(p.elapsed_s) << "\n";
    }
  };
}

// The whole-map EM's progress: one line per iteration (redrawn in place on a terminal).
EmProgress emProgress(bool tty, int max_iterations) {
  return [tty, max_iterations](const EmIteration& it) {
    char line[160];
    std::snprintf(line, sizeof(line), "iter %4d/%d  mean log-lik %12.6f  %8.2f s  %6.1f comps/pt",
                  it.iteration, max_iterations, it.mean_log_likelihood, it.elapsed_s,
                  it.mean_candidates);
    if (tty) {
      std::cerr << "\r" << line << std::flush;
    } else {
      std::cerr << line << "\n";
    }
  };
}

// The block count --blocks asks for on this many points (1 = whole-map EM).
int blockCount(const Options& o, size_t points) {
  if (o.blocks == "off") return 1;
  if (o.blocks == "auto") {
    BlockFitParams bp = o.block;
    bp.em = o.em;
    return autoBlockCount(points, bp);
  }
  return static_cast<int>(parseNumberList(o.blocks)[0]);
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
  FitReport report;
  PointCloud train, held_out;
  const PointCloud* fit_points = &cloud;
  if (o->holdout > 0.0) {
    splitHoldout(cloud, o->holdout, em.seed, &train, &held_out);
    fit_points = &train;
    if (held_out.empty())
      throw FitError("--holdout " + std::to_string(o->holdout) +
                     " held out no points (too few points)");
  }
  report.train_points = fit_points->size();
  report.holdout_points = held_out.size();
  const int blocks = blockCount(*o, fit_points->size());
  if (blocks > 1 && !o->init_means_path.empty()) {
    usageError("--init-means needs a whole-map EM: add --blocks off");
  }
  if (!quiet) {
    std::cerr << "EM: M=" << em.components << ", " << fit_points->size() << " points";
    if (o->holdout > 0.0) std::cerr << " (" << held_out.size() << " held out)";
    std::cerr << ", tol " << em.tolerance << ", max " << em.max_iterations
              << " iterations, reg_covar " << em.reg_covar_m2 << " m^2, prune " << em.prune_sigma
              << " sigma, " << omp_get_max_threads() << " threads, seed " << em.seed;
    if (blocks > 1) {
      std::cerr << "; " << blocks << " blocks, margin ";
      if (o->block.margin_m >= 0.0) {
        std::cerr << o->block.margin_m << " m";
      } else {
        std::cerr << o->block.margin_radii << " component radii";
      }
      std::cerr << ", at most " << o->block.reconcile_iterations << " reconcile iterations";
    }
    std::cerr << "\n";
  }
  BlockFitResult block_fit;
  if (blocks > 1) {
    BlockFitParams bp = o->block;
    bp.em = em;
    bp.blocks = blocks;
    block_fit = fitGmmBlocks(*fit_points, bp, quiet ? BlockProgressFn() : blockProgress(tty));
    if (!quiet && tty && block_fit.reconcile.iterations > 0) std::cerr << "\n";
    EmResult& f = report.fit;
    f.components = std::move(block_fit.components);
    f.iterations = block_fit.reconcile.iterations;
    f.converged = true;
    for (const BlockInfo& b : block_fit.blocks) f.converged &= b.converged || b.components == 0;
    f.final_mean_log_likelihood = block_fit.final_mean_log_likelihood;
    f.init_s = block_fit.split_s;
    f.total_s = block_fit.total_s;
    f.regularised_components = block_fit.regularised_components;
    f.empty_components = block_fit.empty_components;
    f.history = block_fit.reconcile.history;
    report.blocks = &block_fit;
  } else {
    report.fit = fitGmm(*fit_points, em, quiet ? EmProgress() : emProgress(tty, em.max_iterations));
    if (!quiet && tty) std::cerr << "\n";
  }
  const EmResult& fit = report.fit;
  int repaired = 0;
  const GmmMap map = makeStorableMap(fit.components, em.reg_covar_m2, o->output, &repaired);
  saveMap(map, o->output);
  loadMap(o->output);  // read back: the file validates as every consumer will see it
  const size_t bytes = encodeMap(map).size();
  if (!held_out.empty()) {
    // The stored (float32) map on the held-out points, pruned as the E-step is.
    report.holdout_mean_log_likelihood =
        meanLogLikelihood(map.components(), held_out, em.prune_sigma);
  }
  if (!quiet) {
    if (report.blocks) {
      const BlockFitResult& b = *report.blocks;
      int unconverged = 0;
      size_t margin_points = 0;
      for (const BlockInfo& info : b.blocks) {
        unconverged += (info.converged || info.components == 0) ? 0 : 1;
        margin_points += info.margin_points;
      }
      std::cerr << b.blocks.size() << " blocks (" << unconverged
                << " stopped at the iteration cap), " << margin_points << " margin points, "
                << b.kept_outside << " components kept outside their block, " << b.dropped_inside
                << " dropped inside; " << fit.iterations
                << " reconcile iterations; final mean log-lik " << fit.final_mean_log_likelihood
                << "; blocks " << b.blocks_s << " s, reconcile " << b.reconcile_s << " s, total "
                << b.total_s << " s\n";
    } else {
      std::cerr << (fit.converged ? "converged" : "stopped at the iteration cap") << " after "
                << fit.iterations << " iterations; final mean log-lik "
                << fit.final_mean_log_likelihood << "; init " << fit.init_s << " s, total "
                << fit.total_s << " s\n";
    }
    if (!held_out.empty()) {
      std::cerr << "held-out mean log-lik " << report.holdout_mean_log_likelihood << " on "
                << held_out.size() << " points\n";
    }
    if (fit.regularised_components || repaired || fit.empty_components) {
      std::cerr << "note: " << fit.regularised_components
                << " covariances needed extra diagonal loading, " << repaired
                << " were repaired for float32 storage, " << fit.empty_components
                << " components are (numerically) empty\n";
    }
    std::cerr << "wrote " << o->output << " (" << map.size() << " components, " << bytes
              << " bytes)\n";
  }
  if (!o->stats_json.empty()) writeStatsJson(o->stats_json, report, map, bytes, em);
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
