// Point-cloud and mesh files without PCL: PCD (ascii, binary, binary_compressed), PLY (the
// package's one PLY reader, sim/mesh.h: vertices and faces) and XYZ text (three numbers a line).
#pragma once

#include <string>

#include "gmm_mcl/fit/point_cloud.h"

namespace gmm_mcl {

// What a file held: points, and triangles when it is a PLY mesh with faces.
struct CloudFile {
  PointCloud points;  // PCD/XYZ points or PLY vertices, in file order
  TriangleMesh mesh;  // PLY only: vertices (same as points) and triangles; empty otherwise
  bool hasFaces() const { return !mesh.triangles.empty(); }
};

// Reads by extension (.pcd, .ply, .xyz/.txt). Non-finite points are kept (the caller decides);
// throws FitError naming the file and the fault for unreadable or malformed files.
CloudFile readCloudFile(const std::string& path);
PointCloud readPcd(const std::string& path);
CloudFile readPly(const std::string& path);
PointCloud readXyz(const std::string& path);

// Writes a binary PCD (FIELDS x y z, float32) or XYZ text; throws FitError on failure.
void writePcd(const PointCloud& points, const std::string& path);
void writeXyz(const PointCloud& points, const std::string& path);

}  // namespace gmm_mcl
