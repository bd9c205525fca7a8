#include "gmm_mcl/ros/ros_params.h"

#include <XmlRpcValue.h>
#include <dynamic_reconfigure/config_tools.h>
#include <ros/console.h>
#include <ros/names.h>
#include <ros/param.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <functional>
#include <set>
#include <sstream>

#include "gmm_mcl/fit/fit_on_load.h"
#include "gmm_mcl/map/gmm_map_io.h"

namespace gmm_mcl {

namespace {

// One XmlRpc value as a table value of `type`; false with why.
bool fromXmlRpc(XmlRpc::XmlRpcValue& x, ParamType type, ParamValue* v) {
  using X = XmlRpc::XmlRpcValue;
  v->type = type;
  auto number = [](X& e, double* d) {
    if (e.getType() == X::TypeDouble)
      *d = static_cast<double>(e);
    else if (e.getType() == X::TypeInt)
      *d = static_cast<int>(e);
    else
      return false;
    return true;
  };
  switch (type) {
    case ParamType::kBool:
      if (x.getType() != X::TypeBoolean) return false;
      v->b = static_cast<bool>(x);
      return true;
    case ParamType::kInt:
      if (x.getType() != X::TypeInt) return false;
      v->i = static_cast<int>(x);
      return true;
    case ParamType::kDouble:
      return number(x, &v->d);
    case ParamType::kString:
      if (x.getType() == X::TypeArray) {  // a list of names (~more_cameras: [down, left])
        v->s.clear();
        for (int k = 0; k < x.size(); ++k) {
          if (x[k].getType() != X::TypeString) return false;
          v->s += (k ? "," : "") + static_cast<std::string>(x[k]);
        }
        return true;
      }
      if (x.getType() != X::TypeString) return false;
      v->s = static_cast<std::string>(x);
      return true;
    case ParamType::kVector3:
      if (x.getType() != X::TypeArray || x.size() != 3) return false;
      for (int k = 0; k < 3; ++k) {
        if (!number(x[k], &v->v[k])) return false;
      }
      return true;
  }
  return false;
}

template <typename S>
void loadTable(const ros::NodeHandle& pnh, const ParamTable<S>& table, S* out,
               std::string* faults) {
  for (const ParamSpec<S>& p : table) {
    XmlRpc::XmlRpcValue x;
    if (!pnh.getParam(p.name, x)) continue;
    ParamValue v;
    if (!fromXmlRpc(x, p.type, &v)) {
      *faults += "~" + p.name + " must be a " + paramTypeName(p.type) +
                 (p.type == ParamType::kVector3 ? " (a list of 3 numbers)" : "") + "; ";
      continue;
    }
    const std::string why = p.check(v);
    if (!why.empty()) {
      *faults += "~" + why + "; ";
      continue;
    }
    p.set(out, v);
  }
}

template <typename S>
void toConfig(const ParamTable<S>& table, const S& values, dynamic_reconfigure::Config* msg) {
  using dynamic_reconfigure::ConfigTools;
  for (const ParamSpec<S>& p : table) {
    if (!p.runtime) continue;
    const ParamValue v = p.get(values);
    switch (p.type) {
      case ParamType::kBool:
        ConfigTools::appendParameter(*msg, p.name, v.b);
        break;
      case ParamType::kInt:
        ConfigTools::appendParameter(*msg, p.name, static_cast<int>(v.i));
        break;
      case ParamType::kDouble:
        ConfigTools::appendParameter(*msg, p.name, v.d);
        break;
      case ParamType::kString:
        ConfigTools::appendParameter(*msg, p.name, v.s);
        break;
      case ParamType::kVector3:
        break;  // never changeable at run time
    }
  }
}

template <typename S>
void fromConfig(const ParamTable<S>& table, const dynamic_reconfigure::Config& msg, S* out,
                std::string* faults) {
  using dynamic_reconfigure::ConfigTools;
  for (const ParamSpec<S>& p : table) {
    if (!p.runtime) continue;
    ParamValue v = p.get(*out);
    int i = 0;
    bool found = false;
    switch (p.type) {
      case ParamType::kBool:
        found = ConfigTools::getParameter(msg, p.name, v.b);
        break;
      case ParamType::kInt:
        found = ConfigTools::getParameter(msg, p.name, i);
        v.i = i;
        break;
      case ParamType::kDouble:
        found = ConfigTools::getParameter(msg, p.name, v.d);
        break;
      case ParamType::kString:
        found = ConfigTools::getParameter(msg, p.name, v.s);
        break;
      case ParamType::kVector3:
        break;
    }
    if (!found) continue;
    const std::string why = p.check(v);
    if (!why.empty())
      *faults += why + "; ";
    else
      p.set(out, v);
  }
}

template <typename S>
void cfgLines(const ParamTable<S>& table, std::set<std::string>* groups, std::ostringstream* s) {
  auto quote = [](const std::string& text) {
    std::string q = "\"";
    for (char c : text) q += (c == '"' || c == '\\') ? std::string("\\") + c : std::string(1, c);
    return q + "\"";
  };
  auto number = [](double x) {  // a Python float literal
    ParamValue v;
    v.d = x;
    const std::string s = v.toString();
    return s.find_first_of(".e") == std::string::npos ? s + ".0" : s;
  };
  for (const ParamSpec<S>& p : table) {
    if (!p.runtime) continue;
    if (groups->insert(p.group).second)
      *s << p.group << " = gen.add_group(\"" << p.group << "\")\n";
    const ParamValue d = p.defaultValue();
    *s << p.group << ".add(\"" << p.name << "\", ";
    switch (p.type) {
      case ParamType::kBool:
        *s << "bool_t, 0, " << quote(p.help) << ", " << (d.b ? "True" : "False");
        break;
      case ParamType::kInt:
        *s << "int_t, 0, " << quote(p.help) << ", " << d.i << ", " << static_cast<long long>(p.min)
           << ", " << static_cast<long long>(p.max);
        break;
      case ParamType::kDouble:
        *s << "double_t, 0, " << quote(p.help) << ", " << number(d.d) << ", " << number(p.min)
           << ", " << number(p.max);
        break;
      case ParamType::kString:
        *s << "str_t, 0, " << quote(p.help) << ", " << quote(d.s);
        if (!p.choices.empty()) {
          *s << ",\n    edit_method=gen.enum([";
          for (size_t i = 0; i < p.choices.size(); ++i) {
            *s << (i ? ", " : "") << "gen.const(" << quote(p.choices[i]) << ", str_t, "
               << quote(p.choices[i]) << ", " << quote(p.choices[i]) << ")";
          }
          *s << "], " << quote(p.name) << ")";
        }
        break;
      case ParamType::kVector3:
        break;
    }
    *s << ")\n";
  }
}

}  // namespace

namespace {

// The parameters under nh's namespace (their names relative to it) that `known` refuses, as
// "~" + prefix + name.
void listUnknown(const ros::NodeHandle& nh, const std::string& prefix,
                 const std::function<bool(const std::string&)>& known,
                 std::vector<std::string>* unknown) {
  std::vector<std::string> names;
  ros::param::getParamNames(names);
  const std::string ns = nh.getNamespace() + "/";
  for (const std::string& n : names) {
    if (n.compare(0, ns.size(), ns) != 0) continue;
    const std::string name = n.substr(ns.size());
    if (!known(name)) unknown->push_back("~" + prefix + name);
  }
}

}  // namespace

std::string loadRosParams(const ros::NodeHandle& pnh, LocalizerParams* core, RosOptions* ros,
                          std::vector<std::string>* unknown) {
  std::string faults;
  loadTable(pnh, localizerParamTable(), core, &faults);
  loadTable(pnh, rosOptionsTable(), ros, &faults);
  if (unknown) {
    // Names with a '/' are a rig camera's (loadRigCameras checks those).
    listUnknown(
        pnh, "",
        [](const std::string& name) {
          return name.find('/') != std::string::npos || findParam(localizerParamTable(), name) ||
                 findParam(rosOptionsTable(), name);
        },
        unknown);
  }
  return faults + ros->validate() + core->validate();
}

std::vector<std::string> moreCameraNames(const RosOptions& ros, std::string* error) {
  std::vector<std::string> names;
  std::string name;
  auto take = [&] {
    if (name.empty()) return;
    bool valid = std::isalpha(static_cast<unsigned char>(name[0]));
    for (char c : name) valid = valid && (std::isalnum(static_cast<unsigned char>(c)) || c == '_');
    if (!valid) {
      *error += "~more_cameras: '" + name + "' is not a ROS name (letters, digits, _); ";
    } else if (name == "depth") {
      *error += "~more_cameras: 'depth' is the first camera's namespace; ";
    } else if (std::find(names.begin(), names.end(), name) != names.end()) {
      *error += "~more_cameras: '" + name + "' is given twice; ";
    } else {
      names.push_back(name);
    }
    name.clear();
  };
  for (char c : ros.more_cameras) {
    if (c == ',' || std::isspace(static_cast<unsigned char>(c)) || c == '[' || c == ']') {
      take();
    } else {
      name += c;
    }
  }
  take();
  return names;
}

const std::vector<std::string>& rigCameraParamNames() {
  static const std::vector<std::string> names = {"depth_input",
                                                 "image_transport",
                                                 "pixel_stride",
                                                 "min_range_m",
                                                 "max_range_m",
                                                 "depth_noise_preset",
                                                 "depth_noise_a_m",
                                                 "depth_noise_b_per_m",
                                                 "depth_noise_z0_m",
                                                 "refine_depth_scale_initial",
                                                 "topic"};
  return names;
}

std::string loadRigCameras(const ros::NodeHandle& pnh, const LocalizerParams& core,
                           const RosOptions& ros, std::vector<RigCameraParams>* cameras,
                           std::vector<std::string>* unknown) {
  std::string faults;
  const std::vector<std::string> names = moreCameraNames(ros, &faults);
  const std::vector<std::string>& read = rigCameraParamNames();
  auto subset = [&read](const auto& table) {
    typename std::decay<decltype(table)>::type out;
    for (const auto& p : table) {
      if (std::find(read.begin(), read.end(), p.name) != read.end()) out.push_back(p);
    }
    return out;
  };
  // The core's table in its order (depth_noise_preset before the numbers it fills).
  static const ParamTable<LocalizerParams> core_table = subset(localizerParamTable());
  static const ParamTable<RosOptions> ros_table = subset(rosOptionsTable());
  cameras->clear();
  for (const std::string& name : names) {
    const ros::NodeHandle nh(pnh, name);
    LocalizerParams c = core;                // the first camera's values are the defaults
    c.refinement.depth_scale_initial = 1.0;  // but not its depth scale: each camera has its own
    RosOptions r = ros;
    std::string f;
    loadTable(nh, core_table, &c, &f);
    loadTable(nh, ros_table, &r, &f);
    const std::string v = c.frame.validate() + c.measurement.validate() + c.refinement.validate();
    if (!v.empty()) f += v;
    if (r.image_transport.empty()) f += "~image_transport is empty; ";
    // ~NAME/topic: the camera's image (or cloud) topic, when not NAME/image (NAME/points).
    std::string topic, topic_error;
    if (nh.hasParam("topic") && (!nh.getParam("topic", topic) || topic.empty() ||
                                 !ros::names::validate(topic, topic_error))) {
      f += "~topic must be a topic name (a string such as /down/depth/image_raw); ";
      topic.clear();
    }
    // "~pixel_stride ..." as "~down/pixel_stride ...".
    for (size_t at = f.find('~'); at != std::string::npos; at = f.find('~', at + name.size() + 2))
      f.insert(at + 1, name + "/");
    if (!f.empty()) faults += "camera '" + name + "': " + f;
    RigCameraParams cam;
    cam.name = name;
    cam.depth_input = r.depth_input;
    cam.image_transport = r.image_transport;
    cam.topic = topic;
    cam.frame = c.frame;
    cam.measurement = c.measurement;
    cam.depth_scale_initial = c.refinement.depth_scale_initial;
    cameras->push_back(cam);
    if (unknown) {
      listUnknown(
          nh, name + "/",
          [&read](const std::string& p) {
            return std::find(read.begin(), read.end(), p) != read.end();
          },
          unknown);
    }
  }
  return faults;
}

GmmMap loadNodeMap(const std::string& path, const RosOptions& ros, std::string* summary) {
#ifdef GMM_MCL_HAVE_FIT_ON_LOAD
  FitOnLoadLog log;
  log.info = [](const std::string& s) { ROS_INFO("gmm_mcl: %s", s.c_str()); };
  log.warn = [](const std::string& s) { ROS_WARN("gmm_mcl: %s", s.c_str()); };
  FitOnLoadParams params;
  params.components = ros.map_fit_components;
  params.time_limit_s = ros.map_fit_time_limit_s;
  params.cache = ros.map_fit_cache;
  FitOnLoadResult r = loadOrFitMap(path, params, log);
  if (r.from_cache) log.info(r.summary);  // a fit logs its own lines
  *summary = r.summary;
  return std::move(r.map);
#else
  if (isCloudMapPath(path)) {
    throw MapError(path +
                   ": a point cloud or mesh as the map needs the map builder, which this "
                   "build leaves out (GMM_MCL_BUILD_FIT=OFF): fit it with gmm_mcl_fit and "
                   "give the .gmm file");
  }
  (void)ros;
  GmmMap map = loadMap(path);
  *summary = std::to_string(map.size()) + " components from " + path;
  return map;
#endif
}

std::unique_ptr<Localizer> makeLocalizer(LocalizerParams* core, const RosOptions& ros,
                                         std::string* error) {
  try {
    std::string summary;
    GmmMap map = loadNodeMap(ros.map_path, ros, &summary);
    if (ros.init_from_map_bounds) core->init = mapBounds(map);
    return std::make_unique<Localizer>(*core, std::move(map));
  } catch (const std::exception& e) {
    *error = e.what();
    return nullptr;
  }
}

std::string describeParams(const LocalizerParams& core, const RosOptions& ros) {
  return describeParams(rosOptionsTable(), ros) + "\n" +
         describeParams(localizerParamTable(), core) + "\n(* differs from the default)";
}

void toReconfigure(const LocalizerParams& core, const RosOptions& ros,
                   dynamic_reconfigure::Config* msg) {
  toConfig(localizerParamTable(), core, msg);
  toConfig(rosOptionsTable(), ros, msg);
}

LocalizerConfig toLocalizerConfig(const LocalizerParams& core, const RosOptions& ros) {
  dynamic_reconfigure::Config msg;
  toReconfigure(core, ros, &msg);
  LocalizerConfig config = LocalizerConfig::__getDefault__();
  config.__fromMessage__(msg);
  return config;
}

std::string fromReconfigure(const dynamic_reconfigure::Config& msg, LocalizerParams* core,
                            RosOptions* ros) {
  LocalizerParams c = *core;
  RosOptions r = *ros;
  std::string faults;
  fromConfig(localizerParamTable(), msg, &c, &faults);
  fromConfig(rosOptionsTable(), msg, &r, &faults);
  faults += c.validate() + r.validate();
  if (faults.empty()) {
    *core = c;
    *ros = r;
  }
  return faults;
}

std::string reconfigure(LocalizerConfig* config, LocalizerParams* core, RosOptions* ros,
                        const std::function<void(const LocalizerParams&)>& apply,
                        std::string* changes) {
  dynamic_reconfigure::Config msg;
  config->__toMessage__(msg);
  LocalizerParams c = *core;
  RosOptions r = *ros;
  std::string error = fromReconfigure(msg, &c, &r);
  if (error.empty()) {
    try {
      apply(c);
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  if (!error.empty()) {
    msg = dynamic_reconfigure::Config();
    toReconfigure(*core, *ros, &msg);
    config->__fromMessage__(msg);
    return error;
  }
  const std::string a = describeChanges(localizerParamTable(), *core, c);
  const std::string b = describeChanges(rosOptionsTable(), *ros, r);
  *changes = a + (a.empty() || b.empty() ? "" : ", ") + b;
  *core = c;
  *ros = r;
  return "";
}

void savePoseParams(const ros::NodeHandle& pnh, const Particle& m,
                    const Eigen::Matrix<double, 6, 6>& c, double depth_scale,
                    const CameraScales& camera_scales) {
  if (depth_scale != 1.0) pnh.setParam("refine_depth_scale_initial", depth_scale);
  for (const auto& cam : camera_scales) {
    if (cam.second != 1.0) pnh.setParam(cam.first + "/refine_depth_scale_initial", cam.second);
  }
  pnh.setParam("initial_pose_x", m.x_m);
  pnh.setParam("initial_pose_y", m.y_m);
  pnh.setParam("initial_pose_z", m.z_m);
  pnh.setParam("initial_pose_yaw", m.yaw_rad);
  pnh.setParam("initial_cov_xx", c(0, 0));
  pnh.setParam("initial_cov_yy", c(1, 1));
  pnh.setParam("initial_cov_zz", c(2, 2));
  pnh.setParam("initial_cov_yawyaw", c(5, 5));
}

void PoseSaver::offer(double rate_hz, const ros::Time& stamp, const Particle& mean,
                      const Eigen::Matrix<double, 6, 6>& covariance, double depth_scale,
                      const CameraScales& camera_scales) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (rate_hz <= 0 || (!last_.isZero() && (stamp - last_).toSec() < 1.0 / rate_hz)) return;
  last_ = stamp;
  pending_ = true;
  mean_ = mean;
  covariance_ = covariance;
  depth_scale_ = depth_scale;
  camera_scales_ = camera_scales;
}

void PoseSaver::restart() {
  std::lock_guard<std::mutex> lock(mutex_);
  last_ = ros::Time();
}

void PoseSaver::flush(const ros::NodeHandle& pnh) {
  Particle mean;
  Eigen::Matrix<double, 6, 6> covariance;
  double depth_scale = 1.0;
  CameraScales camera_scales;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!pending_) return;
    pending_ = false;
    mean = mean_;
    covariance = covariance_;
    depth_scale = depth_scale_;
    camera_scales = camera_scales_;
  }
  savePoseParams(pnh, mean, covariance, depth_scale, camera_scales);
}

void initialPose(const RosOptions& o, Eigen::Isometry3d* T, Eigen::Matrix<double, 6, 6>* cov) {
  *T = particleToPose(
      Particle{o.initial_pose_x_m, o.initial_pose_y_m, o.initial_pose_z_m, o.initial_pose_yaw_rad},
      0, 0);
  cov->setZero();
  (*cov)(0, 0) = o.initial_cov_xx_m2;
  (*cov)(1, 1) = o.initial_cov_yy_m2;
  (*cov)(2, 2) = o.initial_cov_zz_m2;
  (*cov)(5, 5) = o.initial_cov_yawyaw_rad2;
}

std::string dynamicReconfigureCfg() {
  std::ostringstream s;
  s << "#!/usr/bin/env python\n"
       "# dynamic_reconfigure: every parameter that can change while running. Generated from the\n"
       "# parameter tables (include/gmm_mcl/filter/parameter_table.h,\n"
       "# src/ros/ros_options_table.cpp) by `gmm_mcl_params --cfg > cfg/Localizer.cfg`;\n"
       "# test_ros_params checks that they agree.\n"
       "# Defaults are the core's; the node starts from its ROS parameters.\n"
       "from dynamic_reconfigure.parameter_generator_catkin import ParameterGenerator, bool_t, "
       "double_t, int_t, str_t\n\n"
       "gen = ParameterGenerator()\n";
  std::set<std::string> groups;
  cfgLines(localizerParamTable(), &groups, &s);
  cfgLines(rosOptionsTable(), &groups, &s);
  s << "exit(gen.generate(\"gmm_mcl\", \"gmm_mcl\", \"Localizer\"))\n";
  return s.str();
}

namespace {
template <typename S>
void yamlLines(const ParamTable<S>& table, std::string* out) {
  std::string group;
  for (const ParamSpec<S>& p : table) {
    if (p.group != group) *out += "# " + (group = p.group) + "\n";
    const ParamValue v = p.defaultValue();
    const std::string value = v.toString();
    const bool unset = value == "unset" || (p.type == ParamType::kString && value.empty());
    *out += (unset ? "# " : "") + p.name + ": " +
            (p.type == ParamType::kString ? "'" + value + "'" : value) +
            (p.unit.empty() ? "" : "  # " + p.unit) + "\n";
  }
}
}  // namespace

std::string defaultsYaml() {
  std::string out =
      "# Every parameter of the localization nodelet with its default (gmm_mcl_params "
      "--defaults).\n";
  yamlLines(rosOptionsTable(), &out);
  yamlLines(localizerParamTable(), &out);
  return out;
}

std::string parameterReferenceMarkdown() {
  return "# Parameters of the localization nodelet\n\n"
         "Generated from the parameter tables (`include/gmm_mcl/filter/parameter_table.h`, "
         "`src/ros/ros_options_table.cpp`) by `gmm_mcl_params --markdown > docs/parameters.md`; "
         "`test_ros_params` checks that this file is current. Every parameter is a private "
         "parameter of the nodelet (`~name`, e.g. `/gmm_mcl/num_particles`). *Run time*: "
         "changeable while running through dynamic_reconfigure (`rosrun rqt_reconfigure "
         "rqt_reconfigure`, `rosrun dynamic_reconfigure dynparam set /gmm_mcl NAME VALUE`), "
         "keeping the particles; the others are read once at start-up. A value outside its "
         "range, of the wrong type or failing a rule between parameters (e.g. `alpha_slow` < "
         "`alpha_fast`) stops the nodelet with one message naming every fault. `unset`: no "
         "default.\n\n"
         "## The node\n\n" +
         markdownReference(rosOptionsTable()) + "\n## The filter\n\n" +
         markdownReference(localizerParamTable());
}

}  // namespace gmm_mcl
