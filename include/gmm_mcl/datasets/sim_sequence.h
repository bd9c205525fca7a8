// The synthetic box scene (gmm_mcl::sim) as a Sequence: the built-in drone trajectory at
// 30 Hz, depth rendered with noise on demand (seeded per frame, so any access order gives the
// same frames). For tests and fixtures: written out as a TUM or Stanford folder
// (sequence_writer.h) it exercises the readers end to end. World z is up.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gmm_mcl/datasets/sequence_base.h"
#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/sim/box_scene.h"

namespace gmm_mcl {

struct SimSequenceParams {
  int frames = 120;
  int width_px = 160;  // height 3/4 of it; focal length 585 px scaled from 640
  uint64_t seed = 1;
  double sigma_at_1m_m = 0.0015;  // axial depth noise at 1 m (grows with z^2)
  double dropout = 0.02;
  double max_range_m = 8.0;
  double start_s = 0.0;  // stamp of the first frame
};

class SimSequence : public Sequence {
 public:
  explicit SimSequence(const SimSequenceParams& params = SimSequenceParams());

  // Rendered with noise, seeded per frame.
  DepthImage loadDepth(int i) const override;

  const sim::BoxScene& scene() const { return scene_; }
  // The scene's GMM (surfaces tiled at 0.4 m, 1.5 cm normal sigma), in the world frame.
  GmmMap map() const;

 private:
  SimSequenceParams params_;
  sim::BoxScene scene_;
};

}  // namespace gmm_mcl
