// Text and file helpers shared by the sequence readers (private to src/datasets).
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_image.h"

namespace gmm_mcl {
namespace seqio {

[[noreturn]] void fail(const std::string& path, const std::string& what);
bool fileExists(const std::string& path);
bool isDirectory(const std::string& path);
// Names of the entries of a folder (no "." or ".."), sorted; throws when it cannot be read.
std::vector<std::string> listDirectory(const std::string& dir);
// The numbers of a text file, skipping '#' comments; false when unreadable or not all numbers
// are finite (then *why says what).
bool readNumberFile(const std::string& path, std::vector<double>* out, std::string* why);
// A rotation from a possibly slightly non-orthonormal matrix (text poses carry rounding);
// throws naming `where` when it is far from a rotation (|det - 1| or |R^T R - I| > 1e-2).
Eigen::Matrix3d orthonormalise(const Eigen::Matrix3d& M, const std::string& where);
// A 16-bit depth PNG rescaled to millimetres from `units_per_m` raw units per metre (1000:
// unchanged); 0 stays 0 (no measurement), values beyond 65534 mm become 0.
DepthImage loadDepthPngScaled(const std::string& path, double units_per_m);

}  // namespace seqio
}  // namespace gmm_mcl
