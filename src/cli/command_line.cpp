#include "gmm_mcl/cli/command_line.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>

namespace gmm_mcl {
namespace cli {

namespace {

std::string flagName(const std::string& param_name) {
  std::string f = param_name;
  for (char& c : f) c = c == '_' ? '-' : c;
  return f;
}

bool parseDouble(const std::string& s, double* x) {
  char* end = nullptr;
  errno = 0;
  *x = std::strtod(s.c_str(), &end);
  return !s.empty() && end == s.c_str() + s.size() && errno != ERANGE;
}

bool parseInteger(const std::string& s, long long* x) {
  char* end = nullptr;
  errno = 0;
  *x = std::strtoll(s.c_str(), &end, 10);
  return !s.empty() && end == s.c_str() + s.size() && errno != ERANGE;
}

// The text of a table parameter as its typed value; "" when it is well-formed, else why.
std::string toParamValue(const std::string& text, ParamType type, ParamValue* v) {
  v->type = type;
  switch (type) {
    case ParamType::kBool:
      if (text == "true" || text == "1" || text == "yes" || text == "on")
        v->b = true;
      else if (text == "false" || text == "0" || text == "no" || text == "off")
        v->b = false;
      else
        return "'" + text + "' is not true or false";
      return "";
    case ParamType::kInt:
      return parseInteger(text, &v->i) ? "" : "'" + text + "' is not an integer";
    case ParamType::kDouble:
      return parseDouble(text, &v->d) ? "" : "'" + text + "' is not a number";
    case ParamType::kString:
      v->s = text;
      return "";
    case ParamType::kVector3: {
      double xyz[3];
      if (!parseNumberList(text, 3, xyz)) return "'" + text + "' is not three numbers X,Y,Z";
      v->v = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
      return "";
    }
  }
  return "unknown type";
}

}  // namespace

bool parseNumberList(const std::string& text, int n, double* out) {
  const std::vector<double> v = gmm_mcl::parseNumberList(text);
  if (static_cast<int>(v.size()) != n) return false;
  std::copy(v.begin(), v.end(), out);
  return true;
}

CommandLine::CommandLine(std::string tool, std::string usage)
    : tool_(std::move(tool)),
      usage_(std::move(usage)),
      options_("options"),
      table_options_("filter parameters (the ROS parameter of the same name, '_' for '-')") {}

void CommandLine::addLocalizerParams(LocalizerParams* values, const std::set<std::string>& skip,
                                     const std::set<std::string>& groups) {
  table_values_ = values;
  for (const ParamSpec<LocalizerParams>& p : localizerParamTable()) {
    if (skip.count(p.name) || (!groups.empty() && !groups.count(p.group))) continue;
    table_flags_.insert(p.name);
  }
}

void CommandLine::describeDefault(const std::string& param, const std::string& text) {
  described_defaults_[param] = text;
}

void CommandLine::particleRangeByBackend(const std::string* backend) {
  range_backend_ = backend;
  int lowest, cpu_most, cuda_most;
  defaultParticleRange("cpu", &lowest, &cpu_most);
  defaultParticleRange("cuda", &lowest, &cuda_most);
  describeDefault("num_particles", std::to_string(cpu_most) + " with the cpu backend, " +
                                       std::to_string(cuda_most) + " with cuda");
  describeDefault("min_particles", std::to_string(lowest) + ", at most --num-particles");
}

void CommandLine::addTableOptions() {
  for (const ParamSpec<LocalizerParams>& p : localizerParamTable()) {
    if (!table_flags_.count(p.name)) continue;
    const auto described = described_defaults_.find(p.name);
    const std::string shown =
        described != described_defaults_.end()
            ? described->second
            : p.get(*table_values_).toString() + (p.unit.empty() ? "" : " " + p.unit);
    const std::string name = flagName(p.name);
    const std::string help = p.help + " (" + shown + ")";
    table_options_.add_options()(name.c_str(), po::value<std::string>(), help.c_str());
  }
}

void CommandLine::addDepthNoise(DepthNoiseModel* model) {
  depth_noise_ = model;
  add()("depth-noise", value(&depth_noise_text_),
        "depth noise sigma(z) = A + B (z - Z0)^2 in metres as A,B,Z0 (0,0,0: off)");
}

void CommandLine::addNumbers(const std::string& name, int n, std::vector<double>* out) {
  NumberList& list = number_lists_[name];
  list.n = n;
  list.out = out;
  add()(name.c_str(), value(&list.text));
}

void CommandLine::alias(const std::string& old_spelling, const std::string& name) {
  aliases_["--" + old_spelling] = "--" + name;
}

void CommandLine::positional(const std::string& name, int max_count) {
  positional_.add(name.c_str(), max_count);
}

void CommandLine::fail(const std::string& why) const {
  std::cerr << tool_ << ": " << why << "\n\n" << usage_;
  std::exit(2);
}

void CommandLine::parse(int argc, char** argv) {
  if (table_values_) addTableOptions();
  std::vector<std::string> args;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::cout << usage_ << "\n" << options_;
      if (!table_flags_.empty()) std::cout << "\n" << table_options_;
      std::exit(0);
    }
    const std::string key = a.substr(0, a.find('='));
    const auto alias = aliases_.find(key);
    if (alias != aliases_.end()) a = alias->second + a.substr(key.size());
    args.push_back(a);
    // The n values of a number list as one comma-separated value (boost would take a negative
    // one for a flag).
    const auto list = a.size() > 2 ? number_lists_.find(a.substr(2)) : number_lists_.end();
    if (list != number_lists_.end()) {
      if (i + list->second.n >= argc) {
        fail(a + " needs " + std::to_string(list->second.n) + " numbers");
      }
      std::string joined;
      for (int k = 0; k < list->second.n; ++k) joined += (k ? "," : "") + std::string(argv[++i]);
      args.push_back(joined);
    }
  }
  po::options_description all;
  all.add(options_);
  if (!table_flags_.empty()) all.add(table_options_);
  try {
    po::store(
        po::command_line_parser(args)
            .options(all)
            .positional(positional_)
            .style(po::command_line_style::unix_style ^ po::command_line_style::allow_guessing)
            .run(),
        vm_);
    po::notify(vm_);
  } catch (const po::error& e) {
    fail(e.what());
  }
  for (auto& entry : number_lists_) {
    NumberList& list = entry.second;
    if (!vm_.count(entry.first)) continue;
    list.out->resize(list.n);
    if (!parseNumberList(list.text, list.n, list.out->data())) {
      fail("--" + entry.first + ": expected " + std::to_string(list.n) + " numbers (got '" +
           list.text + "')");
    }
  }
  const auto apply_depth_noise = [this] {
    if (!depth_noise_ || depth_noise_text_.empty()) return;
    double abz[3];
    if (!parseNumberList(depth_noise_text_, 3, abz))
      fail("--depth-noise: expected A,B,Z0 (got '" + depth_noise_text_ + "')");
    depth_noise_->a_m = static_cast<float>(abz[0]);
    depth_noise_->b_per_m = static_cast<float>(abz[1]);
    depth_noise_->z0_m = static_cast<float>(abz[2]);
  };
  // --depth-noise A,B,Z0 overrides a --depth-noise-preset's numbers (applied right after it),
  // and --depth-noise-a-m, -b-per-m, -z0-m (later in the table) override both.
  const bool preset_given =
      table_values_ && table_flags_.count("depth_noise_preset") && given("depth-noise-preset");
  if (!preset_given) apply_depth_noise();
  if (!table_values_) return;
  for (const ParamSpec<LocalizerParams>& p : localizerParamTable()) {
    const std::string name = flagName(p.name);
    if (!table_flags_.count(p.name) || !vm_.count(name)) continue;
    ParamValue v;
    std::string why = toParamValue(vm_[name].as<std::string>(), p.type, &v);
    if (why.empty()) why = p.check(v);
    if (!why.empty()) fail("--" + name + ": " + why);
    p.set(table_values_, v);
    if (p.name == "depth_noise_preset") apply_depth_noise();
  }
  if (range_backend_) {
    int default_min, default_max;
    defaultParticleRange(*range_backend_, &default_min, &default_max);
    ParticleFilterParams& f = table_values_->filter;
    if (!given("num-particles")) f.num_particles = default_max;
    if (!given("min-particles")) f.min_particles = std::min(default_min, f.num_particles);
  }
}

}  // namespace cli
}  // namespace gmm_mcl
