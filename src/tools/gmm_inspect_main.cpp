// gmm_inspect: summary of a map file and export of its k-sigma ellipsoids for viewing.
#include <cstdlib>
#include <iostream>
#include <string>

#include "gmm_mcl/fit/map_inspect.h"
#include "gmm_mcl/map/gmm_map_io.h"

namespace {

const char* kUsage =
    "usage: gmm_inspect MAP [--ply OUT.ply] [--csv OUT.csv] [--sigma S] [--rings R]\n"
    "                       [--segments N]\n"
    "Prints count, bounds, weight, volume and shape statistics of a gmm_mcl map file and\n"
    "optionally exports its S-sigma ellipsoids (3) as a coloured PLY mesh or a CSV table.\n";

[[noreturn]] void usageError(const std::string& what) {
  std::cerr << "gmm_inspect: " << what << "\n\n" << kUsage;
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace gmm_mcl;
  std::string map_path, ply, csv;
  EllipsoidExportParams params;
  for (int i = 1; i < argc; ++i) {
    const std::string opt = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usageError(opt + " needs a value");
      return argv[++i];
    };
    if (opt == "-h" || opt == "--help") {
      std::cout << kUsage;
      return 0;
    } else if (opt == "--ply") {
      ply = value();
    } else if (opt == "--csv") {
      csv = value();
    } else if (opt == "--sigma") {
      params.sigma = std::atof(value().c_str());
    } else if (opt == "--rings") {
      params.rings = std::atoi(value().c_str());
    } else if (opt == "--segments") {
      params.segments = std::atoi(value().c_str());
    } else if (!opt.empty() && opt[0] == '-') {
      usageError("unknown option " + opt);
    } else if (map_path.empty()) {
      map_path = opt;
    } else {
      usageError("more than one map given");
    }
  }
  if (map_path.empty()) usageError("no map file given");
  try {
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
  } catch (const std::exception& e) {
    std::cerr << "gmm_inspect: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
