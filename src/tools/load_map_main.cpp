// gmm_mcl_load_map: a map loaded as the nodelet loads its ~map (a point cloud or mesh fitted on
// load and cached beside it, fit_on_load.h), with the load's timings printed. Fills the cache
// ahead of a deployment, and measures the cache (docs/map_builder.md, "Maps given as point
// clouds").
#include <cstdio>
#include <iostream>
#include <string>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/fit/fit_on_load.h"

namespace {

const char* kUsage =
    "usage: gmm_mcl_load_map MAP [-m M] [--time-limit S] [--no-cache] [--seed S] [--repeat N]\n"
    "Loads MAP as the nodelet's ~map does: a .gmm file as it is; a point cloud or mesh (.pcd,\n"
    ".ply, .xyz, .txt) fitted with the map builder's defaults (M from the cloud's surface unless\n"
    "-m gives it) and cached as MAP.fit-<key>.gmm, or taken from that cache. Prints one line per\n"
    "load: what happened and its wall time. --repeat loads it N times (the first may fit, the\n"
    "others read the cache).\n";

}  // namespace

int main(int argc, char** argv) {
  using namespace gmm_mcl;
  std::string map_path;
  FitOnLoadParams params;
  bool no_cache = false;
  int repeat = 1;
  cli::CommandLine cl("gmm_mcl_load_map", kUsage);
  // clang-format off
  cl.flags({{"map", &map_path}, {"components,m", &params.components},
            {"time-limit", &params.time_limit_s}, {"no-cache", &no_cache}, {"seed", &params.seed},
            {"repeat", &repeat}});
  // clang-format on
  cl.positional("map");
  cl.parse(argc, argv);
  if (map_path.empty()) cl.fail("no map given");
  if (repeat < 1) cl.fail("--repeat must be >= 1");
  params.cache = !no_cache;
  const std::string fault = params.validate();
  if (!fault.empty()) cl.fail(fault);
  return cli::reportErrors("gmm_mcl_load_map", [&] {
    FitOnLoadLog log;
    log.info = [](const std::string& s) { std::cerr << s << "\n"; };
    log.warn = [](const std::string& s) { std::cerr << "warning: " << s << "\n"; };
    for (int i = 0; i < repeat; ++i) {
      const FitOnLoadResult r = loadOrFitMap(map_path, params, log);
      const char* what = r.fitted ? "fitted" : r.from_cache ? "cache" : "map file";
      std::printf("load %d: %s, %d components, %.3f s", i + 1, what, r.components, r.seconds);
      if (r.fitted) {
        std::printf(" (%zu points fitted of %zu read, estimate %.2f s)", r.points_fitted,
                    r.points_read, r.estimate_s);
      }
      std::printf("\n");
    }
    return 0;
  });
}
