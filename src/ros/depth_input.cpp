#include "gmm_mcl/ros/depth_input.h"

#include <image_transport/camera_common.h>

#include "gmm_mcl/ros/conversions.h"

namespace gmm_mcl {
namespace {

// CameraInfos kept for images still waiting for tf (about a second at 30 Hz).
constexpr uint32_t kSyncQueue = 30;
// A frame older than the last one used by more than this is a jump back in time, not a frame
// whose tf came late: no frame waits for tf that long in practice (the message filter keeps
// queue_size frames).
constexpr double kLongestWaitS = 1.0;

std::string noTransform(const std::vector<std::string>& targets, const std::string& frame) {
  std::string to;
  for (const std::string& t : targets) to += (to.empty() ? "" : " and ") + t;
  return "no transform " + to + " <- '" + frame + "' at the frame's stamp";
}

std::string failureWhy(tf2_ros::FilterFailureReason reason, const std::vector<std::string>& targets,
                       const std::string& frame) {
  switch (reason) {
    case tf2_ros::filter_failure_reasons::OutTheBack:
      return noTransform(targets, frame) + ": older than the tf buffer";
    case tf2_ros::filter_failure_reasons::EmptyFrameID:
      return "the depth message has no frame_id";
    default:
      return noTransform(targets, frame) + " before the next frame arrived";
  }
}

bool decode(const sensor_msgs::Image& m, DepthImage* depth, std::string* why) {
  return ros_conv::depthImageFromMsg(m, depth, why);
}
bool decode(const sensor_msgs::CompressedImage& m, DepthImage* depth, std::string* why) {
  return ros_conv::depthImageFromCompressedDepth(m, depth, why);
}

}  // namespace

DepthInput::DepthInput(ros::NodeHandle nh, ros::NodeHandle pnh, tf2_ros::Buffer* tf,
                       const RosOptions& opts, Callbacks callbacks, const std::string& ns,
                       const std::string& topic)
    : cb_(std::move(callbacks)) {
  targets_ = {opts.base_frame};
  if (opts.odometry_source == "tf" && !opts.odom_frame.empty()) targets_.push_back(opts.odom_frame);
  const uint32_t queue = static_cast<uint32_t>(opts.queue_size);
  if (opts.depth_input == "cloud") {
    const std::string cloud = topic.empty() ? ns + "/points" : topic;
    depth_topic_ = nh.resolveName(cloud);
    cloud_sub_.reset(new message_filters::Subscriber<sensor_msgs::PointCloud2>(nh, cloud, queue));
    connectTf(cloud_sub_.get(), tf, nh, queue)->registerCallback(&DepthInput::onCloud, this);
    return;
  }
  const std::string image = topic.empty() ? ns + "/image" : topic;
  depth_topic_ = nh.resolveName(image);
  info_topic_ = image_transport::getCameraInfoTopic(depth_topic_);
  info_sub_.reset(
      new message_filters::Subscriber<sensor_msgs::CameraInfo>(nh, info_topic_, kSyncQueue));
  info_sub_->registerCallback(boost::function<void(const sensor_msgs::CameraInfoConstPtr&)>(
      [this](const sensor_msgs::CameraInfoConstPtr& m) {
        cb_.camera_info(m->header);
        cb_.frame_clock(m->header);
      }));
  if (opts.image_transport == "compressedDepth") {
    depth_topic_ += "/compressedDepth";
    compressed_sub_.reset(
        new message_filters::Subscriber<sensor_msgs::CompressedImage>(nh, depth_topic_, queue));
    connectImage(compressed_sub_.get(), tf, nh, queue);
  } else {
    it_ = std::make_unique<image_transport::ImageTransport>(nh);
    image_sub_ = std::make_unique<image_transport::SubscriberFilter>(
        *it_, image, queue,
        image_transport::TransportHints(opts.image_transport, ros::TransportHints(), pnh));
    connectImage(image_sub_.get(), tf, nh, queue);
  }
}

DepthInput::~DepthInput() = default;

template <class M>
tf2_ros::MessageFilter<M>* DepthInput::connectTf(message_filters::SimpleFilter<M>* source,
                                                 tf2_ros::Buffer* tf, ros::NodeHandle nh,
                                                 uint32_t queue) {
  using MPtr = boost::shared_ptr<const M>;
  source->registerCallback(boost::function<void(const MPtr&)>([this](const MPtr& m) {
    waiting_[m->header.stamp] = m->header.frame_id;
    cb_.arrived(m->header);
    if (info_topic_.empty()) cb_.frame_clock(m->header);  // a cloud
  }));
  auto filter = std::make_shared<tf2_ros::MessageFilter<M>>(*source, *tf, "", queue, nh);
  filter->setTargetFrames(targets_);
  // Before anything downstream: the message has its transforms.
  filter->registerCallback(boost::function<void(const MPtr&)>(
      [this](const MPtr& m) { waiting_.erase(m->header.stamp); }));
  filter->registerFailureCallback([this](const MPtr& m, tf2_ros::FilterFailureReason r) {
    waiting_.erase(m->header.stamp);
    cb_.dropped(FrameDrop::kExtrinsics, failureWhy(r, targets_, m->header.frame_id));
  });
  tf_filter_ = filter;
  clear_tf_ = [filter] { filter->clear(); };
  return filter.get();
}

template <class M>
void DepthInput::connectImage(message_filters::SimpleFilter<M>* source, tf2_ros::Buffer* tf,
                              ros::NodeHandle nh, uint32_t queue) {
  auto sync = std::make_shared<message_filters::TimeSynchronizer<M, sensor_msgs::CameraInfo>>(
      *connectTf(source, tf, nh, queue), *info_sub_, kSyncQueue);
  sync->registerCallback(boost::bind(&DepthInput::onSynced<M>, this, boost::placeholders::_1,
                                     boost::placeholders::_2));
  // Called with the dropped tuple: an image that no CameraInfo with its stamp joined (the
  // image's slot empty when a CameraInfo alone is dropped).
  sync->registerDropCallback(
      boost::bind(&DepthInput::onUnmatched<M>, this, boost::placeholders::_1));
  sync_ = sync;
}

template <class M>
void DepthInput::onSynced(const boost::shared_ptr<const M>& image,
                          const sensor_msgs::CameraInfoConstPtr& info) {
  DepthImage depth;
  std::string why;
  if (!decode(*image, &depth, &why)) return cb_.dropped(FrameDrop::kConversion, why);
  convertInfo(image->header, depth, *info);
}

template <class M>
void DepthInput::onUnmatched(const boost::shared_ptr<const M>& image) {
  if (image)
    cb_.dropped(FrameDrop::kCameraInfo, "no CameraInfo with the image's stamp on " + info_topic_);
}

bool DepthInput::inOrder(const std_msgs::Header& header) {
  const ros::Time t = header.stamp;
  // tf came for an older frame only after a newer one was used: used now it would look like time
  // running backwards. Not so when the clock went back, or when the frame is older by more than
  // a frame can wait (a looped bag whose first frame is taken before /clock, which arrives on
  // another connection and thread, has gone back).
  const bool jump =
      ros::Time::now() < last_delivered_ || (last_delivered_ - t).toSec() > kLongestWaitS;
  if (!last_delivered_.isZero() && t < last_delivered_ && !jump) {
    cb_.dropped(FrameDrop::kExtrinsics,
                "tf for the frame of '" + header.frame_id + "' came after a newer frame");
    return false;
  }
  last_delivered_ = t;
  // Frames still waiting for tf that are older than this one can never be used in order.
  if (!waiting_.empty() && waiting_.rbegin()->first < t) {
    for (const auto& w : waiting_) {
      cb_.dropped(FrameDrop::kExtrinsics,
                  noTransform(targets_, w.second) + " before a newer frame was used");
    }
    waiting_.clear();
    clear_tf_();
  }
  return true;
}

void DepthInput::convertInfo(const std_msgs::Header& header, const DepthImage& depth,
                             const sensor_msgs::CameraInfo& info) {
  Intrinsics K;
  std::string why, note;
  if (!ros_conv::intrinsicsFromCameraInfo(info, depth.width_px, depth.height_px, &K, &why, &note)) {
    return cb_.dropped(FrameDrop::kCameraInfo, why);
  }
  if (!note.empty()) cb_.note(note);
  if (inOrder(header)) cb_.frame(header, depth, K);
}

void DepthInput::onCloud(const sensor_msgs::PointCloud2ConstPtr& cloud) {
  DepthImage depth;
  Intrinsics K;
  std::string why;
  if (!ros_conv::depthImageFromCloud(*cloud, &depth, &K, &why))
    return cb_.dropped(FrameDrop::kConversion, why);
  if (inOrder(cloud->header)) cb_.frame(cloud->header, depth, K);
}

}  // namespace gmm_mcl
