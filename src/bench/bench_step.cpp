// gmm_mcl_bench --step: the whole filter step per stage, on the host filter, the device filter
// (CUDA) and through Localizer::step.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_tool.h"
#include "gmm_mcl/common/timing.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/lost_detector.h"
#include "gmm_mcl/filter/particle_filter_base.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/replay/replay.h"

namespace gmm_mcl {
namespace bench {
namespace {

struct StepRow {
  std::string what, workload;
  int particles = 0, resampled_to = 0, timed = 0;
  double predict = 0, prep = 0, likelihood = 0, weights = 0, estimate = 0, resample = 0,
         recover = 0, lost = 0, refine = 0, total = 0;
  bool has_first_update = false;
  StepTimings first_update;  // the first step from the protocol's uniform start, by stage
  double redraw = -1;        // ms: a lost redraw at the backend's default particle range
  int redrawn = 0;           // particles redrawn by it
};

// Per-stage samples (ms) of the timed steps.
struct StageSamples {
  std::vector<double> predict, prep, likelihood, weights, estimate, resample, recover, lost, refine,
      total;
  // The medians into row (a stage without samples: 0).
  void summarise(StepRow* row) const {
    row->timed = static_cast<int>(total.size());
    row->predict = median(predict);
    row->prep = median(prep);
    row->likelihood = median(likelihood);
    row->weights = median(weights);
    row->estimate = median(estimate);
    row->resample = median(resample);
    row->recover = median(recover);
    row->lost = median(lost);
    row->refine = median(refine);
    row->total = median(total);
  }
};

// n particles: the truth first, then uniform +-spread_m per axis and +-spread_rad of yaw around
// it (the frame's own seed).
std::vector<Particle> spreadParticles(const Particle& truth, int n, int frame, const Options& opt) {
  std::mt19937_64 rng(opt.seed * 7919u + static_cast<unsigned>(frame));
  std::uniform_real_distribution<double> um(-opt.spread_m, opt.spread_m),
      ur(-opt.spread_rad, opt.spread_rad);
  std::vector<Particle> particles(n, truth);
  for (int i = 1; i < n; ++i) {
    particles[i].x_m += um(rng);
    particles[i].y_m += um(rng);
    particles[i].z_m += um(rng);
    particles[i].yaw_rad = wrapAngle(particles[i].yaw_rad + ur(rng));
  }
  return particles;
}

// The filter's operations one after the other, each timed to its end (synchronised), on fresh
// particles for every frame (uniform +-spread around the true base pose, as the `scale`
// workload's), the particle count adapting by KLD-sampling between 1068 and N at a resampling
// done on every step (the worst case: the localizer resamples when Neff < N / 2).
StepRow runFilterStep(LikelihoodBackend* backend, bool device, const Workload& w,
                      const FrameSet& frames, const Options& opt) {
  StepRow row;
  row.workload = w.name;
  row.particles = opt.particles > 0 ? opt.particles : w.particles;
  const int n = row.particles;
  ParticleFilterParams fp;
  fp.num_particles = n;
  fp.min_particles = n > kDefaultParticleCount ? kDefaultParticleCount : 0;
  fp.seed = opt.seed;
  std::string why;
  std::unique_ptr<ParticleFilterBase> filter = makeParticleFilter(fp, backend, device, &why);
  if (device && !why.empty()) throw BackendError(why);
  row.what =
      std::string(device ? "device filter" : "host filter") + ", " + backend->name() + " backend";
  FrameParams frp;
  frp.pixel_stride = w.stride_px;
  frp.patch_size_px = opt.patch_px;
  MeasurementParams mp;
  if (!opt.depth_noise) mp.depth_noise.a_m = mp.depth_noise.b_per_m = 0.f;
  const Eigen::Isometry3d T_base_cam = opticalToBase();
  LostDetector lost(LostDetectionParams(), 0.0);
  StageSamples s;
  std::vector<double> v_n;
  const int nf = static_cast<int>(frames.images.size());
  double timed_s = 0.0;
  for (TimedLoop loop(opt); loop.next(timed_s);) {
    const int f = loop.iteration() % nf;
    const Eigen::Isometry3d T_map_base = frames.T_map_cam[f] * T_base_cam.inverse();
    const Particle truth = poseToParticle(T_map_base);
    double roll, pitch, yaw;
    rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
    filter->setParticles(spreadParticles(truth, n, f, opt), std::vector<double>(n, 1.0));
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
    if (!filter->weighFrame(pixels, &scores))
      throw std::runtime_error("--step: degenerate weights");
    const Clock::time_point t4 = Clock::now();
    filter->estimate();
    filter->effectiveSampleSize();
    const Clock::time_point t5 = Clock::now();
    filter->resample();
    filter->synchronize();
    const Clock::time_point t6 = Clock::now();
    filter->recoverFrame(pixels, region);
    filter->synchronize();
    const Clock::time_point t7 = Clock::now();
    lost.update(scores.best_loglik / pixels);
    const Clock::time_point t8 = Clock::now();
    if (loop.warm()) continue;
    s.predict.push_back(msBetween(t0, t1));
    s.prep.push_back(msBetween(t1, t2));
    s.likelihood.push_back(msBetween(t2, t3));
    s.weights.push_back(msBetween(t3, t4));
    s.estimate.push_back(msBetween(t4, t5));
    s.resample.push_back(msBetween(t5, t6));
    s.recover.push_back(msBetween(t6, t7));
    s.lost.push_back(msBetween(t7, t8));
    s.total.push_back(msBetween(t0, t8));
    v_n.push_back(filter->size());
    timed_s += msBetween(t0, t8) * 1e-3;
  }
  s.summarise(&row);
  row.resampled_to = static_cast<int>(median(v_n));
  return row;
}

// Localizer::step along the frames (back and forth, so that the motion stays continuous) with
// odometry and attitude from the ground truth, from a Gaussian start at the truth, at a fixed
// count of N particles: the product path, refinement included.
StepRow runLocalizerStep(const std::string& backend, bool device, const Workload& w,
                         const GmmMap& map, const FrameSet& frames, const Options& opt) {
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
  lp.T_base_cam = opticalToBase();
  lp.cuda = opt.cuda;
  if (!opt.depth_noise) lp.measurement.depth_noise.a_m = lp.measurement.depth_noise.b_per_m = 0.f;
  const int nf = static_cast<int>(frames.images.size());
  std::vector<Eigen::Isometry3d> T_map_base(nf);
  for (int f = 0; f < nf; ++f) T_map_base[f] = frames.T_map_cam[f] * lp.T_base_cam.inverse();
  const Particle start = poseToParticle(T_map_base[0]);
  lp.init.centre_m = Eigen::Vector3d(start.x_m, start.y_m, start.z_m);
  lp.init.yaw_centre_rad = start.yaw_rad;
  auto input = [&](int f, double stamp_s) {
    StepInput in;
    in.stamp_s = stamp_s;
    in.has_odometry = true;
    in.T_odom_base = T_map_base[f];
    in.has_attitude = true;
    double yaw;
    rpyFromRotation(T_map_base[f].linear(), &in.roll_rad, &in.pitch_rad, &yaw);
    in.depth = &frames.images[f];
    in.intrinsics = frames.K;
    return in;
  };
  // The first update from the protocol's start: uniform over lp.init (the paper's 4 m cube
  // around the first pose, a yaw range of pi), candidates_per_particle candidates per particle
  // scored on the first frame.
  {
    Localizer fresh(lp, map);
    row.first_update = fresh.step(input(0, 0.0)).timings;
    row.has_first_update = true;
  }
  // A lost redraw as a run with the backend's defaults makes it: the set at its tracking count
  // (N) around a pose 1 m and 0.5 rad off, judged lost on its first frame, redrawn up to the
  // default largest count (16 candidates each: half uniform over the start region against the
  // blurred map, half around the best of them).
  {
    LocalizerParams lost = lp;
    int lo = 0, hi = 0;
    defaultParticleRange(backend, &lo, &hi);
    lost.filter.min_particles = row.particles;
    lost.filter.num_particles = std::max(hi, row.particles);
    lost.lost.frames = 1;
    lost.lost.grace_frames = 0;
    Localizer kidnapped(lost, map);
    Particle off = start;
    off.x_m += 1.0;
    off.yaw_rad += 0.5;
    kidnapped.resetToPose(off, Eigen::Vector4d(0.05, 0.05, 0.05, 0.05));
    const StepResult r = kidnapped.step(input(0, 0.0));
    if (r.lost_reinitialised > 0) {
      row.redraw = r.timings.resample_ms;
      row.redrawn = r.lost_reinitialised;
    }
  }
  Localizer loc(lp, map);
  row.what = std::string("Localizer::step, ") + loc.filterName() + " filter, " +
             loc.backend().name() + " backend";
  loc.resetToPose(start, Eigen::Vector4d(0.05, 0.05, 0.05, 0.05));
  StageSamples s;
  double timed_s = 0.0;
  const int period = nf > 1 ? 2 * (nf - 1) : 1;
  for (TimedLoop loop(opt); loop.next(timed_s);) {
    const int it = loop.iteration();
    const int k = it % period;
    const int f = k < nf ? k : period - k;  // 0, 1, ..., nf - 1, nf - 2, ..., 1
    const StepResult r = loc.step(input(f, it / 30.0));
    if (r.status != StepStatus::kOk) {
      std::fprintf(stderr, "# %s: frame %d: %s (%s)\n", row.what.c_str(), f,
                   stepStatusName(r.status), r.message.c_str());
    }
    if (loop.warm()) continue;
    const StepTimings& t = r.timings;
    s.predict.push_back(t.predict_ms);
    s.prep.push_back(t.frame_prep_ms);
    s.likelihood.push_back(t.projection_membership_ms + t.likelihood_ms);
    s.weights.push_back(t.weights_ms);
    s.estimate.push_back(t.estimate_ms);
    s.resample.push_back(t.resample_ms);
    s.refine.push_back(t.refine_ms);
    s.total.push_back(t.total_ms);
    timed_s += t.total_ms * 1e-3;
  }
  s.summarise(&row);
  row.resampled_to = loc.filter().size();
  return row;
}

}  // namespace

void runSteps(const std::vector<LikelihoodBackend*>& backends, const BenchData& data,
              const Options& opt) {
  // `large` is the likelihood's workload alone; a workload whose input is absent is skipped.
  auto stepped = [&](const Workload& w) {
    return listed(opt.workloads, w.name) && w.input != WorkloadInput::kLargeMap &&
           data.absent(w).empty();
  };
  std::vector<StepRow> rows;
  for (LikelihoodBackend* b : backends) {
    const GmmMap* current = nullptr;
    for (const Workload& w : kWorkloads) {
      if (!stepped(w)) continue;
      if (current != &data.mapFor(w)) b->setMap(data.mapFor(w));
      current = &data.mapFor(w);
      for (int device = 0; device < 2; ++device) {
        if (device && b->device() == nullptr) continue;
        rows.push_back(runFilterStep(b, device != 0, w, data.framesFor(w), opt));
        std::fprintf(stderr, "# done %s / %s: %.2f ms\n", rows.back().what.c_str(), w.name,
                     rows.back().total);
      }
    }
  }
  for (LikelihoodBackend* b : backends) {
    for (const Workload& w : kWorkloads) {
      if (!stepped(w)) continue;
      for (int device = 0; device < 2; ++device) {
        if (device && b->name() != "cuda") continue;
        rows.push_back(
            runLocalizerStep(b->name(), device != 0, w, data.mapFor(w), data.framesFor(w), opt));
        std::fprintf(stderr, "# done %s / %s: %.2f ms\n", rows.back().what.c_str(), w.name,
                     rows.back().total);
      }
    }
  }
  std::printf(
      "\n# filter step: wall-clock medians (ms), each stage synchronised to its end; filter rows "
      "resample on every step (KLD count 1068..N), localizer rows resample when Neff < N/2 "
      "(fixed N) and their likelihood column is the GPU's event time (CPU: the stages' time); "
      "first update: a localizer's first step from the uniform 4 m cube start (yaw range pi): "
      "its candidates screened, the set that replaced them evaluated, the estimate refined; "
      "redraw: a lost redraw from the tracking count up to the backend's default largest count "
      "(the particles redrawn in brackets)\n");
  std::printf(
      "| step | workload | N | predict | frame prep | likelihood | weights | estimate "
      "| resample | recover | lost detector | refine | total | N after | timed | first update "
      "| redraw |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const StepRow& r : rows) {
    std::string first = "-";
    if (r.has_first_update) {
      const StepTimings& t = r.first_update;
      char text[160];
      std::snprintf(text, sizeof(text), "%.0f ms (screen %.1f, set %.1f, refine %.1f)", t.total_ms,
                    t.screen_ms, t.projection_membership_ms + t.likelihood_ms, t.refine_ms);
      first = text;
    }
    const std::string redraw = r.redraw >= 0
                                   ? std::to_string(static_cast<long long>(r.redraw + 0.5)) +
                                         " ms (" + std::to_string(r.redrawn) + ")"
                                   : std::string("-");
    std::printf(
        "| %s | %s | %d | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.4f | %.3f "
        "| **%.2f** | %d | %d | %s | %s |\n",
        r.what.c_str(), r.workload.c_str(), r.particles, r.predict, r.prep, r.likelihood, r.weights,
        r.estimate, r.resample, r.recover, r.lost, r.refine, r.total, r.resampled_to, r.timed,
        first.c_str(), redraw.c_str());
  }
}

}  // namespace bench
}  // namespace gmm_mcl
