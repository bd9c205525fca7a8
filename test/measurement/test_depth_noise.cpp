// The depth-noise model of the likelihood (gmm_mcl/measurement/depth_noise.h): the float32
// evaluation form of a component convolved with the axial noise along its viewing ray, against
// the double-precision density of Sigma + s^2 r r^T; why the membership does not change; and
// what it is for: a map sharper than the sensor scores the true pose near the map's own level.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>

#include "gmm_mcl/filter/lost_detector.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/measurement/depth_noise.h"
#include "gmm_mcl/measurement/likelihood.h"
#include "gmm_mcl/measurement/projection.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

constexpr double kLog2Pi = 1.8378770664093453;

Eigen::Matrix3d unpack(const float s[6]) {
  return (Eigen::Matrix3d() << s[0], s[1], s[2], s[1], s[3], s[4], s[2], s[4], s[5]).finished();
}

// A camera somewhere in the room looking in a random direction.
Eigen::Isometry3d randomCamera(std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(3.0 * u(*rng), 2.0 * u(*rng), 1.5 + 0.8 * u(*rng));
  T.linear() = (Eigen::AngleAxisd(M_PI * u(*rng), Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(0.3 * u(*rng), Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(0.3 * u(*rng), Eigen::Vector3d::UnitX()))
                   .toRotationMatrix() *
               sim::defaultBaseToCamera().linear();
  return T;
}

// Each component of the synthetic map seen from `cameras` random cameras, drawn from rng:
// f(T_map_cam, T_cam_map, component, its mean in the map frame, in the camera frame).
template <typename F>
void forEachComponentView(int cameras, std::mt19937_64* rng, F&& f) {
  for (int pose = 0; pose < cameras; ++pose) {
    const Eigen::Isometry3d T_map_cam = randomCamera(rng);
    const RigidTransformF T_cam_map = toRigidF(T_map_cam.inverse());
    for (const ComponentF& c : test::world().map.packed()) {
      const Eigen::Vector3d mu(c.mean_m[0], c.mean_m[1], c.mean_m[2]);
      f(T_map_cam, T_cam_map, c, mu, Eigen::Vector3d(T_map_cam.inverse() * mu));
    }
  }
}

TEST(DepthNoiseTest, EvaluationFormMatchesTheConvolvedDensity) {
  const DepthNoiseModel noise;  // Kinect v1 defaults
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  double worst = 0.0, worst_thin_dir_ratio = 1e9, worst_vectorised = 0.0;
  int formed = 0;
  // The CPU backend's forms (noisyEvalComponents: all components of a pose in one vectorised
  // loop, sqrtVec and logPositive for sqrtf and logf) against the same reference.
  const auto& comps = test::world().map.packed();
  std::vector<EvalComponentF> base, vectorised;
  makeEvalComponents(comps, &base);
  const std::vector<char> valid(comps.size(), 1);
  RigidTransformF formed_for{};
  forEachComponentView(
      20, &rng,
      [&](const Eigen::Isometry3d& T_map_cam, const RigidTransformF& T_cam_map, const ComponentF& c,
          const Eigen::Vector3d& mu, const Eigen::Vector3d& m) {
        if (vectorised.empty() || std::memcmp(&formed_for, &T_cam_map, sizeof(T_cam_map)) != 0) {
          noisyEvalComponents(comps, base, valid, T_cam_map, noise, &vectorised);
          formed_for = T_cam_map;
        }
        const size_t index = static_cast<size_t>(&c - comps.data());
        const EvalComponentF& v = vectorised[index];
        // Value-initialised: GCC does not see that the ASSERT below guards their use.
        EvalComponentF e{}, e2{};
        const bool ok = makeNoisyEvalComponent(c, T_cam_map, noise, kEvalScaleNats, &e);
        ASSERT_EQ(ok, m.z() > 0.0);
        // Behind the camera: the noise-free form.
        if (!ok) {
          EXPECT_EQ(std::memcmp(&v, &base[index], sizeof(v)), 0) << index;
        }
        // Components whose mean projects into a VGA image (585 px focal length): the ones a
        // patch can use. Beside the image the ray turns towards the image plane, |m| / z grows
        // without bound and so does s.
        if (!ok || m.z() < 0.1 || std::abs(m.x() / m.z()) > 0.6 || std::abs(m.y() / m.z()) > 0.45) {
          return;
        }
        ASSERT_TRUE(makeNoisyEvalComponent(c, T_cam_map, noise, kEvalScaleLog2, &e2));
        ++formed;
        // Reference in double: Sigma + s^2 r r^T, s = sigma(z) |m| / z.
        const double d = m.z() - noise.z0_m;
        const double s = (noise.a_m + noise.b_per_m * d * d) * m.norm() / m.z();
        const Eigen::Vector3d r = (mu - T_map_cam.translation()).normalized();
        const Eigen::Matrix3d cov = unpack(c.cov_m2) + s * s * r * r.transpose();
        const Eigen::Matrix3d L = cov.llt().matrixL();
        const double log_norm = c.log_weight - 0.5 * std::log(cov.determinant());
        EXPECT_NEAR(e.log_norm, log_norm, 1e-4 * std::max(1.0, std::abs(log_norm)));
        EXPECT_NEAR(v.log_norm, log_norm, 1e-4 * std::max(1.0, std::abs(log_norm)));
        // The variance along the ray grew by s^2 (the component is now at least as thick as the
        // sensor's noise along the ray).
        worst_thin_dir_ratio = std::min(worst_thin_dir_ratio, r.dot(cov * r) / (s * s));
        for (int k = 0; k < 10; ++k) {
          Eigen::Vector3d z(n01(rng), n01(rng), n01(rng));
          if (z.norm() > 3.0) z *= 3.0 / z.norm();
          const Eigen::Vector3d p = mu + L * z;
          const double ref = log_norm - 0.5 * z.squaredNorm();
          const float px = static_cast<float>(p.x()), py = static_cast<float>(p.y()),
                      pz = static_cast<float>(p.z());
          worst = std::max(worst, std::abs(evalLogDensity(e, px, py, pz) - ref));
          worst = std::max(worst, std::abs(evalLogDensity(e2, px, py, pz) / kEvalScaleLog2 - ref));
          worst_vectorised =
              std::max(worst_vectorised, std::abs(evalLogDensity(v, px, py, pz) - ref));
        }
      });
  std::printf(
      "[ measured ] %d noisy evaluation forms: worst |ln density error| %.2e nats "
      "within 3 sigma (vectorised: %.2e); variance along the ray >= %.3f s^2\n",
      formed, worst, worst_vectorised, worst_thin_dir_ratio);
  EXPECT_GT(formed, 1000);
  EXPECT_LT(worst, 2e-4);  // float rounding of map-frame points (DESIGN.md: ~1e-4 per pixel)
  EXPECT_LT(worst_vectorised, 2e-4);
  EXPECT_GE(worst_thin_dir_ratio, 1.0 - 1e-9);
}

TEST(DepthNoiseTest, RayInflationLeavesTheProjectionUnchanged) {
  // The noise lies along the ray through the mean, which the pinhole Jacobian maps to zero: the
  // projected 2D covariance, and so the patch membership, is the noise-free one.
  const Intrinsics K = test::vgaCamera();
  std::mt19937_64 rng(5);
  double worst = 0.0;
  int compared = 0;
  forEachComponentView(
      10, &rng,
      [&](const Eigen::Isometry3d& T_map_cam, const RigidTransformF& T_cam_map, const ComponentF& c,
          const Eigen::Vector3d& mu, const Eigen::Vector3d& m) {
        if (m.z() < 0.1) return;
        const Eigen::Vector3d r = (mu - T_map_cam.translation()).normalized();
        const Eigen::Matrix3d cov = unpack(c.cov_m2) + 0.05 * 0.05 * r * r.transpose();  // 5 cm
        ComponentF wide = c;
        const float packed[6] = {static_cast<float>(cov(0, 0)), static_cast<float>(cov(0, 1)),
                                 static_cast<float>(cov(0, 2)), static_cast<float>(cov(1, 1)),
                                 static_cast<float>(cov(1, 2)), static_cast<float>(cov(2, 2))};
        for (int k = 0; k < 6; ++k) wide.cov_m2[k] = packed[k];
        ProjectedComponent a, b;
        ASSERT_TRUE(projectComponent(c, T_cam_map, K, 0.1f, 3.f, 22.6f, &a));
        ASSERT_TRUE(projectComponent(wide, T_cam_map, K, 0.1f, 3.f, 22.6f, &b));
        const double scale = std::max({1.0, static_cast<double>(std::abs(a.cov_uu)),
                                       static_cast<double>(std::abs(a.cov_vv))});
        worst = std::max({worst, std::abs(a.cov_uu - b.cov_uu) / scale,
                          std::abs(a.cov_uv - b.cov_uv) / scale,
                          std::abs(a.cov_vv - b.cov_vv) / scale});
        ++compared;
      });
  std::printf(
      "[ measured ] %d components: projected covariance changed by at most %.2e "
      "(relative) by 5 cm of noise along the ray\n",
      compared, worst);
  EXPECT_GT(compared, 1000);
  EXPECT_LT(worst, 1e-3);  // float rounding of the larger covariance entries
}

TEST(DepthNoiseTest, ZeroNoiseUsesTheNoiseFreeForm) {
  const auto& comps = test::world().map.packed();
  std::vector<EvalComponentF> base, out;
  makeEvalComponents(comps, &base);
  const std::vector<char> valid(comps.size(), 1);
  DepthNoiseModel off;
  off.a_m = off.b_per_m = 0.f;
  EXPECT_FALSE(off.enabled());
  const RigidTransformF T = toRigidF(Eigen::Isometry3d::Identity());
  EXPECT_EQ(noisyEvalComponents(comps, base, valid, T, off, &out), base.data());
  MeasurementParams bad;
  bad.depth_noise.b_per_m = -1.f;
  EXPECT_NE(bad.validate().find("depth_noise"), std::string::npos);
  bad.depth_noise.b_per_m = std::nanf("");
  EXPECT_NE(bad.validate().find("depth_noise"), std::string::npos);
}

TEST(DepthNoiseTest, SharpMapScoresTheTruthNearItsOwnLevel) {
  // A map 2 mm thick (a mesh-like source) and a sensor with sigma = 3 mm z^2 (about 1-3 cm at
  // 2-3 m): without the noise model the true pose scores far below the map's own expected
  // log-density (and many pixels at the floor); with it, near that level; the likelihood still
  // peaks at the true pose.
  const sim::BoxScene scene = sim::makeDefaultScene();
  const GmmMap sharp = sim::tileScene(scene, 0.4, 0.002);
  const Intrinsics K = test::smallCamera();
  const Eigen::Isometry3d T_map_base = test::referenceBasePose();
  const Eigen::Isometry3d T_map_cam = T_map_base * sim::defaultBaseToCamera();
  FrameParams fp;
  fp.pixel_stride = 4;
  sim::DepthNoise sensor;
  sensor.sigma_at_1m_m = 0.003;
  std::mt19937_64 rng(11);
  const DepthImage img =
      sim::renderDepth(scene, K, T_map_cam, DepthEncoding::kFloat32Metres, 8.0, sensor, &rng);
  const DepthFrame frame = prepareFrame(img, K, fp);
  MeasurementParams off, on;
  off.depth_noise.a_m = off.depth_noise.b_per_m = 0.f;
  on.depth_noise.a_m = 0.f;
  on.depth_noise.b_per_m = 0.003f;
  on.depth_noise.z0_m = 0.f;
  const double self = mapSelfLogDensity(sharp, off.floor_log_density);
  // The level the noise model predicts (the map convolved with the noise at 2 m along each
  // component's normal): the lost detector's starting reference.
  const double self_noisy = mapSelfLogDensity(sharp, on.floor_log_density, on.depth_noise);
  LikelihoodScratch scratch;
  const FrameLikelihood l_off =
      poseLogLikelihood(sharp.packed(), frame, toRigidF(T_map_cam), off, &scratch);
  const FrameLikelihood l_on =
      poseLogLikelihood(sharp.packed(), frame, toRigidF(T_map_cam), on, &scratch);
  const double px = l_on.pixels;
  std::printf(
      "[ measured ] 2 mm map, noisy frame (%d px): map's own level %.2f nats/px (%.2f "
      "with the noise at 2 m); true pose %.2f without the noise model (%.0f%% at the "
      "floor), %.2f with it (%.0f%%)\n",
      l_on.pixels, self, self_noisy, l_off.log_likelihood / px, 100.0 * l_off.floor_hits / px,
      l_on.log_likelihood / px, 100.0 * l_on.floor_hits / px);
  EXPECT_LT(self_noisy, self);
  EXPECT_NEAR(l_on.log_likelihood / px, self_noisy, 1.5);
  EXPECT_LT(l_off.log_likelihood / px, self - 4.0);
  EXPECT_GT(l_off.floor_hits, 0.25 * px);
  EXPECT_GT(l_on.log_likelihood / px, self - 3.0);
  EXPECT_LT(l_on.floor_hits, 0.05 * px);
  // Peak at the truth in x and yaw sweeps (+-20 cm, +-0.2 rad).
  double roll, pitch, yaw;
  rpyFromRotation(T_map_base.linear(), &roll, &pitch, &yaw);
  for (int axis = 0; axis < 2; ++axis) {
    for (int k = -4; k <= 4; ++k) {
      if (k == 0) continue;
      Particle p = poseToParticle(T_map_base);
      if (axis == 0)
        p.x_m += 0.05 * k;
      else
        p.yaw_rad += 0.05 * k;
      const Eigen::Isometry3d T = particleToPose(p, roll, pitch) * sim::defaultBaseToCamera();
      const FrameLikelihood l = poseLogLikelihood(sharp.packed(), frame, toRigidF(T), on, &scratch);
      EXPECT_LT(l.log_likelihood, l_on.log_likelihood) << "axis " << axis << " step " << k;
    }
  }
}

}  // namespace
}  // namespace gmm_mcl
