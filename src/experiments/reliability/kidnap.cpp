#include "gmm_mcl/experiments/reliability/kidnap.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <stdexcept>
#include <utility>

#include "gmm_mcl/datasets/sequence_base.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/replay/replay.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/mesh_renderer.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace reliability {
namespace {

// A built-in scene along sim::makeTrajectory, seen from sim::defaultBaseToCamera; `render`
// draws one depth image of the camera pose from the trial's random stream.
class SimSceneSource : public FrameSource {
 public:
  using Render = std::function<DepthImage(const Eigen::Isometry3d&, std::mt19937_64*)>;
  SimSceneSource(std::string name, const Intrinsics& K, int frames, GmmMap map, Render render)
      : name_(std::move(name)),
        K_(K),
        map_(std::move(map)),
        render_(std::move(render)),
        T_base_cam_(sim::defaultBaseToCamera()),
        truth_(sim::makeTrajectory(frames)) {}
  int size() const override { return static_cast<int>(truth_.size()); }
  const Eigen::Isometry3d& truthBase(int i) const override { return truth_.at(i); }
  DepthImage depth(int i, std::mt19937_64* rng) const override {
    return render_(truth_.at(i) * T_base_cam_, rng);
  }
  const Intrinsics& intrinsics() const override { return K_; }
  const Eigen::Isometry3d& baseToCamera() const override { return T_base_cam_; }
  const GmmMap& map() const override { return map_; }
  std::string name() const override { return name_; }

 private:
  std::string name_;
  Intrinsics K_;
  GmmMap map_;
  Render render_;
  Eigen::Isometry3d T_base_cam_;
  std::vector<Eigen::Isometry3d> truth_;
};

// Any data-set folder (replay's readers), gravity-aligned like gmm_mcl_replay; the frame rate
// from the stamps.
class SequenceSource : public FrameSource {
 public:
  SequenceSource(std::unique_ptr<Sequence> seq, const std::string& map_path, std::string name)
      : seq_(std::move(seq)), T_base_cam_(opticalToBase()), name_(std::move(name)) {
    map_ = rotateMap(loadMap(map_path), seq_->R_aligned_world(), map_path + " (gravity-aligned)");
    truth_ = alignedBaseTrajectory(*seq_, seq_->size());
    const int n = seq_->size();
    if (n > 1) rate_hz_ = (n - 1) / (seq_->stampS(n - 1) - seq_->stampS(0));
  }
  int size() const override { return seq_->size(); }
  const Eigen::Isometry3d& truthBase(int i) const override { return truth_.at(i); }
  DepthImage depth(int i, std::mt19937_64*) const override { return seq_->loadDepth(i); }
  const Intrinsics& intrinsics() const override { return seq_->intrinsics(); }
  const Eigen::Isometry3d& baseToCamera() const override { return T_base_cam_; }
  const GmmMap& map() const override { return map_; }
  double frameRateHz() const override { return rate_hz_; }
  std::string name() const override { return name_; }

 private:
  std::unique_ptr<Sequence> seq_;
  Eigen::Isometry3d T_base_cam_;
  std::string name_;
  GmmMap map_;
  std::vector<Eigen::Isometry3d> truth_;
  double rate_hz_ = 30.0;
};

bool inRegion(const Particle& p, const Particle& centre, const KidnapParams& params) {
  const double margin = 0.9;  // keep clear of the region's edge
  return std::abs(p.x_m - centre.x_m) < margin * params.region_half_extent_m &&
         std::abs(p.y_m - centre.y_m) < margin * params.region_half_extent_m &&
         std::abs(p.z_m - centre.z_m) < margin * params.region_half_extent_m &&
         std::abs(wrapAngle(p.yaw_rad - centre.yaw_rad)) <
             margin * params.region_yaw_half_range_rad;
}

double distance(const Particle& a, const Particle& b) {
  return std::sqrt(std::pow(a.x_m - b.x_m, 2) + std::pow(a.y_m - b.y_m, 2) +
                   std::pow(a.z_m - b.z_m, 2));
}

}  // namespace

std::unique_ptr<FrameSource> makeBoxSceneSource(const Intrinsics& K, int frames) {
  auto scene = std::make_shared<const sim::BoxScene>(sim::makeDefaultScene());
  auto render = [scene, K](const Eigen::Isometry3d& T_map_cam, std::mt19937_64* rng) {
    // Kinect-like axial noise (1.5 mm at 1 m, growing with z^2) and 2% dropout.
    return sim::renderDepth(*scene, K, T_map_cam, DepthEncoding::kMono16Millimetres, 9.0,
                            sim::DepthNoise{0.0015, 0.02}, rng);
  };
  return std::make_unique<SimSceneSource>("box", K, frames, sim::tileScene(*scene, 0.4, 0.015),
                                          render);
}

// The built-in mesh scene (boxes and cylinders) rendered through the structured-light sensor
// model (sim::SensorNoiseParams defaults), seeded per frame from the trial's stream.
std::unique_ptr<FrameSource> makeSyntheticSource(const Intrinsics& K, int frames) {
  auto scene = std::make_shared<const sim::MeshScene>(sim::makeDefaultMeshScene());
  auto render = [scene, K](const Eigen::Isometry3d& T_map_cam, std::mt19937_64* rng) {
    const sim::SensorNoiseParams noise;
    return sim::renderDepth(*scene->bvh, K, T_map_cam, DepthEncoding::kMono16Millimetres, 9.0,
                            &noise, (*rng)());
  };
  return std::make_unique<SimSceneSource>("synthetic", K, frames,
                                          sim::tileScene(scene->primitives, 0.4, 0.015), render);
}

std::unique_ptr<FrameSource> makeSevenScenesSource(const std::string& data_dir,
                                                   const std::string& map_path) {
  return makeSequenceSource("7scenes", data_dir, map_path);
}

std::unique_ptr<FrameSource> makeSequenceSource(const std::string& format,
                                                const std::string& data_dir,
                                                const std::string& map_path) {
  return std::make_unique<SequenceSource>(openSequence(format, data_dir), map_path, format);
}

KidnapResult planKidnap(const FrameSource& src, const KidnapParams& params, uint64_t seed) {
  const int n = src.size();
  const int span = params.track_frames + params.after_frames;
  if (params.track_frames == 1 || params.after_frames < params.hold_frames || n < span) {
    throw std::runtime_error(src.name() + ": too few frames for a kidnap trial");
  }
  std::mt19937_64 rng(seed * 104729 + 3);
  if (params.track_frames == 0) {  // global localisation from the region around the start
    KidnapResult r;
    r.seed = seed;
    r.start_frame = r.from_frame = r.to_frame =
        params.start_frame >= 0 ? std::min(params.start_frame, n - span)
                                : std::uniform_int_distribution<int>(0, n - span)(rng);
    return r;
  }
  for (int attempt = 0; attempt < 200; ++attempt) {
    const int drawn = std::uniform_int_distribution<int>(0, n - span)(rng);
    const int start = params.start_frame >= 0 ? std::min(params.start_frame, n - span) : drawn;
    const int from = start + params.track_frames;  // first frame shown from elsewhere
    const Particle centre = poseToParticle(src.truthBase(start));
    const Particle last = poseToParticle(src.truthBase(from - 1));
    std::vector<int> candidates;
    for (int j = 0; j + params.after_frames <= n; ++j) {
      const Particle p = poseToParticle(src.truthBase(j));
      if (std::abs(j - from) > params.hold_frames && inRegion(p, centre, params) &&
          distance(p, last) >= params.min_jump_m) {
        candidates.push_back(j);
      }
    }
    if (candidates.empty()) continue;
    KidnapResult r;
    r.seed = seed;
    r.start_frame = start;
    r.from_frame = from;
    r.to_frame = candidates[std::uniform_int_distribution<size_t>(0, candidates.size() - 1)(rng)];
    const Particle to = poseToParticle(src.truthBase(r.to_frame));
    r.jump_m = distance(to, last);
    r.jump_yaw_rad = wrapAngle(to.yaw_rad - last.yaw_rad);
    return r;
  }
  throw std::runtime_error(src.name() + ": no kidnap destination inside the recovery region");
}

KidnapResult runKidnapTrial(const FrameSource& src, const KidnapParams& params, uint64_t seed) {
  KidnapResult r = planKidnap(src, params, seed);
  const int total = params.track_frames + params.after_frames;
  auto sourceIndex = [&](int k) {
    return k < params.track_frames ? r.start_frame + k : r.to_frame + (k - params.track_frames);
  };
  LocalizerParams lp = params.localizer;
  lp.T_base_cam = src.baseToCamera();
  lp.filter.seed = seed;
  const Particle start = poseToParticle(src.truthBase(r.start_frame));
  lp.init.centre_m = Eigen::Vector3d(start.x_m, start.y_m, start.z_m);
  lp.init.half_extent_m.setConstant(params.region_half_extent_m);
  lp.init.yaw_centre_rad = start.yaw_rad;
  lp.init.yaw_half_range_rad = params.region_yaw_half_range_rad;
  Localizer loc(lp, src.map());
  if (params.track_frames > 0) {
    loc.resetToPose(start, Eigen::Vector4d(0.05, 0.05, 0.05, 0.05));
  } else if (params.whole_map_start) {
    loc.reset(loc.mapBounds());  // global localisation over the whole map, full yaw
  }

  std::mt19937_64 rng(seed * 7919 + 17);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::Isometry3d odom = src.truthBase(r.start_frame);
  // The gyro feels the turns the odometry reports: its own random draws (the frames' unchanged).
  OdometrySynthesizer gyro(ProtocolNoise(), seed);
  double felt_yaw = poseToParticle(odom).yaw_rad;
  std::vector<double> errors(total);
  double total_ms = 0.0;
  for (int k = 0; k < total; ++k) {
    const int i = sourceIndex(k);
    if (k > 0) {
      // At the kidnap, odometry reports the motion the old trajectory would have made.
      const int a = k == params.track_frames ? sourceIndex(k - 1) - 1 : sourceIndex(k - 1);
      const int b = k == params.track_frames ? sourceIndex(k - 1) : i;
      Eigen::Isometry3d delta = src.truthBase(a).inverse() * src.truthBase(b);
      delta.translation() += params.odom_sigma_m * Eigen::Vector3d(g(rng), g(rng), g(rng));
      delta.linear() = delta.linear() * Eigen::AngleAxisd(params.odom_sigma_yaw_rad * g(rng),
                                                          Eigen::Vector3d::UnitZ())
                                            .toRotationMatrix();
      odom = odom * delta;
      felt_yaw += wrapAngle(poseToParticle(src.truthBase(b)).yaw_rad -
                            poseToParticle(src.truthBase(a)).yaw_rad);
      if (k == params.track_frames) {
        // The odometry's tilt stays the body's own: a visual-inertial or wheel-and-IMU odometry
        // takes roll and pitch from gravity, so a kidnap leaves its position and yaw wrong but
        // not its attitude. Composing the new trajectory's body-frame steps onto the old pose's
        // tilt would report them tilted by the difference (tens of degrees between two places
        // of a hand-held sequence), a drift no real odometry has.
        double r_true, p_true, y_true, r_odom, p_odom, y_odom;
        rpyFromRotation(src.truthBase(i).linear(), &r_true, &p_true, &y_true);
        rpyFromRotation(odom.linear(), &r_odom, &p_odom, &y_odom);
        odom.linear() = rotationFromRpy(r_true, p_true, y_odom);
      }
    }
    const DepthImage depth = src.depth(i, &rng);
    double roll, pitch, yaw;
    rpyFromRotation(src.truthBase(i).linear(), &roll, &pitch, &yaw);
    StepInput in;
    in.stamp_s = k / src.frameRateHz();
    in.has_odometry = params.odometry;
    in.T_odom_base = odom;
    if (!params.odometry && params.gyro) {
      const Eigen::Isometry3d felt(Eigen::AngleAxisd(felt_yaw, Eigen::Vector3d::UnitZ()));
      in.gyro_yaw_rad = gyro.gyroYaw(felt, k > 0 ? 1.0 / src.frameRateHz() : 0.0);
      in.has_gyro_yaw = k > 0;
    }
    in.has_attitude = true;
    in.roll_rad = roll + params.attitude_sigma_rad * g(rng);
    in.pitch_rad = pitch + params.attitude_sigma_rad * g(rng);
    in.depth = &depth;
    in.intrinsics = src.intrinsics();
    const StepResult step = loc.step(in);
    total_ms += step.timings.total_ms;
    if (step.lost) ++r.lost_events;
    r.augmented_reinitialised += step.reinitialised;
    const Particle& est = step.estimate.mean;
    if (!std::isfinite(est.x_m) || !std::isfinite(est.y_m) || !std::isfinite(est.z_m) ||
        !std::isfinite(est.yaw_rad) || !step.estimate.covariance.allFinite()) {
      r.any_non_finite = true;
    }
    errors[k] = distance(est, poseToParticle(src.truthBase(i)));
    KidnapFrame f;
    f.source_frame = i;
    f.error_m = errors[k];
    if (step.refinement.refined) {
      f.refined_error_m = distance(step.refinement.pose, poseToParticle(src.truthBase(i)));
    }
    f.best_loglik_px = step.best_loglik_per_pixel;
    f.reference_px = step.reference_loglik_per_pixel;
    f.particles = step.particles;
    f.lost_redrawn = step.lost_reinitialised;
    const Eigen::Matrix<double, 6, 6>& C = step.estimate.covariance;
    f.position_sigma_m = std::sqrt(std::max({C(0, 0), C(1, 1), C(2, 2)}));
    f.neff = step.neff;
    r.frames.push_back(f);
    r.final_best_loglik_px = step.best_loglik_per_pixel;
    r.final_reference_px = step.reference_loglik_per_pixel;
  }
  r.mean_step_ms = total_ms / total;
  r.error_before_m = params.track_frames > 0 ? errors[params.track_frames - 1] : 0.0;
  r.final_error_m = errors.back();
  // Recovery: the first frame after the kidnap from which the error stays below the threshold
  // for hold_frames frames.
  for (int k = params.track_frames; k + params.hold_frames <= total; ++k) {
    bool hold = true;
    for (int m = k; m < k + params.hold_frames && hold; ++m) {
      hold = errors[m] < params.recovered_below_m;
    }
    if (hold) {
      r.recovery_s = (k - params.track_frames) / src.frameRateHz();
      double sq = 0.0;
      for (int m = k; m < total; ++m) sq += errors[m] * errors[m];
      r.ate_after_m = std::sqrt(sq / (total - k));
      break;
    }
  }
  r.recovered = r.recovery_s >= 0.0 && r.recovery_s <= params.max_recovery_s &&
                r.final_error_m < params.recovered_below_m && !r.any_non_finite;
  return r;
}

}  // namespace reliability
}  // namespace gmm_mcl
