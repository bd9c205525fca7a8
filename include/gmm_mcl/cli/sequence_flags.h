// The data-set folder flags shared by the tools that read a sequence (gmm_mcl_replay,
// gmm_mcl_make_bag): --intrinsics, --depth-scale, --tolerance, --gravity, --trajectory, --rate.
#pragma once

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/datasets/sequence_base.h"

namespace gmm_mcl {
namespace cli {

inline void addSequenceFlags(CommandLine* cl, SequenceOptions* so) {
  cl->flags({{"intrinsics", &so->intrinsics},
             {"depth-scale", &so->depth_units_per_m},
             {"tolerance", &so->association_tolerance_s},
             {"gravity", &so->gravity},
             {"trajectory", &so->trajectory},
             {"rate", &so->frame_rate_hz}});
}

}  // namespace cli
}  // namespace gmm_mcl
