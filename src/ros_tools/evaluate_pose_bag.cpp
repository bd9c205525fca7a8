// Reads a bag with the localizer's pose output and the ground truth (e.g. the demo's recording),
// matches them by stamp and prints the ATE (translation RMSE, yaw RMSE) over the frames after
// --skip seconds; writes a CSV and an SVG plot (top view of both trajectories, error over time).
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "gmm_mcl/cli/command_line.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/ros/conversions.h"

namespace gmm_mcl {

namespace {

struct Row {
  double t_s;
  Eigen::Vector3d est, gt;
  double yaw_err_rad;
  double err_m;
};

std::string polyline(const std::vector<std::pair<double, double>>& pts, const std::string& colour) {
  std::string s =
      "<polyline fill=\"none\" stroke=\"" + colour + "\" stroke-width=\"1.5\" points=\"";
  char buf[64];
  for (const auto& p : pts) {
    std::snprintf(buf, sizeof(buf), "%.2f,%.2f ", p.first, p.second);
    s += buf;
  }
  return s + "\"/>\n";
}

}  // namespace

int run(int argc, char** argv) {
  std::string bag_path, pose_topic = "/gmm_mcl/pose", gt_topic = "/ground_truth", out_prefix;
  double skip_s = 2.0;
  cli::CommandLine cl("gmm_mcl_evaluate_pose_bag",
                      "usage: gmm_mcl_evaluate_pose_bag BAG [--pose-topic T] [--truth-topic T] "
                      "[--skip S] [--out PREFIX]\n");
  // clang-format off
  cl.flags({{"bag", &bag_path}, {"pose-topic", &pose_topic}, {"truth-topic", &gt_topic},
           {"skip", &skip_s}, {"out", &out_prefix}});
  // clang-format on
  cl.positional("bag");
  cl.parse(argc, argv);
  if (bag_path.empty()) cl.fail("no bag given");
  if (out_prefix.empty()) out_prefix = bag_path.substr(0, bag_path.rfind('.'));
  std::map<uint64_t, Eigen::Isometry3d> est, gt;
  try {
    rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
    rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{pose_topic, gt_topic}));
    for (const rosbag::MessageInstance& m : view) {
      if (m.getTopic() == pose_topic) {
        auto p = m.instantiate<geometry_msgs::PoseWithCovarianceStamped>();
        if (p) est[p->header.stamp.toNSec()] = ros_conv::isometryFromPose(p->pose.pose);
      } else {
        auto p = m.instantiate<geometry_msgs::PoseStamped>();
        if (p) gt[p->header.stamp.toNSec()] = ros_conv::isometryFromPose(p->pose);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cannot read %s: %s\n", bag_path.c_str(), e.what());
    return 1;
  }
  std::vector<Row> rows;
  for (const auto& e : est) {
    const auto g = gt.find(e.first);
    if (g == gt.end()) continue;
    Row r;
    r.t_s = e.first * 1e-9;
    r.est = e.second.translation();
    r.gt = g->second.translation();
    r.err_m = (r.est - r.gt).norm();
    r.yaw_err_rad = std::abs(
        wrapAngle(yawFromRotation(e.second.linear()) - yawFromRotation(g->second.linear())));
    rows.push_back(r);
  }
  if (rows.empty()) {
    std::fprintf(stderr,
                 "no pose on %s matched a ground-truth stamp on %s (%zu poses, %zu truths)\n",
                 pose_topic.c_str(), gt_topic.c_str(), est.size(), gt.size());
    return 1;
  }
  const double t_first = rows.front().t_s;
  double sum_sq = 0, sum_yaw_sq = 0;
  int n = 0;
  std::ofstream csv(out_prefix + "_ate.csv");
  csv << "t_s,est_x,est_y,est_z,gt_x,gt_y,gt_z,error_m,yaw_error_deg\n";
  for (const Row& r : rows) {
    csv << r.t_s - t_first << "," << r.est.x() << "," << r.est.y() << "," << r.est.z() << ","
        << r.gt.x() << "," << r.gt.y() << "," << r.gt.z() << "," << r.err_m << ","
        << r.yaw_err_rad * 180.0 / M_PI << "\n";
    if (r.t_s - t_first < skip_s) continue;
    sum_sq += r.err_m * r.err_m;
    sum_yaw_sq += r.yaw_err_rad * r.yaw_err_rad;
    ++n;
  }
  // SVG: left, top view (x right, y up) of truth (black) and estimate (red); right, error (m).
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9, emax = 0.05;
  for (const Row& r : rows) {
    for (const Eigen::Vector3d& p : {r.est, r.gt}) {
      x0 = std::min(x0, p.x());
      x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y());
      y1 = std::max(y1, p.y());
    }
    emax = std::max(emax, r.err_m);
  }
  const double span = std::max({x1 - x0, y1 - y0, 0.5});
  std::vector<std::pair<double, double>> pe, pg, perr;
  const double t_span = std::max(1e-6, rows.back().t_s - t_first);
  for (const Row& r : rows) {
    pe.emplace_back(20 + 360 * (r.est.x() - x0) / span, 380 - 360 * (r.est.y() - y0) / span);
    pg.emplace_back(20 + 360 * (r.gt.x() - x0) / span, 380 - 360 * (r.gt.y() - y0) / span);
    perr.emplace_back(420 + 360 * (r.t_s - t_first) / t_span, 380 - 360 * r.err_m / emax);
  }
  std::ofstream svg(out_prefix + "_ate.svg");
  char title[256];
  std::snprintf(title, sizeof(title),
                "ATE %.3f m, yaw %.2f deg RMSE (after %.1f s); error axis 0..%.2f m",
                n ? std::sqrt(sum_sq / n) : 0.0, n ? std::sqrt(sum_yaw_sq / n) * 180 / M_PI : 0.0,
                skip_s, emax);
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"800\" height=\"420\">\n"
      << "<rect width=\"800\" height=\"420\" fill=\"white\"/>\n"
      << "<text x=\"20\" y=\"405\" font-size=\"13\">" << title << "</text>\n"
      << "<rect x=\"20\" y=\"20\" width=\"360\" height=\"360\" fill=\"none\" stroke=\"#888\"/>\n"
      << "<rect x=\"420\" y=\"20\" width=\"360\" height=\"360\" fill=\"none\" stroke=\"#888\"/>\n"
      << "<text x=\"25\" y=\"35\" font-size=\"12\">top view: truth (black), estimate (red)</text>\n"
      << "<text x=\"425\" y=\"35\" font-size=\"12\">translation error over time</text>\n"
      << polyline(pg, "black") << polyline(pe, "red") << polyline(perr, "blue") << "</svg>\n";
  if (n == 0) {
    std::fprintf(stderr, "no matched pose after the first %.1f s\n", skip_s);
    return 1;
  }
  std::printf(
      "matched %zu poses; ATE over %d poses after %.1f s: translation RMSE %.3f m, yaw RMSE "
      "%.2f deg; final error %.3f m\nwrote %s_ate.csv and %s_ate.svg\n",
      rows.size(), n, skip_s, std::sqrt(sum_sq / n), std::sqrt(sum_yaw_sq / n) * 180 / M_PI,
      rows.back().err_m, out_prefix.c_str(), out_prefix.c_str());
  return 0;
}

}  // namespace gmm_mcl

int main(int argc, char** argv) { return gmm_mcl::run(argc, argv); }
