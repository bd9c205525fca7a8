// The nodelet's depth input, one path for its three kinds: a depth image with its CameraInfo
// (image_transport), compressedDepth with its CameraInfo (decoded here: Debian has no plugin),
// or an organized PointCloud2. Each message waits in a tf2 message filter until the camera
// frame reaches base_frame (and odom_frame when odometry comes from tf) at its stamp, as amcl
// waits for its laser scans, then is converted once and handed on as a depth image with its
// intrinsics. Every message that arrives is reported, and every drop with its reason.
#pragma once

#include <image_transport/image_transport.h>
#include <image_transport/subscriber_filter.h>
#include <message_filters/subscriber.h>
#include <message_filters/time_synchronizer.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/message_filter.h>

#include <functional>
#include <map>
#include <memory>
#include <string>

#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/ros/node_status.h"
#include "gmm_mcl/ros/ros_params.h"

namespace gmm_mcl {

class DepthInput {
 public:
  struct Callbacks {
    std::function<void(const std_msgs::Header&)> arrived;      // every depth message
    std::function<void(const std_msgs::Header&)> camera_info;  // every CameraInfo
    // Every message that times the camera: each CameraInfo (their queue holds a second of them
    // while an update runs; depth images beyond the newest are dropped before they arrive), or
    // each cloud.
    std::function<void(const std_msgs::Header&)> frame_clock;
    std::function<void(FrameDrop, const std::string& why)> dropped;
    std::function<void(const std_msgs::Header&, const DepthImage&, const Intrinsics&)> frame;
    // A remark worth logging once (e.g. a distorted CameraInfo used through its P).
    std::function<void(const std::string&)> note;
  };

  // Subscribes on nh (NS/image + NS/camera_info, or NS/points; NS: depth for the first camera,
  // a rig camera's name for the others; a non-empty topic instead of NS/image or NS/points, its
  // camera_info beside it); callbacks run on nh's callback queue. pnh carries the
  // image_transport hints.
  DepthInput(ros::NodeHandle nh, ros::NodeHandle pnh, tf2_ros::Buffer* tf, const RosOptions& opts,
             Callbacks callbacks, const std::string& ns = "depth", const std::string& topic = "");
  ~DepthInput();

  std::string depthTopic() const { return depth_topic_; }
  std::string cameraInfoTopic() const { return info_topic_; }  // empty for a cloud

 private:
  // The subscriber -> tf2 message filter stage of every input (arrivals counted, failures said).
  template <class M>
  tf2_ros::MessageFilter<M>* connectTf(message_filters::SimpleFilter<M>* source,
                                       tf2_ros::Buffer* tf, ros::NodeHandle nh, uint32_t queue);
  template <class M>
  void connectImage(message_filters::SimpleFilter<M>* source, tf2_ros::Buffer* tf,
                    ros::NodeHandle nh, uint32_t queue);
  template <class M>
  void onSynced(const boost::shared_ptr<const M>& image,
                const sensor_msgs::CameraInfoConstPtr& info);
  template <class M>
  void onUnmatched(const boost::shared_ptr<const M>& image);
  void onCloud(const sensor_msgs::PointCloud2ConstPtr& cloud);
  // False (and dropped) for a frame older than one already handed on, unless the clock went
  // back too or the frame is over a second older (a looped bag); drops the frames still waiting
  // for tf that are older than it.
  bool inOrder(const std_msgs::Header& header);
  void convertInfo(const std_msgs::Header& header, const DepthImage& depth,
                   const sensor_msgs::CameraInfo& info);

  Callbacks cb_;
  std::string depth_topic_, info_topic_;
  std::unique_ptr<image_transport::ImageTransport> it_;
  std::unique_ptr<image_transport::SubscriberFilter> image_sub_;
  std::unique_ptr<message_filters::Subscriber<sensor_msgs::CompressedImage>> compressed_sub_;
  std::unique_ptr<message_filters::Subscriber<sensor_msgs::PointCloud2>> cloud_sub_;
  std::unique_ptr<message_filters::Subscriber<sensor_msgs::CameraInfo>> info_sub_;
  // Type-erased tf filter and synchronizer of the input in use.
  std::shared_ptr<void> tf_filter_, sync_;
  std::function<void()> clear_tf_;
  std::vector<std::string> targets_;
  std::map<ros::Time, std::string> waiting_;  // stamp -> frame of messages waiting for tf
  ros::Time last_delivered_;
};

}  // namespace gmm_mcl
