// gmm_mcl_params: prints what the parameter tables generate: the dynamic_reconfigure
// description (cfg/Localizer.cfg), the parameter reference (docs/parameters.md), or every
// parameter's default as a YAML profile. No ROS master needed.
#include <cstdio>
#include <string>

#include "gmm_mcl/ros/ros_params.h"

int main(int argc, char** argv) {
  const std::string what = argc > 1 ? argv[1] : "";
  if (what == "--cfg") {
    std::fputs(gmm_mcl::dynamicReconfigureCfg().c_str(), stdout);
  } else if (what == "--markdown") {
    std::fputs(gmm_mcl::parameterReferenceMarkdown().c_str(), stdout);
  } else if (what == "--defaults") {
    std::fputs(gmm_mcl::defaultsYaml().c_str(), stdout);
  } else {
    std::fprintf(stderr,
                 "usage: gmm_mcl_params --cfg | --markdown | --defaults\n"
                 "  --cfg       dynamic_reconfigure description (cfg/Localizer.cfg)\n"
                 "  --markdown  parameter reference (docs/parameters.md)\n"
                 "  --defaults  every parameter with its default, as a ROS parameter file\n");
    return what == "--help" || what == "-h" ? 0 : 2;
  }
  return 0;
}
