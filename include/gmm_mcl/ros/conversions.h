// Message <-> core conversions for the nodelet: free functions, no node handle, no master, so
// that they are unit-tested on their own (test/ros/test_conversions.cpp).
#pragma once

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/PoseArray.h>
#include <geometry_msgs/PoseWithCovariance.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/Transform.h>
#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2/buffer_core.h>
#include <visualization_msgs/MarkerArray.h>

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/filter/particle_filter.h"
#include "gmm_mcl/filter/pose_reset.h"
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
// The inverse: encodes a depth image in that format (tests, gmm_mcl_make_sim_bag --compressed).
bool compressedDepthFromImage(const DepthImage& image, sensor_msgs::CompressedImage* out,
                              std::string* error);

// CameraInfo -> Intrinsics of the (rectified) depth image, as depth_image_proc and
// image_geometry read it: the projection matrix P (K when P is unset), divided by the binning
// and shifted by the region of interest, whose size (over the binning) is the image's. False
// (with why) when uncalibrated (all zero), non-finite, distorted without a P, a region of
// interest beyond the image, or when expected_width/height (> 0) differ from that size. A
// distorted CameraInfo with a P is used (the image must then be the rectified one) and says so
// in *note.
bool intrinsicsFromCameraInfo(const sensor_msgs::CameraInfo& msg, int expected_width,
                              int expected_height, Intrinsics* out, std::string* error,
                              std::string* note = nullptr);

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
// The IMU's angular velocity (its own frame, rad/s). False when the message has none: the
// covariance's first element -1 (REP 145), a non-finite value, or all three exactly zero (an
// orientation-only message that left them unset).
bool angularVelocityFromImu(const sensor_msgs::Imu& msg, Eigen::Vector3d* omega_rad_s);

// Pose and transform conversions (tf2_eigen); an unset (all zero) quaternion is the identity.
Eigen::Isometry3d isometryFromPose(const geometry_msgs::Pose& msg);
Eigen::Isometry3d isometryFromTransform(const geometry_msgs::Transform& msg);
geometry_msgs::Pose poseFromIsometry(const Eigen::Isometry3d& T);

// sensor_msgs/Imu carrying the attitude roll, pitch, yaw with roll and pitch variance
// attitude_variance_rad2 (yaw unknown: variance 1); with rates_absent, angular velocity and
// linear acceleration marked as not provided (covariance[0] = -1).
sensor_msgs::Imu imuFromAttitude(const ros::Time& stamp, const std::string& frame_id,
                                 double roll_rad, double pitch_rad, double yaw_rad,
                                 double attitude_variance_rad2, bool rates_absent = true);

// CameraInfo of a pinhole camera without distortion (plumb_bob, D zero).
sensor_msgs::CameraInfo cameraInfoFromIntrinsics(const Intrinsics& K, const ros::Time& stamp,
                                                 const std::string& frame_id);
geometry_msgs::Transform transformFromIsometry(const Eigen::Isometry3d& T);
geometry_msgs::TransformStamped transformStamped(const Eigen::Isometry3d& T_parent_child,
                                                 const std::string& parent,
                                                 const std::string& child, const ros::Time& stamp);

// Mean pose with the shared roll/pitch and the full 6x6 covariance (ROS order, row-major).
geometry_msgs::PoseWithCovariance poseWithCovarianceFromEstimate(const PoseEstimate& estimate,
                                                                 double roll_rad, double pitch_rad);

// A pose with its 6x6 covariance (ROS order), stamped in `frame`.
geometry_msgs::PoseWithCovarianceStamped poseWithCovarianceStamped(
    const Eigen::Isometry3d& T, const Eigen::Matrix<double, 6, 6>& covariance,
    const std::string& frame, const ros::Time& stamp);

// Every particle as a pose (shared roll/pitch).
void poseArrayFromParticles(const std::vector<Particle>& particles, double roll_rad,
                            double pitch_rad, geometry_msgs::PoseArray* out);

// A message's row-major 6x6 covariance (x, y, z, roll, pitch, yaw) as a matrix.
Eigen::Matrix<double, 6, 6> covarianceFromMsg(const boost::array<double, 36>& covariance);

// A requested pose (initialpose, a reset service) in the map frame: a pose in another frame is
// transformed with tf at its stamp (the latest transform when tf has none that recent), its
// covariance rotated too; planar when the message itself is (rviz's 2D Pose Estimate sends
// z = 0 in its fixed frame). False, with why, when it cannot be transformed.
bool poseResetRequestFromMsg(const geometry_msgs::PoseWithCovarianceStamped& msg,
                             const tf2::BufferCore& tf, const std::string& map_frame,
                             PoseResetRequest* out, std::string* why);

// The map's 3-sigma ellipsoids as SPHERE markers (scale = 6 sigma along the principal axes),
// coloured by height, in `frame_id`.
// `only` (map indices): those components alone, after a DELETEALL marker that clears the ones
// shown before (a building's markers near the estimate).
void markersFromMap(const GmmMap& map, const std::string& frame_id,
                    visualization_msgs::MarkerArray* out, const std::vector<int>* only = nullptr);

}  // namespace ros_conv
}  // namespace gmm_mcl
