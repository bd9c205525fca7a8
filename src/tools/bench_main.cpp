// gmm_mcl_bench: the DESIGN.md benchmark workloads (paper, cpu, full, scale, large) on both
// backends. Per (backend, workload): warm-up frames, then timed updates (frame preparation +
// backend), median updates per second, per-stage milliseconds, Gaussian evaluations per update
// and per second, for CUDA the likelihood kernel's fraction of the GPU's FP32 peak, and the
// relative error of the backend's log-likelihood against the exact sum (every component, double
// precision) at a few particles. One table out.
// --step: the whole filter step per stage instead (predict, frame preparation, likelihood,
// weights, estimate, resampling, recovery, lost detector), the particle set on the host
// (ParticleFilter) and, with CUDA, on the device (CudaParticleFilter); and the localizer's own
// step (Localizer::step with its stage times) with either filter.
#include <omp.h>
#include <sys/stat.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench/frame_set.h"
#include "gmm_mcl/backend/cpu_backend.h"
#include "gmm_mcl/camera/depth_frame.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/lost_detector.h"
#include "gmm_mcl/filter/particle_filter.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/tools/command_line.h"
#if defined(GMM_MCL_HAVE_CUDA)
#include "gmm_mcl/backend/cuda_backend.h"
#include "gmm_mcl/filter/cuda_particle_filter.h"
#endif

namespace gmm_mcl {
namespace {

struct Workload {
  const char* name;
  int particles;
  int stride_px;
  bool large_map;  // the M=4000 map of the same scene (--large-map) instead of --map
};
const Workload kWorkloads[] = {{"paper", 1068, 4, false},
                               {"cpu", 1068, 8, false},
                               {"full", 1068, 1, false},
                               {"scale", 100000, 8, false},
                               {"large", 1068, 4, true}};

struct Options {
  std::string backends = "all";
  std::string workloads = "all";
  std::string map_path;
  std::string large_map_path;
  std::string frames_dir;
  std::string frames_raw;
  std::string export_frames;
  int frames = 100;
  int warmup = 3;
  double budget_s = 20.0;  // timed seconds per (backend, workload), at least min_timed frames
  int min_timed = 3;
  int threads = 0;
  int particles = 0;  // override
  int patch_px = FrameParams().patch_size_px;
  int exact_particles = 2;  // per checked frame: particle 0 (the true pose) and spread ones
  int exact_frames = 2;     // the first timed frames
  unsigned seed = 1;
  double spread_m = 0.5;
  double spread_rad = 0.3;
  bool synthetic = false;
  bool cuda_host_prep = false;  // CUDA: prepare frames on the host (prepareFrame) and upload points
  bool depth_noise = true;      // the depth-noise model (per-particle evaluation forms)
  bool step = false;            // the whole filter step per stage (--step)
};

bool exists(const std::string& p) {
  struct stat st;
  return !p.empty() && stat(p.c_str(), &st) == 0;
}

const char* kUsage =
      "gmm_mcl_bench [options]\n"
      "  --backend cpu|cuda|all      (all: cpu, and cuda when built and a device is present)\n"
      "  --workload paper|cpu|full|scale|large|all   (comma-separated list accepted)\n"
      "  --map FILE                  GMM map (default $GMM_MCL_MAP, "
      "build/maps/7scenes_redkitchen_m1000.gmm)\n"
      "  --large-map FILE            the `large` workload's M=4000 map of the same scene (default\n"
      "                              $GMM_MCL_LARGE_MAP, build/maps/7scenes_redkitchen_m4000.gmm)\n"
      "  --patch PX                  membership patch size (default 32)\n"
      "  --exact N --exact-frames F  relative error against the exact sum at N particles (the\n"
      "                              true pose first) of the first F timed frames (2, 2; 0: off)\n"
      "  --frames-dir DIR            7-Scenes sequence folder (needs libpng)\n"
      "  --frames-raw FILE           raw frame file (bench --export-frames writes one)\n"
      "  --synthetic                 synthetic box scene and its map instead of 7-Scenes\n"
      "  --frames N (100) --warmup N (3) --budget-s S (20) --min-timed N (3)\n"
      "  --threads N (CPU)  --particles N (override)  --seed S  --spread-m M (0.5) --spread-rad R "
      "(0.3)\n"
      "  --cuda-host-prep            CUDA: prepare frames on the host and upload the points\n"
      "                              (default: the raw image is uploaded and prepared on the GPU)\n"
      "  --export-frames FILE        write the loaded frames as a raw file and exit\n"
      "  --no-depth-noise            the paper's model: no depth-noise convolution (one evaluation\n"
      "                              form for all particles)\n"
      "  --step                      the whole filter step per stage at each workload's N (scale:\n"
      "                              100,000; cpu: 1068): the particle set on the host and, with\n"
      "                              CUDA, on the GPU; then Localizer::step with either filter\n";

bool listed(const std::string& list, const std::string& name) {
  if (list == "all") return true;
  size_t pos = 0;
  while (pos <= list.size()) {
    const size_t comma = list.find(',', pos);
    const std::string item =
        list.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos);
    if (item == name) return true;
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return false;
}

// Particles uniform within +-spread_m per axis and +-spread_rad of yaw (about the map's z axis,
// through the camera centre) around the true camera pose.
std::vector<RigidTransformF> makeParticles(const Eigen::Isometry3d& T_true, int n, double spread_m,
                                           double spread_rad, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> um(-spread_m, spread_m), ur(-spread_rad, spread_rad);
  std::vector<RigidTransformF> out(n);
  out[0] = toRigidF(T_true);
  for (int i = 1; i < n; ++i) {
    Eigen::Isometry3d T = T_true;
    T.linear() =
        Eigen::AngleAxisd(ur(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix() * T_true.linear();
    T.translation() += Eigen::Vector3d(um(rng), um(rng), um(rng));
    out[i] = toRigidF(T);
  }
  return out;
}

// CPU time of the whole process (all threads), milliseconds.
double processCpuMs() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Row {
  std::string backend, workload;
  int particles = 0, stride = 0, timed = 0;
  double pixels = 0, comps_per_patch = 0, evals_per_update = 0, updates_per_s = 0;
  double prep_ms = 0, membership_ms = 0, likelihood_ms = 0, transfer_ms = 0, total_ms = 0;
  double cpu_ms = 0;  // process CPU time per update (all threads)
  double gevals_per_s = 0, kernel_gevals_per_s = 0, peak_fraction = -1, floor_hit_fraction = 0;
  // |L - L_exact| / |L_exact| of the backend's log-likelihood against the exact sum, at the true
  // pose (worst checked frame) and worst over every checked particle; -1: not checked.
  double rel_err_truth = -1, rel_err_max = -1;
  double visible_components = -1;  // mean after the per-update view cull; -1: not culled
};

// A pose the backend evaluated, with its log-likelihood, for the exact-sum check.
struct CheckedPose {
  int frame;
  RigidTransformF T_map_cam;
  double log_likelihood;
};

// Relative error of the backend's log-likelihoods against exactFrameLogLikelihood (double
// precision, every component, the same floor and depth noise) on the host's prepared frames.
void exactErrors(const GmmMap& map, const bench::FrameSet& frames, const FrameParams& fp,
                 const MeasurementParams& mp, const std::vector<CheckedPose>& checked,
                 int per_frame, Row* row) {
  if (checked.empty()) return;
  row->rel_err_truth = row->rel_err_max = 0.0;
  int last_frame = -1;
  DepthFrame frame;
  for (size_t k = 0; k < checked.size(); ++k) {
    const CheckedPose& c = checked[k];
    if (c.frame != last_frame) frame = prepareFrame(frames.images[c.frame], frames.K, fp);
    last_frame = c.frame;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int q = 0; q < 3; ++q) T.linear()(r, q) = c.T_map_cam.R[3 * r + q];
      T.translation()(r) = c.T_map_cam.t[r];
    }
    const FrameLikelihood exact = exactFrameLogLikelihood(map, frame, T, mp);
    const double rel = std::abs(c.log_likelihood - exact.log_likelihood) /
                       std::max(std::abs(exact.log_likelihood), 1e-12);
    if (k % per_frame == 0) row->rel_err_truth = std::max(row->rel_err_truth, rel);
    row->rel_err_max = std::max(row->rel_err_max, rel);
  }
}

Row runWorkload(LikelihoodBackend* backend, double fp32_peak_gflops, const Workload& w,
                const GmmMap& map, const bench::FrameSet& frames, const Options& opt) {
  Row row;
  row.backend = backend->name();
#if defined(GMM_MCL_HAVE_CUDA)
  if (dynamic_cast<CudaBackend*>(backend))
    row.backend = opt.cuda_host_prep ? "cuda (host prep)" : "cuda (GPU prep)";
#endif
  row.workload = w.name;
  row.particles = opt.particles > 0 ? opt.particles : w.particles;
  row.stride = w.stride_px;
  FrameParams fp;
  fp.pixel_stride = w.stride_px;
  fp.patch_size_px = opt.patch_px;
  MeasurementParams mp;
  if (!opt.depth_noise) mp.depth_noise.a_m = mp.depth_noise.b_per_m = 0.f;
  const int check_per_frame = std::min(opt.exact_particles, row.particles);
  std::vector<CheckedPose> checked;
  std::vector<double> total_ms, prep_ms, memb_ms, lik_ms, xfer_ms, pixels, cpp, evals, hits, cpu_ms,
      visible;
  BackendOutput out;
  const int nf = static_cast<int>(frames.images.size());
  double timed_s = 0.0;
  for (int it = 0;; ++it) {
    const int f = it % nf;
    const bool warm = it < opt.warmup;
    if (!warm) {
      const int timed = it - opt.warmup;
      if (timed >= opt.frames) break;
      if (timed >= opt.min_timed && timed_s >= opt.budget_s) break;
    }
    const std::vector<RigidTransformF> particles =
        makeParticles(frames.T_map_cam[f], row.particles, opt.spread_m, opt.spread_rad,
                      opt.seed * 7919u + static_cast<unsigned>(f));
    double prep = 0.0, total = 0.0, used_pixels = 0.0;
    const double cpu0 = processCpuMs();
#if defined(GMM_MCL_HAVE_CUDA)
    auto* cuda_backend = dynamic_cast<CudaBackend*>(backend);
    if (cuda_backend && !opt.cuda_host_prep) {
      // Frame preparation on the GPU: the update uploads the raw image.
      const auto t0 = std::chrono::steady_clock::now();
      cuda_backend->evaluateImage(frames.images[f], frames.K, fp, particles, mp, &out);
      const auto t2 = std::chrono::steady_clock::now();
      prep = cuda_backend->lastFramePrepMs();
      total = std::chrono::duration<double, std::milli>(t2 - t0).count();
      used_pixels = cuda_backend->lastFramePixels();
    } else
#endif
    {
      const auto t0 = std::chrono::steady_clock::now();
      const DepthFrame frame = prepareFrame(frames.images[f], frames.K, fp);
      const auto t1 = std::chrono::steady_clock::now();
      backend->evaluate(frame, particles, mp, &out);
      const auto t2 = std::chrono::steady_clock::now();
      prep = std::chrono::duration<double, std::milli>(t1 - t0).count();
      total = std::chrono::duration<double, std::milli>(t2 - t0).count();
      used_pixels = static_cast<double>(frame.size());
    }
    const double cpu = processCpuMs() - cpu0;
    if (warm) continue;
    if (static_cast<int>(total_ms.size()) < opt.exact_frames) {
      for (int k = 0; k < check_per_frame; ++k) {
        checked.push_back(CheckedPose{f, particles[k], out.log_likelihood[k]});
      }
    }
    cpu_ms.push_back(cpu);
    timed_s += total * 1e-3;
    total_ms.push_back(total);
    prep_ms.push_back(prep);
    memb_ms.push_back(out.projection_membership_ms);
    lik_ms.push_back(out.likelihood_ms);
#if defined(GMM_MCL_HAVE_CUDA)
    if (auto* cb = dynamic_cast<CudaBackend*>(backend)) xfer_ms.push_back(cb->lastTransferMs());
#endif
    pixels.push_back(used_pixels);
    cpp.push_back(out.patches_with_pixels > 0
                      ? double(out.relevant_pairs) /
                            (double(row.particles) * out.patches_with_pixels)
                      : 0.0);
    evals.push_back(static_cast<double>(out.evaluations));
    if (out.visible_components >= 0) visible.push_back(out.visible_components);
    long long h = 0;
    for (int x : out.floor_hits) h += x;
    hits.push_back(used_pixels > 0 ? double(h) / (used_pixels * row.particles) : 0.0);
  }
  row.timed = static_cast<int>(total_ms.size());
  auto mean = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? 0.0 : s / v.size();
  };
  row.total_ms = median(total_ms);
  row.updates_per_s = row.total_ms > 0 ? 1e3 / row.total_ms : 0;
  row.prep_ms = median(prep_ms);
  row.cpu_ms = median(cpu_ms);
  row.membership_ms = median(memb_ms);
  row.likelihood_ms = median(lik_ms);
  row.transfer_ms = xfer_ms.empty() ? -1 : median(xfer_ms);
  row.visible_components = visible.empty() ? -1 : mean(visible);
  row.pixels = mean(pixels);
  row.comps_per_patch = mean(cpp);
  row.evals_per_update = mean(evals);
  row.floor_hit_fraction = mean(hits);
  row.gevals_per_s = row.evals_per_update * row.updates_per_s * 1e-9;
  // Likelihood stage alone: evaluations of each frame over its likelihood time (median).
  std::vector<double> rate;
  for (size_t i = 0; i < evals.size(); ++i) {
    if (lik_ms[i] > 0) rate.push_back(evals[i] / (lik_ms[i] * 1e-3) * 1e-9);
  }
  row.kernel_gevals_per_s = median(rate);
#if defined(GMM_MCL_HAVE_CUDA)
  if (fp32_peak_gflops > 0 && dynamic_cast<CudaBackend*>(backend)) {
    row.peak_fraction = row.kernel_gevals_per_s * kCudaFlopsPerEvaluation / fp32_peak_gflops;
  }
#else
  (void)fp32_peak_gflops;
#endif
  exactErrors(map, frames, fp, mp, checked, check_per_frame, &row);
  return row;
}

// ---- --step: the whole filter step --------------------------------------------------------------

using Clock = std::chrono::steady_clock;
double msBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Base (x forward, z up) to the camera optical frame, the replay tool's mount.
Eigen::Isometry3d baseToCamera() {
  Eigen::Matrix3d R;
  R << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  return T;
}

struct StepRow {
  std::string what, workload;
  int particles = 0, resampled_to = 0, timed = 0;
  double predict = 0, prep = 0, likelihood = 0, weights = 0, estimate = 0, resample = 0,
         recover = 0, lost = 0, refine = 0, total = 0;
};

// The filter's operations one after the other, each timed to its end (synchronised), on fresh
// particles for every frame (uniform +-spread around the true base pose, as the `scale`
// workload's), the particle count adapting by KLD-sampling between 1068 and N at a resampling
// done on every step (the worst case: the localizer resamples when Neff < N / 2).
StepRow runFilterStep(LikelihoodBackend* backend, bool device, const Workload& w,
                      const bench::FrameSet& frames, const Options& opt) {
  StepRow row;
  row.workload = w.name;
  row.particles = opt.particles > 0 ? opt.particles : w.particles;
  const int n = row.particles;
  ParticleFilterParams fp;
  fp.num_particles = n;
  fp.min_particles = n > kDefaultParticleCount ? kDefaultParticleCount : 0;
  fp.seed = opt.seed;
  std::unique_ptr<ParticleFilterBase> filter;
#if defined(GMM_MCL_HAVE_CUDA)
  if (device) filter.reset(new CudaParticleFilter(fp, dynamic_cast<CudaBackend*>(backend)));
#endif
  if (!filter) filter.reset(new ParticleFilter(fp));
  row.what = std::string(device ? "device filter" : "host filter") + ", " + backend->name() +
             " backend";
  FrameParams frp;
  frp.pixel_stride = w.stride_px;
  frp.patch_size_px = opt.patch_px;
  MeasurementParams mp;
  if (!opt.depth_noise) mp.depth_noise.a_m = mp.depth_noise.b_per_m = 0.f;
  const Eigen::Isometry3d T_base_cam = baseToCamera();
  LostDetector lost(LostDetectionParams(), 0.0);
  std::vector<double> v_predict, v_prep, v_lik, v_weights, v_est, v_res, v_rec, v_lost, v_total,
      v_n;
  const int nf = static_cast<int>(frames.images.size());
  double timed_s = 0.0;
  for (int it = 0;; ++it) {
    const int f = it % nf;
    const bool warm = it < opt.warmup;
    if (!warm) {
      const int timed = it - opt.warmup;
      if (timed >= opt.frames) break;
      if (timed >= opt.min_timed && timed_s >= opt.budget_s) break;
    }
    const Eigen::Isometry3d T_map_base = frames.T_map_cam[f] * T_base_cam.inverse();
    const Particle truth = poseToParticle(T_map_base);
    double roll, pitch, yaw;
    rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
    std::mt19937_64 rng(opt.seed * 7919u + static_cast<unsigned>(f));
    std::uniform_real_distribution<double> um(-opt.spread_m, opt.spread_m),
        ur(-opt.spread_rad, opt.spread_rad);
    std::vector<Particle> particles(n, truth);
    for (int i = 1; i < n; ++i) {
      particles[i].x_m += um(rng);
      particles[i].y_m += um(rng);
      particles[i].z_m += um(rng);
      particles[i].yaw_rad = wrapAngle(particles[i].yaw_rad + ur(rng));
    }
    filter->setParticles(particles, std::vector<double>(n, 1.0));
    InitRegion region;
    region.centre_m = Eigen::Vector3d(truth.x_m, truth.y_m, truth.z_m);
    filter->synchronize();

    PlanarDelta delta;
    delta.translation_m = Eigen::Vector3d(0.01, 0.0, 0.0);
    delta.yaw_rad = 0.005;
    const Clock::time_point t0 = Clock::now();
    filter->predict(delta);
    filter->synchronize();
    const Clock::time_point t1 = Clock::now();
    DepthFrame frame;
    DeviceFrameSummary summary;
    int pixels = 0;
    if (filter->prepareDeviceFrame(frames.images[f], frames.K, frp, &summary)) {
      pixels = summary.pixels;
    } else {
      frame = prepareFrame(frames.images[f], frames.K, frp);
      pixels = static_cast<int>(frame.size());
    }
    const Clock::time_point t2 = Clock::now();
    MeasurementContext ctx;
    ctx.backend = backend;
    ctx.frame = device ? nullptr : &frame;
    ctx.roll_rad = roll;
    ctx.pitch_rad = pitch;
    ctx.T_base_cam = T_base_cam;
    ctx.params = &mp;
    EvaluationStats stats;
    filter->evaluateFrame(ctx, &stats);
    filter->synchronize();
    const Clock::time_point t3 = Clock::now();
    FrameScores scores;
    if (!filter->weighFrame(pixels, &scores)) throw std::runtime_error("--step: degenerate weights");
    const Clock::time_point t4 = Clock::now();
    filter->estimate();
    filter->effectiveSampleSize();
    const Clock::time_point t5 = Clock::now();
#if defined(GMM_MCL_HAVE_CUDA)
    if (auto* d = dynamic_cast<CudaParticleFilter*>(filter.get())) d->resample();
#endif
    if (auto* h = dynamic_cast<ParticleFilter*>(filter.get())) h->resample();
    filter->synchronize();
    const Clock::time_point t6 = Clock::now();
    filter->recoverFrame(pixels, region);
    filter->synchronize();
    const Clock::time_point t7 = Clock::now();
    lost.update(scores.best_loglik / pixels);
    const Clock::time_point t8 = Clock::now();
    if (warm) continue;
    v_predict.push_back(msBetween(t0, t1));
    v_prep.push_back(msBetween(t1, t2));
    v_lik.push_back(msBetween(t2, t3));
    v_weights.push_back(msBetween(t3, t4));
    v_est.push_back(msBetween(t4, t5));
    v_res.push_back(msBetween(t5, t6));
    v_rec.push_back(msBetween(t6, t7));
    v_lost.push_back(msBetween(t7, t8));
    v_total.push_back(msBetween(t0, t8));
    v_n.push_back(filter->size());
    timed_s += msBetween(t0, t8) * 1e-3;
  }
  row.timed = static_cast<int>(v_total.size());
  row.predict = median(v_predict);
  row.prep = median(v_prep);
  row.likelihood = median(v_lik);
  row.weights = median(v_weights);
  row.estimate = median(v_est);
  row.resample = median(v_res);
  row.recover = median(v_rec);
  row.lost = median(v_lost);
  row.total = median(v_total);
  row.resampled_to = static_cast<int>(median(v_n));
  return row;
}

// Localizer::step along the frames (back and forth, so that the motion stays continuous) with
// odometry and attitude from the ground truth, from a Gaussian start at the truth, at a fixed
// count of N particles: the product path, refinement included.
StepRow runLocalizerStep(const std::string& backend, bool device, const Workload& w,
                         const GmmMap& map, const bench::FrameSet& frames, const Options& opt) {
  StepRow row;
  row.workload = w.name;
  row.particles = opt.particles > 0 ? opt.particles : w.particles;
  LocalizerParams lp;
  lp.backend = backend;
  lp.device_filter = device;
  lp.filter.num_particles = row.particles;
  lp.filter.min_particles = 0;
  lp.filter.seed = opt.seed;
  lp.frame.pixel_stride = w.stride_px;
  lp.frame.patch_size_px = opt.patch_px;
  lp.T_base_cam = baseToCamera();
  if (!opt.depth_noise) lp.measurement.depth_noise.a_m = lp.measurement.depth_noise.b_per_m = 0.f;
  const int nf = static_cast<int>(frames.images.size());
  std::vector<Eigen::Isometry3d> T_map_base(nf);
  for (int f = 0; f < nf; ++f) T_map_base[f] = frames.T_map_cam[f] * lp.T_base_cam.inverse();
  const Particle start = poseToParticle(T_map_base[0]);
  lp.init.centre_m = Eigen::Vector3d(start.x_m, start.y_m, start.z_m);
  lp.init.yaw_centre_rad = start.yaw_rad;
  Localizer loc(lp, map);
  row.what = std::string("Localizer::step, ") + loc.filterName() + " filter, " +
             loc.backend().name() + " backend";
  loc.resetToPose(start, Eigen::Vector4d(0.05, 0.05, 0.05, 0.05));
  std::vector<double> v_predict, v_prep, v_lik, v_weights, v_est, v_res, v_refine, v_total;
  double timed_s = 0.0;
  const int period = nf > 1 ? 2 * (nf - 1) : 1;
  for (int it = 0;; ++it) {
    const bool warm = it < opt.warmup;
    if (!warm) {
      const int timed = it - opt.warmup;
      if (timed >= opt.frames) break;
      if (timed >= opt.min_timed && timed_s >= opt.budget_s) break;
    }
    const int k = it % period;
    const int f = k < nf ? k : period - k;  // 0, 1, ..., nf - 1, nf - 2, ..., 1
    StepInput in;
    in.stamp_s = it / 30.0;
    in.has_odometry = true;
    in.T_odom_base = T_map_base[f];
    in.has_attitude = true;
    double yaw;
    rpyFromRotation(T_map_base[f].linear(), &in.roll_rad, &in.pitch_rad, &yaw);
    in.depth = &frames.images[f];
    in.intrinsics = frames.K;
    const StepResult r = loc.step(in);
    if (r.status != StepStatus::kOk) {
      std::fprintf(stderr, "# %s: frame %d: %s (%s)\n", row.what.c_str(), f,
                   stepStatusName(r.status), r.message.c_str());
    }
    if (warm) continue;
    const StepTimings& t = r.timings;
    v_predict.push_back(t.predict_ms);
    v_prep.push_back(t.frame_prep_ms);
    v_lik.push_back(t.projection_membership_ms + t.likelihood_ms);
    v_weights.push_back(t.weights_ms);
    v_est.push_back(t.estimate_ms);
    v_res.push_back(t.resample_ms);
    v_refine.push_back(t.refine_ms);
    v_total.push_back(t.total_ms);
    timed_s += t.total_ms * 1e-3;
  }
  row.timed = static_cast<int>(v_total.size());
  row.predict = median(v_predict);
  row.prep = median(v_prep);
  row.likelihood = median(v_lik);
  row.weights = median(v_weights);
  row.estimate = median(v_est);
  row.resample = median(v_res);
  row.refine = median(v_refine);
  row.total = median(v_total);
  row.resampled_to = loc.filter().size();
  return row;
}

void runSteps(const std::vector<LikelihoodBackend*>& backends, const GmmMap& map,
              const bench::FrameSet& frames, const Options& opt) {
  std::vector<StepRow> rows;
  for (LikelihoodBackend* b : backends) {
    for (const Workload& w : kWorkloads) {
      if (!listed(opt.workloads, w.name) || w.large_map) continue;
      for (int device = 0; device < 2; ++device) {
        bool is_cuda = false;
#if defined(GMM_MCL_HAVE_CUDA)
        is_cuda = dynamic_cast<CudaBackend*>(b) != nullptr;
#endif
        if (device && !is_cuda) continue;
        rows.push_back(runFilterStep(b, device != 0, w, frames, opt));
        std::fprintf(stderr, "# done %s / %s: %.2f ms\n", rows.back().what.c_str(), w.name,
                     rows.back().total);
      }
    }
  }
  for (LikelihoodBackend* b : backends) {
    for (const Workload& w : kWorkloads) {
      if (!listed(opt.workloads, w.name) || w.large_map) continue;
      for (int device = 0; device < 2; ++device) {
        if (device && b->name() != "cuda") continue;
        rows.push_back(runLocalizerStep(b->name(), device != 0, w, map, frames, opt));
        std::fprintf(stderr, "# done %s / %s: %.2f ms\n", rows.back().what.c_str(), w.name,
                     rows.back().total);
      }
    }
  }
  std::printf(
      "\n# filter step: wall-clock medians (ms), each stage synchronised to its end; filter rows "
      "resample on every step (KLD count 1068..N), localizer rows resample when Neff < N/2 "
      "(fixed N) and their likelihood column is the GPU's event time (CPU: the stages' time)\n");
  std::printf("| step | workload | N | predict | frame prep | likelihood | weights | estimate "
              "| resample | recover | lost detector | refine | total | N after | timed |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const StepRow& r : rows) {
    std::printf("| %s | %s | %d | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.4f | %.3f "
                "| **%.2f** | %d | %d |\n",
                r.what.c_str(), r.workload.c_str(), r.particles, r.predict, r.prep, r.likelihood,
                r.weights, r.estimate, r.resample, r.recover, r.lost, r.refine, r.total,
                r.resampled_to, r.timed);
  }
}

int run(int argc, char** argv) {
  Options opt;
  cli::CommandLine cl("gmm_mcl_bench", kUsage);
  cl.flags({{"backend", &opt.backends}, {"workload", &opt.workloads}, {"map", &opt.map_path},
            {"large-map", &opt.large_map_path}, {"patch", &opt.patch_px},
            {"exact", &opt.exact_particles}, {"exact-frames", &opt.exact_frames},
            {"frames-dir", &opt.frames_dir}, {"frames-raw", &opt.frames_raw},
            {"export-frames", &opt.export_frames}, {"frames", &opt.frames}, {"warmup", &opt.warmup},
            {"budget-s", &opt.budget_s}, {"min-timed", &opt.min_timed}, {"threads", &opt.threads},
            {"particles", &opt.particles}, {"seed", &opt.seed},
            {"no-depth-noise", cli::Clear{&opt.depth_noise}}, {"spread-m", &opt.spread_m},
            {"spread-rad", &opt.spread_rad}, {"synthetic", &opt.synthetic},
            {"cuda-host-prep", &opt.cuda_host_prep}, {"step", &opt.step}});
  cl.parse(argc, argv);
  if (opt.frames < 1 || opt.warmup < 0) throw std::invalid_argument("--frames >= 1, --warmup >= 0");
  if (opt.patch_px < 1) throw std::invalid_argument("--patch must be >= 1");
  if (opt.exact_particles < 0 || opt.exact_frames < 0) {
    throw std::invalid_argument("--exact and --exact-frames must be >= 0");
  }

  // Data: the 7-Scenes M=1000 map and frames, else the synthetic scene (said so in the output).
  GmmMap map;
  bench::FrameSet frames;
  std::string map_source;
  const char* env_ds = std::getenv("GMM_MCL_DATASETS");
  const std::string default_dir =
      std::string(env_ds && *env_ds ? env_ds : "../shared/datasets") + "/7scenes_redkitchen/data";
  const char* env_map = std::getenv("GMM_MCL_MAP");
  if (opt.map_path.empty()) {
    if (env_map && *env_map)
      opt.map_path = env_map;
    else if (exists("build/maps/7scenes_redkitchen_m1000.gmm"))
      opt.map_path = "build/maps/7scenes_redkitchen_m1000.gmm";
  }
  if (!opt.synthetic) {
    if (!opt.frames_raw.empty()) {
      frames = bench::loadFrameSet(opt.frames_raw);
      if (static_cast<int>(frames.images.size()) > opt.frames) {
        frames.images.resize(opt.frames);
        frames.T_map_cam.resize(opt.frames);
      }
    } else {
      const std::string dir = opt.frames_dir.empty() ? default_dir : opt.frames_dir;
#if defined(GMM_MCL_HAVE_PNG)
      if (exists(dir + "/frame-000000.depth.png"))
        frames = bench::loadSevenScenes(dir, 0, opt.frames);
#endif
      if (frames.images.empty() && !opt.frames_dir.empty()) {
        throw std::runtime_error("cannot read 7-Scenes frames from " + dir);
      }
    }
    if (!frames.images.empty() && exists(opt.map_path)) {
      map = loadMap(opt.map_path);
      map_source = opt.map_path;
    } else {
      std::printf("# 7-Scenes map or frames absent (map '%s'): using the synthetic scene\n",
                  opt.map_path.c_str());
      frames = bench::FrameSet();
    }
  }
  if (frames.images.empty()) {
    bench::makeSyntheticScene(std::min(opt.frames, 100), &map, &frames);
    map_source = "synthetic box scene (tiled)";
  }
  if (!opt.export_frames.empty()) {
    bench::saveFrameSet(frames, opt.export_frames);
    std::printf("wrote %zu frames to %s\n", frames.images.size(), opt.export_frames.c_str());
    return 0;
  }
  std::printf("# frames: %s (%zu), map: %s (M = %zu)\n", frames.source.c_str(),
              frames.images.size(), map_source.c_str(), map.size());
  // The `large` workload's map: the same scene fitted with M=4000 (DESIGN.md), only with the
  // 7-Scenes frames.
  GmmMap large_map;
  std::string large_absent;
  bool want_large = false;
  for (const Workload& w : kWorkloads) want_large |= w.large_map && listed(opt.workloads, w.name);
  if (want_large && !opt.step) {
    const char* env_large = std::getenv("GMM_MCL_LARGE_MAP");
    if (opt.large_map_path.empty()) {
      opt.large_map_path = env_large && *env_large ? env_large
                                                   : "build/maps/7scenes_redkitchen_m4000.gmm";
    }
    if (map_source.compare(0, 9, "synthetic") == 0) {
      large_absent = "the synthetic scene has no M=4000 map";
    } else if (!exists(opt.large_map_path)) {
      large_absent = "no map at '" + opt.large_map_path +
                     "' (scripts/build_map_7scenes.sh with -m 4000, see docs/benchmark.md)";
    } else {
      large_map = loadMap(opt.large_map_path);
      std::printf("# large: map %s (M = %zu)\n", opt.large_map_path.c_str(), large_map.size());
    }
    if (!large_absent.empty()) std::printf("# large: skipped (%s)\n", large_absent.c_str());
  }
  std::printf("# patches %dx%d px; relative error against the exact sum at %d particle(s) of "
              "the first %d timed frame(s)\n",
              opt.patch_px, opt.patch_px, opt.exact_particles, opt.exact_frames);
  double load[3] = {0, 0, 0};
  if (getloadavg(load, 3) == 3) {
    std::printf("# host load average %.2f %.2f %.2f on %d CPUs (CPU ms/update = process CPU time, "
                "all threads, per update)\n",
                load[0], load[1], load[2], omp_get_num_procs());
  }
  std::printf(
      "# particles: uniform +-%.2f m per axis and +-%.2f rad of yaw around the true camera "
      "pose (particle 0 = the true pose), seed %u\n",
      opt.spread_m, opt.spread_rad, opt.seed);
  std::printf(
      "# timing: %d warm-up updates, then up to %d timed (>= %d, stop after %.0f s); "
      "update = frame preparation + backend (wall clock); medians. CUDA stage times are "
      "events; transfer = upload + download\n",
      opt.warmup, opt.frames, opt.min_timed, opt.budget_s);

  struct Candidate {
    std::unique_ptr<LikelihoodBackend> backend;
    double peak = 0.0;
  };
  std::vector<Candidate> backends;
  if (listed(opt.backends, "cpu")) {
    Candidate c;
    c.backend.reset(new CpuBackend(opt.threads));
    std::printf("# cpu: %d OpenMP threads\n",
                opt.threads > 0 ? opt.threads : omp_get_max_threads());
    backends.push_back(std::move(c));
  }
  if (listed(opt.backends, "cuda")) {
#if defined(GMM_MCL_HAVE_CUDA)
    std::string why;
    if (cudaDeviceCount(&why) > 0) {
      std::unique_ptr<CudaBackend> cb(new CudaBackend(0));
      const CudaDeviceInfo& d = cb->deviceInfo();
      std::printf(
          "# cuda: %s, sm_%d, %d SMs x %d FP32 lanes at %.2f GHz = %.1f TFLOP/s FP32 peak; "
          "%g FLOP counted per evaluation\n",
          d.name.c_str(), d.compute_capability, d.multiprocessors, d.fp32_lanes_per_sm, d.clock_ghz,
          d.fp32_peak_gflops * 1e-3, kCudaFlopsPerEvaluation);
      Candidate c;
      c.peak = d.fp32_peak_gflops;
      c.backend = std::move(cb);
      backends.push_back(std::move(c));
    } else {
      std::printf("# cuda: skipped (%s)\n", why.c_str());
    }
#else
    std::printf("# cuda: not built (GMM_MCL_WITH_CUDA=OFF)\n");
#endif
  }
  if (opt.step) {
    std::vector<LikelihoodBackend*> list;
    for (Candidate& c : backends) {
      c.backend->setMap(map);
      list.push_back(c.backend.get());
    }
    runSteps(list, map, frames, opt);
    return 0;
  }
  std::vector<Row> rows;
  for (Candidate& c : backends) {
    const GmmMap* current = nullptr;
    for (const Workload& w : kWorkloads) {
      if (!listed(opt.workloads, w.name)) continue;
      if (w.large_map && !large_absent.empty()) continue;
      const GmmMap& m = w.large_map ? large_map : map;
      if (current != &m) c.backend->setMap(m);
      current = &m;
      try {
        rows.push_back(runWorkload(c.backend.get(), c.peak, w, m, frames, opt));
      } catch (const BackendError& e) {  // e.g. a bitmask beyond the GPU's shared memory
        std::printf("# %s/%s: skipped (%s)\n", c.backend->name().c_str(), w.name, e.what());
        current = nullptr;
        continue;
      }
      const Row& r = rows.back();
      std::fprintf(stderr, "# done %s/%s: %.2f updates/s\n", r.backend.c_str(), r.workload.c_str(),
                   r.updates_per_s);
    }
  }
  std::printf(
      "\n| backend | workload | N | stride | pixels | comps/patch | evals/update | updates/s "
      "| prep ms | proj+memb ms | likelihood ms | transfer ms | update ms | Geval/s "
      "| lik. kernel Geval/s | FP32 peak | floor hits | CPU ms/update | rel. err. truth "
      "| rel. err. max | timed | visible comps |\n");
  std::printf(
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
      "---|\n");
  for (const Row& r : rows) {
    char xfer[32], peak[32], err_truth[32], err_max[32], visible[32];
    std::snprintf(visible, sizeof(visible), r.visible_components >= 0 ? "%.0f" : "-",
                  r.visible_components);
    std::snprintf(err_truth, sizeof(err_truth), r.rel_err_truth >= 0 ? "%.2e" : "-",
                  r.rel_err_truth);
    std::snprintf(err_max, sizeof(err_max), r.rel_err_max >= 0 ? "%.2e" : "-", r.rel_err_max);
    if (r.transfer_ms >= 0)
      std::snprintf(xfer, sizeof(xfer), "%.3f", r.transfer_ms);
    else
      std::snprintf(xfer, sizeof(xfer), "-");
    if (r.peak_fraction >= 0)
      std::snprintf(peak, sizeof(peak), "%.1f%%", 100 * r.peak_fraction);
    else
      std::snprintf(peak, sizeof(peak), "-");
    std::printf(
        "| %s | %s | %d | %d | %.0f | %.1f | %.3g | %.2f | %.3f | %.3f | %.3f | %s | %.3f "
        "| %.2f | %.2f | %s | %.3f | %.1f | %s | %s | %d | %s |\n",
        r.backend.c_str(), r.workload.c_str(), r.particles, r.stride, r.pixels, r.comps_per_patch,
        r.evals_per_update, r.updates_per_s, r.prep_ms, r.membership_ms, r.likelihood_ms, xfer,
        r.total_ms, r.gevals_per_s, r.kernel_gevals_per_s, peak, r.floor_hit_fraction, r.cpu_ms,
        err_truth, err_max, r.timed, visible);
  }
  return 0;
}

}  // namespace
}  // namespace gmm_mcl

int main(int argc, char** argv) {
  try {
    return gmm_mcl::run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gmm_mcl_bench: %s\n", e.what());
    return 1;
  }
}
