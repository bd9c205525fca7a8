// What a likelihood backend is built with (makeBackend): the CPU backend's thread count and the
// CUDA backend's kernel tuning. The tuning is a start-up group of the parameter table ("cuda",
// the cuda_* parameters; docs/parameters.md); its defaults are the shapes and thresholds
// measured on an H100 (docs/cuda_backend.md), for tuning runs such as scripts/gpu_sweep.sh.
#pragma once

#include <string>

namespace gmm_mcl {

struct CudaTuningParams {
  // The likelihood kernel's shape GROUPSxPX (pixel groups per warp x pixels per group: 32x4,
  // 32x2, 32x1, 16x4, 16x2, 16x1, 8x4, 8x2, 8x1, 4x4, 4x2); "auto": by the frame's largest patch
  // (8x2 up to 16 px, 32x2 up to 64 px, else 32x4).
  std::string likelihood_shape = "auto";
  // The members' records staged in shared memory once per patch (32x4 only): "auto" (the
  // shape's choice: on for 32x4 over patches of more than 128 px), "on", "off".
  std::string stage_members = "auto";
  // Patches per likelihood work item; 0: the shape's choice (10).
  int band_patches = 0;
  // The per-update view cull runs from this many (particle, component) pairs on (0: always; a
  // number larger than any update's: never). Measured on an H100: its kernels and the wait for
  // the visible count cost ~0.04 ms per update, and with the benchmark's particle spread
  // (+-0.5 m, +-0.3 rad) 76-81% of the 7-Scenes map stays visible, so it pays only for large
  // products: `large` (1068 x 4000) and `scale` (100,000 x 1000) gain, `paper` (1068 x 1000)
  // would lose 8%.
  long long view_cull_min_pairs = 2000000;
  // About this many membership bitmask words per pass where the visible components need more:
  // the nearest number of passes, all of one size (one pass up to 1.5 times this; 0: always one
  // pass).
  int membership_pass_words = 32;
  // A cloud spread over several places of a map of 20,000 components or more (a start from a
  // uniform cloud, a lost detector's redraw) evaluated group by group of poses by place, each
  // over what its own views can see (as the CPU backend does), instead of all over the union of
  // the views. Off: measured slower on an H100 (docs/building_scale.md); its parity with the CPU
  // backend is CudaBackendTest.CloudSpreadOverABuildingMatchesCpu.
  bool place_groups = false;
  // From this many components visible to the update's poses together on, each pose's bitmask
  // and evaluation forms cover only the components it can see itself (a count kernel first
  // sizes them), instead of all of them, and each pose skips the chunks of 256 of them whose
  // bounding ball lies outside its view: a cloud spread over a building sees a hundred times
  // more together than one pose does. The same members in the same order (the sums equal to
  // float rounding). On the view cull's set only (view_cull_min_pairs). 0: always.
  int local_lists_min_components = 4096;
  // From this many components on, the device holds the map in the Z order of the components'
  // means (0.25 m cells), so that a chunk of 256 consecutive components is a small piece of
  // space and the membership kernel skips each chunk outside a pose's view; smaller maps keep
  // their own order (the sums, in map order, unchanged to the bit).
  int z_order_min_components = 20000;
};

// The options of makeBackend().
struct BackendOptions {
  int cpu_threads = 0;  // the CPU backend's OpenMP threads; <= 0: OpenMP's default
  CudaTuningParams cuda;
};

}  // namespace gmm_mcl
