// The particle filter's per-particle math as plain data and inline functions shared by the host
// and the device filter (GMM_MCL_HD): the 4-DoF state, prediction, uniform draws in a region,
// the camera pose of a particle and the KLD-sampling bin key. No Eigen: nvcc compiles it.
#pragma once

#include <math.h>
#include <stdint.h>

#include "gmm_mcl/common/host_device.h"
#include "gmm_mcl/common/types.h"

namespace gmm_mcl {

constexpr double kParticlePi = 3.14159265358979323846;

// x, y, z, yaw of the base in the map: the layout of Particle (pose.h), as plain data.
struct ParticleState {
  double x_m;
  double y_m;
  double z_m;
  double yaw_rad;
};

// A uniform initial distribution (InitRegion) as plain data.
struct RegionBox {
  double centre_m[3];
  double half_extent_m[3];
  double yaw_centre_rad;
  double yaw_half_range_rad;
};

// Wraps an angle into [-pi, pi) (the arithmetic of wrapAngle in pose.h).
GMM_MCL_HD double wrapAngleHD(double a_rad) {
  const double two_pi = 2.0 * kParticlePi;
  double a = fmod(a_rad + kParticlePi, two_pi);
  if (a < 0.0) a += two_pi;
  return a - kParticlePi;
}

// Odometry delta (translation_m, yaw_rad) applied in the particle's yaw frame, then process
// noise: noise[0..3] standard normal draws for x, y, z, yaw (ParticleFilter::predict).
GMM_MCL_HD void predictParticle(const double delta[4], const double noise[4], double sigma_m,
                                double sigma_rad, ParticleState* p) {
  const double c = cos(p->yaw_rad), s = sin(p->yaw_rad);
  p->x_m += c * delta[0] - s * delta[1] + sigma_m * noise[0];
  p->y_m += s * delta[0] + c * delta[1] + sigma_m * noise[1];
  p->z_m += delta[2] + sigma_m * noise[2];
  p->yaw_rad = wrapAngleHD(p->yaw_rad + delta[3] + sigma_rad * noise[3]);
}

// The point of the region at u[0..3] in [-1, 1] (ParticleFilter's uniform draw).
GMM_MCL_HD ParticleState regionPoint(const RegionBox& r, const double u[4]) {
  ParticleState p;
  p.x_m = r.centre_m[0] + r.half_extent_m[0] * u[0];
  p.y_m = r.centre_m[1] + r.half_extent_m[1] * u[1];
  p.z_m = r.centre_m[2] + r.half_extent_m[2] * u[2];
  p.yaw_rad = wrapAngleHD(r.yaw_centre_rad + r.yaw_half_range_rad * u[3]);
  return p;
}

// KLD-sampling bin of a particle: 16 bits per dimension (bins apart within +-6.5 km at 0.2 m).
GMM_MCL_HD uint64_t kldBinKey(const ParticleState& p, double inv_bin_m, double inv_bin_rad) {
  const uint64_t qx =
      static_cast<uint64_t>(static_cast<int64_t>(floor(p.x_m * inv_bin_m)) & 0xffff);
  const uint64_t qy =
      static_cast<uint64_t>(static_cast<int64_t>(floor(p.y_m * inv_bin_m)) & 0xffff);
  const uint64_t qz =
      static_cast<uint64_t>(static_cast<int64_t>(floor(p.z_m * inv_bin_m)) & 0xffff);
  const uint64_t qa = static_cast<uint64_t>(
      static_cast<int64_t>(floor((p.yaw_rad + kParticlePi) * inv_bin_rad)) & 0xffff);
  return qx | (qy << 16) | (qz << 32) | (qa << 48);
}

// The shared attitude and the camera mount: R_pitch_roll = Ry(pitch) Rx(roll), T_base_cam
// (row-major), all in double.
struct CameraMount {
  double R_pitch_roll[9];
  double R_base_cam[9];
  double t_base_cam[3];
};

// T_map_cam = (Rz(yaw) Ry(pitch) Rx(roll), (x, y, z)) * T_base_cam, composed in double and
// rounded to float once (as toRigidF(particleToPose(p, roll, pitch) * T_base_cam)).
GMM_MCL_HD RigidTransformF cameraPoseOf(const ParticleState& p, const CameraMount& m) {
  const double c = cos(p.yaw_rad), s = sin(p.yaw_rad);
  const double* A = m.R_pitch_roll;
  double R[9];  // R_map_base = Rz(yaw) * A
  for (int k = 0; k < 3; ++k) {
    R[0 + k] = c * A[0 + k] - s * A[3 + k];
    R[3 + k] = s * A[0 + k] + c * A[3 + k];
    R[6 + k] = A[6 + k];
  }
  const double* B = m.R_base_cam;
  const double* t = m.t_base_cam;
  RigidTransformF out;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) {
      out.R[r * 3 + k] = static_cast<float>(R[r * 3 + 0] * B[0 + k] + R[r * 3 + 1] * B[3 + k] +
                                            R[r * 3 + 2] * B[6 + k]);
    }
  }
  out.t[0] = static_cast<float>(R[0] * t[0] + R[1] * t[1] + R[2] * t[2] + p.x_m);
  out.t[1] = static_cast<float>(R[3] * t[0] + R[4] * t[1] + R[5] * t[2] + p.y_m);
  out.t[2] = static_cast<float>(R[6] * t[0] + R[7] * t[1] + R[8] * t[2] + p.z_m);
  return out;
}

}  // namespace gmm_mcl
