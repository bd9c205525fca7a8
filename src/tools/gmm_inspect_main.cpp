// gmm_mcl_inspect: summary of a map file and export of its k-sigma ellipsoids for viewing.
#include <cstdlib>
#include <iostream>
#include <string>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/fit/map_inspect.h"
#include "gmm_mcl/map/gmm_map_io.h"

namespace {

const char* kUsage =
    "usage: gmm_mcl_inspect MAP [--ply OUT.ply] [--csv OUT.csv] [--sigma S] [--rings R]\n"
    "                       [--segments N]\n"
    "Prints count, bounds, weight, volume and shape statistics of a gmm_mcl map file and\n"
    "optionally exports its S-sigma ellipsoids (3) as a coloured PLY mesh or a CSV table.\n";

}  // namespace

int main(int argc, char** argv) {
  using namespace gmm_mcl;
  std::string map_path, ply, csv;
  EllipsoidExportParams params;
  cli::CommandLine cl("gmm_mcl_inspect", kUsage);
  // clang-format off
  cl.flags({{"map", &map_path}, {"ply", &ply}, {"csv", &csv}, {"sigma", &params.sigma},
           {"rings", &params.rings}, {"segments", &params.segments}});
  // clang-format on
  cl.positional("map");
  cl.parse(argc, argv);
  if (map_path.empty()) cl.fail("no map file given");
  return cli::reportErrors("gmm_mcl_inspect", [&] {
    const GmmMap map = loadMap(map_path);
    std::cout << map_path << "\n";
    printMapSummary(summarizeMap(map), std::cout, encodeMap(map).size());
    if (!ply.empty()) {
      writeEllipsoidsPly(map, ply, params);
      std::cout << "wrote " << params.sigma << "-sigma ellipsoids to " << ply << "\n";
    }
    if (!csv.empty()) {
      writeEllipsoidsCsv(map, csv, params);
      std::cout << "wrote " << params.sigma << "-sigma ellipsoid table to " << csv << "\n";
    }
    return 0;
  });
}
