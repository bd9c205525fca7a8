#include "gmm_mcl/filter/params.h"

#include <cmath>
#include <sstream>

#include "gmm_mcl/common/enum_names.h"

namespace gmm_mcl {

namespace {

const EnumName<WeightingMode> kWeightingNames[] = {{"paper", WeightingMode::kPaper},
                                                   {"tempered", WeightingMode::kTempered}};

}  // namespace

bool parseWeightingMode(const std::string& name, WeightingMode* out) {
  return parseEnumName(name, kWeightingNames, out);
}

const char* weightingModeName(WeightingMode mode) { return enumNameOf(mode, kWeightingNames); }

std::string InitRegion::validate() const {
  std::ostringstream err;
  if (!centre_m.allFinite()) err << "init centre must be finite; ";
  if (!half_extent_m.allFinite() || (half_extent_m.array() < 0.0).any()) {
    err << "init half extents must be finite and >= 0; ";
  }
  if (!std::isfinite(yaw_centre_rad)) err << "init yaw centre must be finite; ";
  if (!(yaw_half_range_rad >= 0.0) || yaw_half_range_rad > M_PI) {
    err << "init yaw half range must be in [0, pi] (got " << yaw_half_range_rad << "); ";
  }
  return err.str();
}

std::string ParticleFilterParams::validate() const {
  std::ostringstream err;
  auto positive = [&err](const char* name, double v) {
    if (!(v > 0.0) || !std::isfinite(v)) err << name << " must be positive (got " << v << "); ";
  };
  auto non_negative = [&err](const char* name, double v) {
    if (!(v >= 0.0) || !std::isfinite(v)) err << name << " must be >= 0 (got " << v << "); ";
  };
  if (num_particles < 1) err << "num_particles must be >= 1 (got " << num_particles << "); ";
  if (min_particles < 0 || min_particles > num_particles) {
    err << "min_particles must be in [0, num_particles] (got " << min_particles << "); ";
  }
  positive("kld_epsilon", kld_epsilon);
  positive("kld_z", kld_z);
  positive("kld_bin_m", kld_bin_m);
  positive("kld_bin_rad", kld_bin_rad);
  non_negative("sigma_translation_m", sigma_translation_m);
  non_negative("sigma_yaw_rad", sigma_yaw_rad);
  non_negative("alpha_slow", alpha_slow);
  non_negative("alpha_fast", alpha_fast);
  if (alpha_fast > 1.0 || alpha_slow > 1.0) err << "alpha_slow and alpha_fast must be <= 1; ";
  if (alpha_slow > 0.0 && !(alpha_slow < alpha_fast)) {
    err << "alpha_slow (" << alpha_slow << ") must be smaller than alpha_fast (" << alpha_fast
        << "), or 0 to disable recovery; ";
  }
  if (!(recovery_threshold > 0.0 && recovery_threshold <= 1.0)) {
    err << "recovery_threshold must be in (0, 1] (got " << recovery_threshold << "); ";
  }
  positive("temperature", temperature);
  if (!(neff_floor_fraction >= 0.0 && neff_floor_fraction < 1.0)) {
    err << "neff_floor_fraction must be in [0, 1) (got " << neff_floor_fraction << "); ";
  }
  non_negative("paper_min_nll_per_pixel", paper_min_nll_per_pixel);
  if (resample_groups < 1 || resample_groups > (adaptive() ? min_particles : num_particles)) {
    err << "resample_groups must be in [1, num_particles] (got " << resample_groups << "); ";
  }
  if (!(resample_neff_fraction >= 0.0 && resample_neff_fraction <= 1.0)) {
    err << "resample_neff_fraction must be in [0, 1] (got " << resample_neff_fraction << "); ";
  }
  non_negative("attitude_sigma_rad", attitude_sigma_rad);
  return err.str();
}

int kldParticleBound(int k, double epsilon, double z) {
  if (k <= 1) return 1;
  const double a = 2.0 / (9.0 * (k - 1));
  const double b = 1.0 - a + std::sqrt(a) * z;
  return static_cast<int>(std::ceil((k - 1) / (2.0 * epsilon) * b * b * b));
}

void defaultParticleRange(const std::string& backend, int* min_particles, int* max_particles) {
  *min_particles = kDefaultParticleCount;
  *max_particles = backend == "cuda" ? 100000 : 3000;
}

std::string LostDetectionParams::validate() const {
  std::ostringstream err;
  if (!(margin_nats >= 0.0) || !std::isfinite(margin_nats)) {
    err << "lost.margin_nats must be >= 0 (got " << margin_nats << "); ";
  }
  if (frames < 1) err << "lost.frames must be >= 1 (got " << frames << "); ";
  if (grace_frames < 0) err << "lost.grace_frames must be >= 0 (got " << grace_frames << "); ";
  auto rate = [&err](const char* name, double v) {
    if (!(v > 0.0 && v <= 1.0)) err << name << " must be in (0, 1] (got " << v << "); ";
  };
  rate("lost.reference_rate_up", reference_rate_up);
  rate("lost.reference_rate_down", reference_rate_down);
  if (!(local_candidate_fraction >= 0.0 && local_candidate_fraction < 1.0)) {
    err << "lost.local_candidate_fraction must be in [0, 1) (got " << local_candidate_fraction
        << "); ";
  }
  if (!(elite_fraction > 0.0 && elite_fraction <= 1.0)) {
    err << "lost.elite_fraction must be in (0, 1] (got " << elite_fraction << "); ";
  }
  if (local_levels < 1 || local_levels > 4) {
    err << "lost.local_levels must be in [1, 4] (got " << local_levels << "); ";
  }
  if (!(start_local_stage_min_area_m2 >= 0.0)) {
    err << "lost.start_local_stage_min_area_m2 must be >= 0 (got " << start_local_stage_min_area_m2
        << "); ";
  }
  if (start_places < 0 || start_places > 100000) {
    err << "lost.start_places must be in [0, 100000] (got " << start_places << "); ";
  }
  if (start_place_frames < 1 || start_place_frames > 100000) {
    err << "lost.start_place_frames must be in [1, 100000] (got " << start_place_frames << "); ";
  }
  if (!(redraw_blur_m >= 0.0) || !std::isfinite(redraw_blur_m)) {
    err << "lost.redraw_blur_m must be >= 0 (got " << redraw_blur_m << "); ";
  }
  if (!(redraw_merge_m >= 0.0) || !std::isfinite(redraw_merge_m)) {
    err << "lost.redraw_merge_m must be >= 0 (got " << redraw_merge_m << "); ";
  }
  if (rival_check_frames < 0) {
    err << "lost.rival_check_frames must be >= 0 (got " << rival_check_frames << "); ";
  }
  if (!(rival_radius_m > 0.0) || !std::isfinite(rival_radius_m)) {
    err << "lost.rival_radius_m must be positive (got " << rival_radius_m << "); ";
  }
  if (!(rival_yaw_rad >= 0.0) || !(rival_yaw_rad <= 3.15)) {
    err << "lost.rival_yaw_rad must be in [0, 3.15] (got " << rival_yaw_rad << "); ";
  }
  if (rival_candidates < 1 || rival_candidates > 1000000) {
    err << "lost.rival_candidates must be in [1, 1000000] (got " << rival_candidates << "); ";
  }
  if (rival_places < 1 || rival_places > 1000) {
    err << "lost.rival_places must be in [1, 1000] (got " << rival_places << "); ";
  }
  if (rival_frames < 1 || rival_frames > 1000) {
    err << "lost.rival_frames must be in [1, 1000] (got " << rival_frames << "); ";
  }
  if (!(rival_margin_nats >= 0.0) || !std::isfinite(rival_margin_nats)) {
    err << "lost.rival_margin_nats must be >= 0 (got " << rival_margin_nats << "); ";
  }
  if (coarse_pixels < 0) err << "lost.coarse_pixels must be >= 0 (got " << coarse_pixels << "); ";
  if (!(local_sigma_m > 0.0) || !(local_sigma_rad > 0.0)) {
    err << "lost.local_sigma_m and lost.local_sigma_rad must be positive; ";
  }
  if (!(reference_max_drop_nats >= 0.0) || !std::isfinite(reference_max_drop_nats)) {
    err << "lost.reference_max_drop_nats must be >= 0 (got " << reference_max_drop_nats << "); ";
  }
  rate("lost.reinit_fraction", reinit_fraction);
  if (candidates_per_particle < 1 || candidates_per_particle > 1000) {
    err << "lost.candidates_per_particle must be in [1, 1000] (got " << candidates_per_particle
        << "); ";
  }
  return err.str();
}

std::string LocalizerParams::validate() const {
  std::string err = filter.validate() + lost.validate() + frame.validate() +
                    measurement.validate() + refinement.validate() + init.validate() +
                    constant_velocity.validate();
  if (!T_base_cam.matrix().allFinite()) err += "T_base_cam must be finite; ";
  if (!(max_odometry_step_m > 0.0)) err += "max_odometry_step_m must be positive; ";
  if (backend != "cpu" && backend != "cuda")
    err += "backend must be 'cpu' or 'cuda' (got '" + backend + "'); ";
  return err;
}

}  // namespace gmm_mcl
