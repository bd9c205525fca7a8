// gmm_mcl_inspect: summary of a map file and export of its k-sigma ellipsoids for viewing.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/cli/report_errors.h"
#include "gmm_mcl/common/number_list.h"
#include "gmm_mcl/fit/map_inspect.h"
#include "gmm_mcl/map/gmm_map_io.h"

namespace {

const char* kUsage =
    "usage: gmm_mcl_inspect MAP [--ply OUT.ply] [--csv OUT.csv] [--sigma S] [--rings R]\n"
    "                       [--segments N] [--tile NX[,NY] [--tile-spacing M] --out OUT.gmm]\n"
    "Prints count, bounds, weight, volume and shape statistics of a gmm_mcl map file and its\n"
    "mapped surface (docs/building_scale.md), and optionally exports its S-sigma ellipsoids (3)\n"
    "as a coloured PLY mesh or a CSV table.\n"
    "--tile writes to OUT.gmm a building of NX x NY copies of the map (the cost case of\n"
    "docs/building_scale.md: copy (0, 0) is the map itself, copy (i, j) moved by (i, j) times the\n"
    "spacing and turned by 90 degrees (i + j) times); --tile-spacing defaults to the map's larger\n"
    "horizontal extent plus 2 m.\n";

}  // namespace

int main(int argc, char** argv) {
  using namespace gmm_mcl;
  std::string map_path, ply, csv, tile, out;
  double tile_spacing_m = 0.0;
  EllipsoidExportParams params;
  cli::CommandLine cl("gmm_mcl_inspect", kUsage);
  // clang-format off
  cl.flags({{"map", &map_path}, {"ply", &ply}, {"csv", &csv}, {"sigma", &params.sigma},
           {"rings", &params.rings}, {"segments", &params.segments}, {"tile", &tile},
           {"tile-spacing", &tile_spacing_m}, {"out", &out}});
  // clang-format on
  cl.positional("map");
  cl.parse(argc, argv);
  if (map_path.empty()) cl.fail("no map file given");
  int nx = 1, ny = 1;
  if (!tile.empty()) {
    const std::vector<double> n = parseNumberList(tile);
    if (n.empty() || n.size() > 2 || n[0] < 1 || n.back() < 1 || n[0] != std::floor(n[0]) ||
        n.back() != std::floor(n.back())) {
      cl.fail("--tile: expected NX or NX,NY (whole numbers >= 1), got '" + tile + "'");
    }
    nx = static_cast<int>(n[0]);
    ny = static_cast<int>(n.back());
    if (out.empty()) cl.fail("--tile needs --out OUT.gmm");
    if (tile_spacing_m < 0.0) cl.fail("--tile-spacing must be positive");
  }
  return cli::reportErrors("gmm_mcl_inspect", [&] {
    const GmmMap map = loadMap(map_path);
    std::cout << map_path << "\n";
    printMapSummary(summarizeMap(map), std::cout, encodeMap(map).size());
    std::cout << "mapped surface: " << map.surfaceArea() << " m^2 (log-weight scale "
              << map.logWeightScale() << " nats against " << kReferenceSurfaceAreaM2 << " m^2)\n";
    if (!tile.empty()) {
      const Eigen::Vector3d extent = map.maxBound() - map.minBound();
      const double spacing =
          tile_spacing_m > 0.0 ? tile_spacing_m : std::max(extent.x(), extent.y()) + 2.0;
      const GmmMap building = tiledMap(map, nx, ny, spacing, map_path + " tiled");
      saveMap(building, out);
      std::cout << "wrote " << out << ": " << nx << " x " << ny << " copies " << spacing
                << " m apart, " << building.size() << " components, mapped surface "
                << building.surfaceArea() << " m^2\n";
    }
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
