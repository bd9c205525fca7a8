// Message conversions, without a ROS master.
#include <gtest/gtest.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2/buffer_core.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/sim/box_scene.h"

namespace gmm_mcl {

namespace {

constexpr double kTol = 1e-9;

sensor_msgs::Image imageMsg(const DepthImage& d, const std::string& encoding) {
  sensor_msgs::Image m;
  m.width = d.width_px;
  m.height = d.height_px;
  m.encoding = encoding;
  m.step = static_cast<uint32_t>(d.row_bytes);
  m.data = d.data;
  return m;
}

sensor_msgs::CameraInfo infoMsg(int w, int h) {
  sensor_msgs::CameraInfo i;
  i.width = w;
  i.height = h;
  i.K = {100, 0, 0.5 * (w - 1), 0, 101, 0.5 * (h - 1), 0, 0, 1};
  return i;
}

}  // namespace

TEST(RosConversionsTest, BothEncodingsGiveTheSameDepths) {
  std::vector<uint16_t> mm = {0, 1000, 2500, 65535, 1234, 4000};
  std::vector<float> m = {std::numeric_limits<float>::quiet_NaN(), 1.0f,   2.5f,
                          std::numeric_limits<float>::quiet_NaN(), 1.234f, 4.0f};
  DepthImage a, b;
  std::string why;
  ASSERT_TRUE(ros_conv::depthImageFromMsg(imageMsg(DepthImage::fromMillimetres(3, 2, mm), "16UC1"),
                                          &a, &why))
      << why;
  ASSERT_TRUE(
      ros_conv::depthImageFromMsg(imageMsg(DepthImage::fromMetres(3, 2, m), "32FC1"), &b, &why))
      << why;
  for (int v = 0; v < 2; ++v) {
    for (int u = 0; u < 3; ++u) {
      const float za = a.depthMetres(u, v), zb = b.depthMetres(u, v);
      if (std::isnan(zb)) {
        EXPECT_TRUE(std::isnan(za)) << u << "," << v;
      } else
        EXPECT_NEAR(za, zb, 1e-6) << u << "," << v;
    }
  }
}

TEST(RosConversionsTest, BigEndianSamplesAreSwapped) {
  DepthImage d = DepthImage::fromMillimetres(2, 1, {1000, 2000});
  sensor_msgs::Image msg = imageMsg(d, "16UC1");
  msg.is_bigendian = 1;
  for (size_t i = 0; i < msg.data.size(); i += 2) std::swap(msg.data[i], msg.data[i + 1]);
  DepthImage out;
  std::string why;
  ASSERT_TRUE(ros_conv::depthImageFromMsg(msg, &out, &why)) << why;
  EXPECT_NEAR(out.depthMetres(0, 0), 1.0f, 1e-6);
  EXPECT_NEAR(out.depthMetres(1, 0), 2.0f, 1e-6);
}

TEST(RosConversionsTest, BadImagesSayWhy) {
  DepthImage d = DepthImage::fromMillimetres(4, 3, std::vector<uint16_t>(12, 1000));
  DepthImage out;
  std::string why;
  EXPECT_FALSE(ros_conv::depthImageFromMsg(imageMsg(d, "rgb8"), &out, &why));
  EXPECT_NE(why.find("rgb8"), std::string::npos) << why;
  sensor_msgs::Image short_data = imageMsg(d, "16UC1");
  short_data.data.resize(10);
  EXPECT_FALSE(ros_conv::depthImageFromMsg(short_data, &out, &why));
  EXPECT_NE(why.find("bytes"), std::string::npos) << why;
  sensor_msgs::Image bad_step = imageMsg(d, "16UC1");
  bad_step.step = 4;
  EXPECT_FALSE(ros_conv::depthImageFromMsg(bad_step, &out, &why));
  EXPECT_NE(why.find("step"), std::string::npos) << why;
  sensor_msgs::Image empty;
  empty.encoding = "32FC1";
  EXPECT_FALSE(ros_conv::depthImageFromMsg(empty, &out, &why));
}

TEST(RosConversionsTest, CameraInfo) {
  Intrinsics K;
  std::string why;
  ASSERT_TRUE(ros_conv::intrinsicsFromCameraInfo(infoMsg(64, 48), 64, 48, &K, &why)) << why;
  EXPECT_FLOAT_EQ(K.fx_px, 100.f);
  EXPECT_FLOAT_EQ(K.fy_px, 101.f);
  EXPECT_FLOAT_EQ(K.cx_px, 31.5f);
  EXPECT_EQ(K.width_px, 64);
  EXPECT_FALSE(ros_conv::intrinsicsFromCameraInfo(infoMsg(64, 48), 32, 24, &K, &why));
  EXPECT_NE(why.find("CameraInfo says 64x48"), std::string::npos) << why;
  sensor_msgs::CameraInfo zero = infoMsg(64, 48);
  zero.K.fill(0.0);
  EXPECT_FALSE(ros_conv::intrinsicsFromCameraInfo(zero, 64, 48, &K, &why));
  EXPECT_NE(why.find("uncalibrated"), std::string::npos) << why;
  sensor_msgs::CameraInfo nan = infoMsg(64, 48);
  nan.K[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(ros_conv::intrinsicsFromCameraInfo(nan, 64, 48, &K, &why));
}

// P (the rectified image's projection) before K, binning and the region of interest as
// image_geometry applies them, distortion without P refused.
TEST(RosConversionsTest, CameraInfoProjectionBinningRoiAndDistortion) {
  sensor_msgs::CameraInfo info = infoMsg(640, 480);
  info.P = {500, 0, 320, 0, 0, 505, 240, 0, 0, 0, 1, 0};
  Intrinsics K;
  std::string why, note;
  ASSERT_TRUE(ros_conv::intrinsicsFromCameraInfo(info, 640, 480, &K, &why, &note)) << why;
  EXPECT_FLOAT_EQ(K.fx_px, 500);
  EXPECT_FLOAT_EQ(K.fy_px, 505);
  EXPECT_TRUE(note.empty());
  // 2x2 binning: a 320x240 image, focal lengths and centre halved.
  info.binning_x = info.binning_y = 2;
  ASSERT_TRUE(ros_conv::intrinsicsFromCameraInfo(info, 320, 240, &K, &why)) << why;
  EXPECT_FLOAT_EQ(K.fx_px, 250);
  EXPECT_FLOAT_EQ(K.cx_px, 160);
  EXPECT_FLOAT_EQ(K.cy_px, 120);
  EXPECT_FALSE(ros_conv::intrinsicsFromCameraInfo(info, 640, 480, &K, &why));
  // A region of interest: the image is the region, the centre moves by its offset.
  info.binning_x = info.binning_y = 0;
  info.roi.x_offset = 100;
  info.roi.y_offset = 40;
  info.roi.width = 200;
  info.roi.height = 160;
  ASSERT_TRUE(ros_conv::intrinsicsFromCameraInfo(info, 200, 160, &K, &why)) << why;
  EXPECT_FLOAT_EQ(K.cx_px, 220);
  EXPECT_FLOAT_EQ(K.cy_px, 200);
  info.roi.width = 600;
  EXPECT_FALSE(ros_conv::intrinsicsFromCameraInfo(info, 600, 160, &K, &why));
  EXPECT_NE(why.find("region of interest"), std::string::npos) << why;
  // Distortion: used through P with a note; refused without P.
  info.roi = sensor_msgs::RegionOfInterest();
  info.D = {0.1, -0.2, 0, 0, 0};
  ASSERT_TRUE(ros_conv::intrinsicsFromCameraInfo(info, 640, 480, &K, &why, &note)) << why;
  EXPECT_NE(note.find("rectified"), std::string::npos) << note;
  info.P.fill(0.0);
  EXPECT_FALSE(ros_conv::intrinsicsFromCameraInfo(info, 640, 480, &K, &why));
  EXPECT_NE(why.find("distortion"), std::string::npos) << why;
}

TEST(RosConversionsTest, OrganizedCloudGivesDepthAndIntrinsics) {
  Intrinsics K;
  K.width_px = 80;
  K.height_px = 60;
  K.fx_px = 73.f;
  K.fy_px = 75.f;
  K.cx_px = 39.2f;
  K.cy_px = 30.1f;
  const sim::BoxScene scene = sim::makeDefaultScene();
  const Eigen::Isometry3d T = sim::makeTrajectory(2)[0] * sim::defaultBaseToCamera();
  const DepthImage depth = sim::renderDepth(scene, K, T, DepthEncoding::kFloat32Metres, 8.0);
  sensor_msgs::PointCloud2 cloud;
  cloud.width = K.width_px;
  cloud.height = K.height_px;
  sensor_msgs::PointCloud2Modifier mod(cloud);
  mod.setPointCloud2FieldsByString(1, "xyz");
  mod.resize(K.width_px * K.height_px);
  cloud.width = K.width_px;  // resize() flattens; restore the organized layout
  cloud.height = K.height_px;
  cloud.row_step = cloud.width * cloud.point_step;
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
  for (int v = 0; v < K.height_px; ++v) {
    for (int u = 0; u < K.width_px; ++u, ++x, ++y, ++z) {
      const float d = depth.depthMetres(u, v);
      float p[3] = {NAN, NAN, NAN};
      if (std::isfinite(d)) backProject(K, static_cast<float>(u), static_cast<float>(v), d, p);
      *x = p[0];
      *y = p[1];
      *z = p[2];
    }
  }
  DepthImage out;
  Intrinsics fitted;
  std::string why;
  ASSERT_TRUE(ros_conv::depthImageFromCloud(cloud, &out, &fitted, &why)) << why;
  EXPECT_NEAR(fitted.fx_px, K.fx_px, 1e-2);
  EXPECT_NEAR(fitted.fy_px, K.fy_px, 1e-2);
  EXPECT_NEAR(fitted.cx_px, K.cx_px, 1e-2);
  EXPECT_NEAR(fitted.cy_px, K.cy_px, 1e-2);
  EXPECT_EQ(out.width_px, K.width_px);
  for (int v = 0; v < K.height_px; v += 7) {
    for (int u = 0; u < K.width_px; u += 5) {
      const float a = depth.depthMetres(u, v), b = out.depthMetres(u, v);
      if (std::isfinite(a)) {
        EXPECT_NEAR(a, b, 1e-6);
      } else
        EXPECT_TRUE(std::isnan(b));
    }
  }
  sensor_msgs::PointCloud2 flat = cloud;
  flat.height = 1;
  flat.width = K.width_px * K.height_px;
  EXPECT_FALSE(ros_conv::depthImageFromCloud(flat, &out, &fitted, &why));
  EXPECT_NE(why.find("not organized"), std::string::npos) << why;
}

TEST(RosConversionsTest, ImuAttitude) {
  sensor_msgs::Imu imu;
  const Eigen::Quaterniond q(rotationFromRpy(0.1, -0.2, 2.0));
  imu.orientation.w = q.w();
  imu.orientation.x = q.x();
  imu.orientation.y = q.y();
  imu.orientation.z = q.z();
  double roll, pitch;
  ASSERT_TRUE(ros_conv::attitudeFromImu(imu, &roll, &pitch));
  EXPECT_NEAR(roll, 0.1, 1e-9);
  EXPECT_NEAR(pitch, -0.2, 1e-9);
  imu.orientation_covariance[0] = -1.0;  // "no orientation" (REP-145)
  EXPECT_FALSE(ros_conv::attitudeFromImu(imu, &roll, &pitch));
  sensor_msgs::Imu zero;
  zero.orientation.w = 0.0;
  EXPECT_FALSE(ros_conv::attitudeFromImu(zero, &roll, &pitch));
}

TEST(RosConversionsTest, PoseRoundTripAndEstimate) {
  Eigen::Isometry3d T = particleToPose(Particle{1.0, -2.0, 0.5, 2.5}, 0.05, -0.1);
  const Eigen::Isometry3d back = ros_conv::isometryFromPose(ros_conv::poseFromIsometry(T));
  EXPECT_TRUE(back.isApprox(T, 1e-12));
  const Eigen::Isometry3d back2 =
      ros_conv::isometryFromTransform(ros_conv::transformFromIsometry(T));
  EXPECT_TRUE(back2.isApprox(T, 1e-12));

  PoseEstimate e;
  e.mean = Particle{1.0, -2.0, 0.5, 2.5};
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) e.covariance(r, c) = (r == c) ? 0.01 * (r + 1) : 0.001 * (r + c);
  }
  const geometry_msgs::PoseWithCovariance pwc =
      ros_conv::poseWithCovarianceFromEstimate(e, 0.05, -0.1);
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) EXPECT_DOUBLE_EQ(pwc.covariance[r * 6 + c], e.covariance(r, c));
  }
  EXPECT_TRUE(ros_conv::isometryFromPose(pwc.pose).isApprox(T, 1e-12));

  EXPECT_TRUE(ros_conv::covarianceFromMsg(pwc.covariance).isApprox(e.covariance, 0.0));
  // An unset quaternion (all zero) is the identity.
  geometry_msgs::Pose unset;
  EXPECT_TRUE(ros_conv::isometryFromPose(unset).isApprox(Eigen::Isometry3d::Identity(), 0.0));
}

TEST(RosConversionsTest, ParticlesAndMarkers) {
  std::vector<Particle> particles = {{0, 0, 0, 0}, {1, 2, 3, 1.0}};
  geometry_msgs::PoseArray arr;
  ros_conv::poseArrayFromParticles(particles, 0.0, 0.0, &arr);
  ASSERT_EQ(arr.poses.size(), 2u);
  EXPECT_DOUBLE_EQ(arr.poses[1].position.z, 3.0);
  EXPECT_NEAR(yawFromRotation(ros_conv::isometryFromPose(arr.poses[1]).linear()), 1.0, 1e-12);

  GaussianComponent c;
  c.weight = 1.0;
  c.mean_m = Eigen::Vector3d(1, 2, 3);
  c.cov_m2 = Eigen::Vector3d(0.04, 0.01, 0.0001).asDiagonal();
  GmmMap map({c});
  visualization_msgs::MarkerArray markers;
  ros_conv::markersFromMap(map, "map", &markers);
  ASSERT_EQ(markers.markers.size(), 1u);
  const auto& m = markers.markers[0];
  EXPECT_EQ(m.header.frame_id, "map");
  // Scale = 6 sigma along the principal axes (eigenvalues ascending: 0.0001, 0.01, 0.04).
  EXPECT_NEAR(m.scale.x, 6 * 0.01, 1e-9);
  EXPECT_NEAR(m.scale.y, 6 * 0.1, 1e-9);
  EXPECT_NEAR(m.scale.z, 6 * 0.2, 1e-9);
  EXPECT_DOUBLE_EQ(m.pose.position.y, 2.0);

  // Some components of a larger map (a building's, near the estimate): a DELETEALL first, so
  // that rviz drops those shown before, then each listed one with its map index as id.
  GaussianComponent d = c;
  d.mean_m = Eigen::Vector3d(5, 6, 7);
  c.weight = d.weight = 0.5;
  const GmmMap two({c, d});
  const std::vector<int> only = {1};
  ros_conv::markersFromMap(two, "map", &markers, &only);
  ASSERT_EQ(markers.markers.size(), 2u);
  EXPECT_EQ(markers.markers[0].action, visualization_msgs::Marker::DELETEALL);
  EXPECT_EQ(markers.markers[1].id, 1);
  EXPECT_DOUBLE_EQ(markers.markers[1].pose.position.x, 5.0);
}

#ifdef GMM_MCL_HAVE_PNG
TEST(RosConversionsTest, CompressedDepthRoundTrip) {
  std::vector<uint16_t> mm = {0, 1000, 2500, 65534, 1234, 4000};
  sensor_msgs::CompressedImage msg;
  std::string why;
  ASSERT_TRUE(ros_conv::compressedDepthFromImage(DepthImage::fromMillimetres(3, 2, mm), &msg, &why))
      << why;
  EXPECT_EQ(msg.format, "16UC1; compressedDepth png");
  DepthImage out;
  ASSERT_TRUE(ros_conv::depthImageFromCompressedDepth(msg, &out, &why)) << why;
  ASSERT_EQ(out.width_px, 3);
  ASSERT_EQ(out.height_px, 2);
  EXPECT_TRUE(std::isnan(out.depthMetres(0, 0)));
  EXPECT_NEAR(out.depthMetres(1, 0), 1.0f, 1e-6);
  EXPECT_NEAR(out.depthMetres(1, 1), 1.234f, 1e-6);
  EXPECT_NEAR(out.depthMetres(2, 1), 4.0f, 1e-6);

  // 32FC1: quantised inverse depth; the error grows with z^2 (about 1 mm at 1 m with the defaults).
  std::vector<float> m = {std::numeric_limits<float>::quiet_NaN(), 0.5f, 1.0f, 2.0f, 3.0f, 4.0f};
  ASSERT_TRUE(ros_conv::compressedDepthFromImage(DepthImage::fromMetres(3, 2, m), &msg, &why))
      << why;
  EXPECT_EQ(msg.format, "32FC1; compressedDepth png");
  ASSERT_TRUE(ros_conv::depthImageFromCompressedDepth(msg, &out, &why)) << why;
  EXPECT_TRUE(std::isnan(out.depthMetres(0, 0)));
  for (int i = 1; i < 6; ++i) {
    const float z = m[i];
    EXPECT_NEAR(out.depthMetres(i % 3, i / 3), z, 2e-4 * z * z + 1e-5) << z;
  }

  sensor_msgs::CompressedImage bad = msg;
  bad.format = "rgb8; jpeg compressed bgr8";
  EXPECT_FALSE(ros_conv::depthImageFromCompressedDepth(bad, &out, &why));
  EXPECT_NE(why.find("unsupported compressed depth format"), std::string::npos) << why;
  bad = msg;
  bad.data.resize(40);
  EXPECT_FALSE(ros_conv::depthImageFromCompressedDepth(bad, &out, &why));
  EXPECT_NE(why.find("compressedDepth"), std::string::npos) << why;
}
#endif

// A requested pose in another frame goes through tf (covariance rotated); a planar tool's pose
// is marked planar before the transform (rviz sends z = 0 in its fixed frame).
TEST(RosConversionsTest, PoseResetRequestThroughTf) {
  tf2::BufferCore tf;
  Eigen::Isometry3d T_map_odom = Eigen::Isometry3d::Identity();
  T_map_odom.translation() = Eigen::Vector3d(1.5, -1.0, 0.2);
  T_map_odom.linear() = rotationFromRpy(0, 0, M_PI / 2);
  geometry_msgs::TransformStamped t;
  t.header.stamp = ros::Time(10.0);
  t.header.frame_id = "map";
  t.child_frame_id = "odom";
  t.transform = ros_conv::transformFromIsometry(T_map_odom);
  ASSERT_TRUE(tf.setTransform(t, "test", true));

  geometry_msgs::PoseWithCovarianceStamped msg;
  msg.header.frame_id = "odom";
  msg.header.stamp = ros::Time(12.0);
  msg.pose.pose.position.x = 1.0;
  msg.pose.pose.orientation.w = 1.0;
  msg.pose.covariance[0] = 0.04;  // x variance in odom: y in the map
  PoseResetRequest r;
  std::string why;
  ASSERT_TRUE(ros_conv::poseResetRequestFromMsg(msg, tf, "map", &r, &why)) << why;
  EXPECT_TRUE(r.planar);
  EXPECT_NEAR(r.T_map_base.translation().x(), 1.5, 1e-9);
  EXPECT_NEAR(r.T_map_base.translation().y(), 0.0, 1e-9);
  EXPECT_NEAR(r.T_map_base.translation().z(), 0.2, 1e-9);
  EXPECT_NEAR(yawFromRotation(r.T_map_base.linear()), M_PI / 2, 1e-9);
  EXPECT_NEAR(r.covariance(1, 1), 0.04, 1e-12);
  EXPECT_NEAR(r.covariance(0, 0), 0.0, 1e-12);
  // In the map frame: as given; a frame tf does not know: refused with why.
  msg.header.frame_id = "map";
  msg.pose.pose.position.z = 1.1;
  ASSERT_TRUE(ros_conv::poseResetRequestFromMsg(msg, tf, "map", &r, &why));
  EXPECT_FALSE(r.planar);
  EXPECT_NEAR(r.T_map_base.translation().x(), 1.0, 1e-12);
  msg.header.frame_id = "nowhere";
  EXPECT_FALSE(ros_conv::poseResetRequestFromMsg(msg, tf, "map", &r, &why));
  EXPECT_NE(why.find("'nowhere'"), std::string::npos) << why;
}

}  // namespace gmm_mcl
