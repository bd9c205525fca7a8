// Every parameter described once: name, the struct field it maps to, type, unit, default (the
// struct's own default initialiser), range, help and whether it can change while running. The
// ROS parameters, dynamic_reconfigure (cfg/Localizer.cfg), the parameter reference
// (docs/parameters.md) and the startup log are all derived from these tables; a tool's
// command-line flag is the name with '-' for '_' (--sigma-translation-m).
//
// ParamTable<S> is generic: localizerParamTable() describes the core's LocalizerParams; the ROS
// layer describes its own options with the same type (gmm_mcl/ros/ros_params.h).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "gmm_mcl/filter/params.h"

namespace gmm_mcl {

enum class ParamType { kBool, kInt, kDouble, kString, kVector3 };
// "bool", "int", "double", "string", "vector3".
const char* paramTypeName(ParamType type);

// One value of any parameter type; only the member of `type` is meaningful.
struct ParamValue {
  ParamType type = ParamType::kDouble;
  bool b = false;
  long long i = 0;
  double d = 0.0;
  std::string s;
  Eigen::Vector3d v = Eigen::Vector3d::Zero();

  // As a YAML scalar or list: true, 4, 0.02, tempered, [0, 0, 1]; "unset" for a NaN double.
  std::string toString() const;
  bool operator==(const ParamValue& o) const;
  bool operator!=(const ParamValue& o) const { return !(*this == o); }
};

template <typename S>
struct ParamSpec {
  std::string name;   // ROS parameter / dynamic_reconfigure name, snake_case
  std::string field;  // the member of S it maps to, e.g. "filter.sigma_translation_m"
  ParamType type = ParamType::kDouble;
  std::string unit;      // "m", "rad", "nats/px", "px", "s", "Hz"; "" when none
  std::string group;     // section of the reference and of dynamic_reconfigure
  bool runtime = false;  // can change while running (dynamic_reconfigure), keeping the belief
  // Accepted range for numbers (also dynamic_reconfigure's bounds); cross-field rules stay in
  // the struct's validate().
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  std::vector<std::string> choices;  // kString: the accepted values (empty: any)
  std::string help;
  std::function<ParamValue(const S&)> get;
  std::function<void(S*, const ParamValue&)> set;  // the value must have `type`

  ParamValue defaultValue() const { return get(S()); }
  // "" when the value has this parameter's type and lies in its range or choices; else why,
  // naming the parameter.
  std::string check(const ParamValue& value) const;
};

template <typename S>
using ParamTable = std::vector<ParamSpec<S>>;

// The core's parameters (LocalizerParams without T_base_cam, which comes from tf or a tool's
// camera setup).
const ParamTable<LocalizerParams>& localizerParamTable();

// ---- building tables -------------------------------------------------------------------------

namespace param_detail {
inline ParamType typeOf(bool*) { return ParamType::kBool; }
inline ParamType typeOf(int*) { return ParamType::kInt; }
inline ParamType typeOf(uint64_t*) { return ParamType::kInt; }
inline ParamType typeOf(long long*) { return ParamType::kInt; }
inline ParamType typeOf(double*) { return ParamType::kDouble; }
inline ParamType typeOf(float*) { return ParamType::kDouble; }
inline ParamType typeOf(std::string*) { return ParamType::kString; }
inline ParamType typeOf(Eigen::Vector3d*) { return ParamType::kVector3; }

inline void toValue(bool x, ParamValue* v) { v->b = x; }
inline void toValue(int x, ParamValue* v) { v->i = x; }
inline void toValue(uint64_t x, ParamValue* v) { v->i = static_cast<long long>(x); }
inline void toValue(long long x, ParamValue* v) { v->i = x; }
inline void toValue(double x, ParamValue* v) { v->d = x; }
inline void toValue(float x, ParamValue* v) { v->d = x; }
inline void toValue(const std::string& x, ParamValue* v) { v->s = x; }
inline void toValue(const Eigen::Vector3d& x, ParamValue* v) { v->v = x; }

inline void fromValue(const ParamValue& v, bool* x) { *x = v.b; }
inline void fromValue(const ParamValue& v, int* x) { *x = static_cast<int>(v.i); }
inline void fromValue(const ParamValue& v, uint64_t* x) { *x = static_cast<uint64_t>(v.i); }
inline void fromValue(const ParamValue& v, long long* x) { *x = v.i; }
inline void fromValue(const ParamValue& v, double* x) { *x = v.d; }
inline void fromValue(const ParamValue& v, float* x) { *x = static_cast<float>(v.d); }
inline void fromValue(const ParamValue& v, std::string* x) { *x = v.s; }
inline void fromValue(const ParamValue& v, Eigen::Vector3d* x) { *x = v.v; }
}  // namespace param_detail

// Range of a number parameter.
struct ParamRange {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
};

// A parameter bound to a member through `ref` (S& -> T&), e.g. with GMM_MCL_PARAM_FIELD.
template <typename S, typename Ref>
ParamSpec<S> paramSpec(const char* name, const char* field, Ref ref, const char* unit,
                       const char* group, ParamRange range, bool runtime, const char* help) {
  using T = typename std::remove_reference<decltype(ref(std::declval<S&>()))>::type;
  ParamSpec<S> p;
  p.name = name;
  p.field = field;
  p.type = param_detail::typeOf(static_cast<T*>(nullptr));
  p.unit = unit;
  p.group = group;
  p.runtime = runtime;
  p.min = range.min;
  p.max = range.max;
  p.help = help;
  const ParamType type = p.type;
  p.get = [ref, type](const S& s) {
    ParamValue v;
    v.type = type;
    param_detail::toValue(ref(const_cast<S&>(s)), &v);
    return v;
  };
  p.set = [ref](S* s, const ParamValue& v) { param_detail::fromValue(v, &ref(*s)); };
  return p;
}

// "member.path", [](S& s) -> T& { return s.member.path; }
#define GMM_MCL_PARAM_FIELD(S, path) #path, [](S & s) -> decltype((s.path)) { return s.path; }

// The table that functions appending one group of parameters each make, in their order.
template <typename S>
ParamTable<S> makeParamTable(std::initializer_list<void (*)(ParamTable<S>*)> add_groups) {
  ParamTable<S> t;
  for (const auto add_group : add_groups) add_group(&t);
  return t;
}

// ---- using tables ----------------------------------------------------------------------------

template <typename S>
std::string ParamSpec<S>::check(const ParamValue& v) const {
  std::ostringstream err;
  if (v.type != type) {
    err << name << " must be a " << paramTypeName(type) << " (got a " << paramTypeName(v.type)
        << ")";
  } else if (type == ParamType::kInt || type == ParamType::kDouble) {
    const double x = type == ParamType::kInt ? static_cast<double>(v.i) : v.d;
    if (!(x >= min && x <= max))
      err << name << " must be in [" << min << ", " << max << "] (got " << x << ")";
  } else if (type == ParamType::kString && !choices.empty()) {
    bool known = false;
    for (const std::string& c : choices) known = known || c == v.s;
    if (!known) {
      err << name << " '" << v.s << "' is not one of";
      for (const std::string& c : choices) err << " " << c;
    }
  } else if (type == ParamType::kVector3 && !v.v.allFinite()) {
    err << name << " must be 3 finite numbers";
  }
  return err.str();
}

template <typename S>
const ParamSpec<S>* findParam(const ParamTable<S>& table, const std::string& name) {
  for (const ParamSpec<S>& p : table) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

// "name old -> new" for every parameter whose value differs between a and b, comma-separated.
template <typename S>
std::string describeChanges(const ParamTable<S>& table, const S& a, const S& b) {
  std::string out;
  for (const ParamSpec<S>& p : table) {
    const ParamValue va = p.get(a), vb = p.get(b);
    if (va != vb)
      out += (out.empty() ? "" : ", ") + p.name + " " + va.toString() + " -> " + vb.toString();
  }
  return out;
}

// The effective values, one group per line ("group: name value unit, ..."); values that
// differ from the default are marked with '*'.
template <typename S>
std::string describeParams(const ParamTable<S>& table, const S& values) {
  std::string out, group;
  for (const ParamSpec<S>& p : table) {
    if (p.group != group) {
      out += (out.empty() ? "" : "\n") + p.group + ":";
      group = p.group;
    } else {
      out += ",";
    }
    const ParamValue v = p.get(values);
    out += " " + p.name + " " + v.toString() + (p.unit.empty() ? "" : " " + p.unit) +
           (v != p.defaultValue() ? "*" : "");
  }
  return out;
}

// The parameter reference as Markdown: one table per group with name, type, default, unit,
// whether it can change while running, and what it does.
template <typename S>
std::string markdownReference(const ParamTable<S>& table) {
  std::string out, group;
  for (const ParamSpec<S>& p : table) {
    if (p.group != group) {
      out += (out.empty() ? "" : "\n") + std::string("### ") + p.group + "\n\n" +
             "| parameter | type | default | unit | range | run time | description |\n" +
             "|---|---|---|---|---|---|---|\n";
      group = p.group;
    }
    std::ostringstream range;
    if (!p.choices.empty()) {
      for (size_t i = 0; i < p.choices.size(); ++i) range << (i ? ", " : "") << p.choices[i];
    } else if (std::isfinite(p.min) || std::isfinite(p.max)) {
      range << "[" << p.min << ", " << p.max << "]";
    }
    out += "| `" + p.name + "` | " + paramTypeName(p.type) + " | " + p.defaultValue().toString() +
           " | " + p.unit + " | " + range.str() + " | " + (p.runtime ? "yes" : "no") + " | " +
           p.help + " |\n";
  }
  return out;
}

}  // namespace gmm_mcl
