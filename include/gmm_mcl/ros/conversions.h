// Message <-> core conversions for the nodelet: free functions, no node handle, no master, so
// that they are unit-tested on their own (test/ros/test_conversions.cpp).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <geometry_msgs/Pose.h>
#include <geometry_msgs/PoseArray.h>
#include <geometry_msgs/PoseWithCovariance.h>
#include <geometry_msgs/Transform.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <visualization_msgs/MarkerArray.h>

#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/filter/particle_filter.h"
#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {
namespace ros_conv {

// The byte-level checks and decoding of the depth inputs live in the ROS-free core
// (gmm_mcl/camera/depth_image.h, png_io.h: fuzzed in test/fuzz); these unpack the messages.

// sensor_msgs/Image (16UC1/mono16 millimetres, 32FC1 metres; either endianness) -> DepthImage.
// False with *error saying why (encoding, size, step, data length).
bool depthImageFromMsg(const sensor_msgs::Image& msg, DepthImage* out, std::string* error);

// compressed_depth_image_transport's format ("16UC1; compressedDepth[ png]" or "32FC1; ..."): a
// 12-byte header (int32 format, float depth quantisation A, B) then a 16-bit grey PNG of the raw
// millimetres (16UC1) or of the quantised inverse depth (32FC1: z = A / (q - B), q = 0 none).
// Decoded once at the boundary, without the transport plugin (Debian does not package it).
bool depthImageFromCompressedDepth(const sensor_msgs::CompressedImage& msg, DepthImage* out,
                                   std::string* error);
// The inverse: encodes a depth image in that format (tests, make_sim_bag --compressed).
bool compressedDepthFromImage(const DepthImage& image, sensor_msgs::CompressedImage* out,
                              std::string* error);

// CameraInfo -> Intrinsics. False (with why) when uncalibrated (K all zero), non-finite, or
// when expected_width/height (> 0) differ from the CameraInfo size.
bool intrinsicsFromCameraInfo(const sensor_msgs::CameraInfo& msg, int expected_width,
                              int expected_height, Intrinsics* out, std::string* error);

// Organized PointCloud2 in the camera optical frame (float32 x, y, z) -> 32FC1 depth image
// (z per pixel, NaN where missing) and pinhole intrinsics fitted to the points by least
// squares (u = fx x / z + cx, v = fy y / z + cy). False with why when unorganized, fields are
// missing or do not fit the point, the data is shorter than the layout, or too few points fit
// intrinsics in makeIntrinsics' range.
bool depthImageFromCloud(const sensor_msgs::PointCloud2& msg, DepthImage* out, Intrinsics* K,
                         std::string* error);

// Roll and pitch (REP-103) of an IMU orientation; false when the quaternion is unset
// (all zero, or orientation_covariance[0] == -1) or not finite.
bool attitudeFromImu(const sensor_msgs::Imu& msg, double* roll_rad, double* pitch_rad);

Eigen::Isometry3d isometryFromPose(const geometry_msgs::Pose& msg);
Eigen::Isometry3d isometryFromTransform(const geometry_msgs::Transform& msg);
geometry_msgs::Pose poseFromIsometry(const Eigen::Isometry3d& T);
geometry_msgs::Transform transformFromIsometry(const Eigen::Isometry3d& T);

// Mean pose with the shared roll/pitch and the full 6x6 covariance (ROS order, row-major).
geometry_msgs::PoseWithCovariance poseWithCovarianceFromEstimate(const PoseEstimate& estimate,
                                                                 double roll_rad,
                                                                 double pitch_rad);

// Every particle as a pose (shared roll/pitch).
void poseArrayFromParticles(const std::vector<Particle>& particles, double roll_rad,
                            double pitch_rad, geometry_msgs::PoseArray* out);

// Particle (x, y, z, yaw) and sigmas from a PoseWithCovariance (e.g. /initialpose): sigmas from
// the covariance diagonal (x, y, z, yaw), each at least min_sigma where the entry is zero,
// negative or not finite. False when the pose is not finite.
bool particleFromPoseWithCovariance(const geometry_msgs::PoseWithCovariance& msg,
                                    const Eigen::Vector4d& min_sigma, Particle* pose,
                                    Eigen::Vector4d* sigma);

// The map's 3-sigma ellipsoids as SPHERE markers (scale = 6 sigma along the principal axes),
// coloured by height, in `frame_id`.
void markersFromMap(const GmmMap& map, const std::string& frame_id,
                    visualization_msgs::MarkerArray* out);

}  // namespace ros_conv
}  // namespace gmm_mcl
