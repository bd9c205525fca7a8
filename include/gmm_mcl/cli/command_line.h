// The offline tools' command lines, on boost::program_options: each tool declares its flags
// once (the flag, where its value goes); the filter's own parameters come from the parameter
// table (gmm_mcl/filter/parameter_table.h) as --name-with-dashes. A malformed or out-of-range
// value, an unknown flag or a missing value is an error naming the flag: the tool prints it with
// its usage and exits with status 2; --help prints the usage and every flag and exits 0.
#pragma once

#include <boost/program_options.hpp>
#include <initializer_list>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "gmm_mcl/common/number_list.h"
#include "gmm_mcl/filter/parameter_table.h"

namespace gmm_mcl {
namespace cli {

namespace po = boost::program_options;

// A flag whose value lands in *target, which keeps its value when the flag is absent.
template <typename T>
po::typed_value<T>* value(T* target) {
  return po::value<T>(target);
}
// A flag without a value that sets *target to true (--quiet).
inline po::typed_value<bool>* flag(bool* target) { return po::bool_switch(target); }
// A flag without a value that sets *target to false (--no-depth-noise).
inline po::typed_value<bool>* clearFlag(bool* target) {
  return po::bool_switch()->notifier([target](bool on) {
    if (on) *target = false;
  });
}

// cli::Clear{&x}: the flag sets x to false.
struct Clear {
  bool* target;
};

// One flag of a list given to CommandLine::flags(): the name and where its value goes. A bool
// target is a switch without a value that sets it (Clear{}: clears it); a vector of strings
// takes the values that follow the flag; any other target takes one value of its type.
struct Flag {
  template <typename T>
  Flag(const char* flag_name, T* target) : name(flag_name), semantic(value(target)) {}
  Flag(const char* flag_name, bool* target) : name(flag_name), semantic(flag(target)) {}
  Flag(const char* flag_name, Clear c) : name(flag_name), semantic(clearFlag(c.target)) {}
  Flag(const char* flag_name, std::vector<std::string>* target)
      : name(flag_name), semantic(value(target)->multitoken()) {}
  const char* name;
  const po::value_semantic* semantic;  // owned by the CommandLine once added
};

class CommandLine {
 public:
  // tool: the program's name in messages; usage: the text printed before the list of flags.
  CommandLine(std::string tool, std::string usage);

  // The tool's flags: flags({{"frames", &frames}, {"quiet", &quiet}}).
  void flags(std::initializer_list<Flag> list) {
    for (const Flag& f : list) options_.add_options()(f.name, f.semantic);
  }
  // One flag with a help text or a semantic of its own.
  po::options_description_easy_init add() { return options_.add_options(); }

  // Every parameter of the localizer's table as --name-with-dashes (--lost-margin-nats,
  // --pixel-stride, --num-particles), except those named in `skip` (which the tool sets itself);
  // a given value is checked against the table's range and written into *values. Non-empty
  // `groups`: only the parameters of these groups ("frame", "measurement", ...). The tool's own
  // defaults are what *values holds when parse() runs (set before it, e.g.
  // lp.frame.pixel_stride = 8): --help shows them.
  void addLocalizerParams(LocalizerParams* values, const std::set<std::string>& skip = {},
                          const std::set<std::string>& groups = {});
  // What --help shows as the default of table parameter `param` (snake_case) where the tool's
  // default depends on other flags ("3000 on the CPU, 100000 with CUDA"); the tool sets the
  // value after parse() where the flag is not given().
  void describeDefault(const std::string& param, const std::string& text);
  // num_particles and min_particles (with addLocalizerParams) default by backend where not given
  // (defaultParticleRange: 1068..3000 on the CPU, 1068..100000 with CUDA; a --num-particles
  // below 1068 alone is a fixed count): *backend is read when parse() has run.
  void particleRangeByBackend(const std::string* backend);

  // --depth-noise A,B,Z0: the camera's depth noise sigma(z) = A + B (z - Z0)^2 in metres, the
  // three depth_noise_* parameters in one flag, written into *model when given (over the
  // numbers of a --depth-noise-preset; --depth-noise-a-m, -b-per-m and -z0-m override it).
  void addDepthNoise(DepthNoiseModel* model);

  // A flag followed by n numbers (--crop-box X0 Y0 Z0 X1 Y1 Z1; negative ones too), written
  // into *out (resized to n) when given.
  void addNumbers(const std::string& name, int n, std::vector<double>* out);

  // `old_spelling` (e.g. "lost-margin") is read as `name` ("lost-margin-nats").
  void alias(const std::string& old_spelling, const std::string& name);

  // Bare arguments fill these flags in order (the last may take any number).
  void positional(const std::string& name, int max_count = 1);

  // Parses; on --help (-h) prints the usage and the flags and exits 0, on an error prints
  // "<tool>: <why>" and the usage and exits 2.
  void parse(int argc, char** argv);

  // Whether the flag was given on the command line.
  bool given(const std::string& name) const { return vm_.count(name) && !vm_[name].defaulted(); }

  // Prints "<tool>: <why>" and the usage to stderr and exits 2.
  [[noreturn]] void fail(const std::string& why) const;

 private:
  std::string tool_, usage_;
  po::options_description options_;
  po::options_description table_options_;
  po::positional_options_description positional_;
  std::map<std::string, std::string> aliases_;
  po::variables_map vm_;
  // The table's flags, described with the tool's defaults when parse() runs.
  void addTableOptions();
  LocalizerParams* table_values_ = nullptr;
  std::set<std::string> table_flags_;
  std::map<std::string, std::string> described_defaults_;
  const std::string* range_backend_ = nullptr;
  struct NumberList {
    int n;
    std::vector<double>* out;
    std::string text;
  };
  std::map<std::string, NumberList> number_lists_;
  std::string depth_noise_text_;
  DepthNoiseModel* depth_noise_ = nullptr;
};

// Parses "a,b,c" into n numbers; false when it is not n numbers.
bool parseNumberList(const std::string& text, int n, double* out);

}  // namespace cli
}  // namespace gmm_mcl
