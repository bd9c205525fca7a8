// gmm_mcl_bench: the likelihood benchmark of one (backend, workload) and its table.
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "bench_tool.h"
#include "gmm_mcl/common/timing.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/sim/pose_scatter.h"

namespace gmm_mcl {
namespace bench {
namespace {

// CPU time of the whole process (all threads), milliseconds.
double processCpuMs() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

// A pose the backend evaluated, with its log-likelihood, for the exact-sum check.
struct CheckedPose {
  int frame;
  RigidTransformF T_map_cam;
  double log_likelihood;
};

// Relative error of the backend's log-likelihoods against exactFrameLogLikelihood (double
// precision, every component, the same floor and depth noise) on the host's prepared frames.
void exactErrors(const GmmMap& map, const FrameSet& frames, const FrameParams& fp,
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

}  // namespace

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

bool TimedLoop::next(double timed_s) {
  ++it_;
  warm_ = it_ < opt_.warmup;
  if (warm_) return true;
  const int timed = it_ - opt_.warmup;
  return timed < opt_.frames && !(timed >= opt_.min_timed && timed_s >= opt_.budget_s);
}

Row runWorkload(LikelihoodBackend* backend, double fp32_peak_gflops, const Workload& w,
                const GmmMap& map, const FrameSet& frames, const Options& opt) {
  Row row;
  row.backend = backend->name();
  DeviceBackend* device = backend->device();
  if (device) row.backend += opt.cuda_host_prep ? " (host prep)" : " (GPU prep)";
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
  for (TimedLoop loop(opt); loop.next(timed_s);) {
    const int f = loop.iteration() % nf;
    const std::vector<RigidTransformF> particles =
        sim::scatterPoses(frames.T_map_cam[f], row.particles, opt.spread_m, opt.spread_rad,
                          opt.seed * 7919u + static_cast<unsigned>(f));
    double prep = 0.0, total = 0.0, used_pixels = 0.0;
    const double cpu0 = processCpuMs();
    if (device && !opt.cuda_host_prep) {
      // Frame preparation on the device: the update uploads the raw image.
      const auto t0 = std::chrono::steady_clock::now();
      device->evaluateImage(frames.images[f], frames.K, fp, particles, mp, &out);
      const auto t2 = std::chrono::steady_clock::now();
      prep = device->lastFramePrepMs();
      total = std::chrono::duration<double, std::milli>(t2 - t0).count();
      used_pixels = device->lastFramePixels();
    } else {
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
    if (loop.warm()) continue;
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
    if (device) xfer_ms.push_back(device->lastTransferMs());
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
  if (fp32_peak_gflops > 0 && device) {
    row.peak_fraction =
        row.kernel_gevals_per_s * device->deviceInfo().flops_per_evaluation / fp32_peak_gflops;
  }
  exactErrors(map, frames, fp, mp, checked, check_per_frame, &row);
  return row;
}

void printWorkloadTable(const std::vector<Row>& rows) {
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
}

}  // namespace bench
}  // namespace gmm_mcl
