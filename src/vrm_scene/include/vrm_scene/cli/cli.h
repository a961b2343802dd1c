#pragma once
// The command line of every tool and benchmark (issue 34 part 2): boost::program_options plus what each tool used to
// write by hand — a consistent --help (usage line, one-line description, the options table; exit status 0), one line
// on stderr for an unknown option, a bad value or a missing required one (naming the option, and pointing to --help;
// exit status 2), and strict numbers: the whole argument must be the number ("5x" is a bad value, where
// program_options' lexical_cast would still reject it but atoi/atof took 5), doubles must be finite (lexical_cast
// accepts "nan" and "inf", which no duration, rate or length of ours can be) and unsigned integers have no sign
// (lexical_cast turns "-1" into 4294967295). ROS-free: the library vrm_cli needs only Boost.
//
//   vrm_sim::cli::CommandLine cli("tissue_offline", "--scene FILE.yaml|NAME --seconds T [options]",
//                                 "Runs a scene headless and prints one JSON object.");
//   cli.add()("scene", po::value(&scene)->required(), "the scene")("rate", cli::real(&rate)->default_value(60), "Hz");
//   if (const auto status = cli.parse(argc, argv)) return *status;
//   if (!(rate > 0.0)) return cli.fail("--rate expects a positive number");
#include <boost/program_options.hpp>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace vrm_sim {
namespace cli {

namespace po = boost::program_options;

// Strict value semantics for CommandLine::add(); they chain like po::value (->default_value(...), ->required()).
po::typed_value<double>* real(double* target = nullptr);  // a finite number
// Exactly `count` finite numbers after the option (--centre X Y Z).
po::typed_value<std::vector<double>>* reals(std::vector<double>* target, unsigned count);
po::typed_value<int>* integer(int* target = nullptr);                     // a decimal integer in int's range
po::typed_value<std::uint32_t>* uint32(std::uint32_t* target = nullptr);  // decimal, no sign, < 2^32
po::typed_value<std::uint64_t>* uint64(std::uint64_t* target = nullptr);  // decimal, no sign, < 2^64
// One of `allowed` (the error lists them).
po::typed_value<std::string>* choice(std::string* target, std::vector<std::string> allowed);

// The parsers behind the value semantics, for a tool that reads a number from elsewhere; nullopt for a bad text.
std::optional<double> parseReal(const std::string& text);
std::optional<std::int64_t> parseInteger(const std::string& text);
std::optional<std::uint64_t> parseUnsigned(const std::string& text);

class CommandLine {
 public:
  // program: the tool's name (messages start with it); usage: the synopsis after "usage: <program> " (more lines
  // for more forms); description: what the tool does, one line; details: optional text after the options table.
  CommandLine(std::string program, std::string usage, std::string description, std::string details = "");

  // The tool's options (--help is always there).
  po::options_description_easy_init add() { return options_.add_options(); }
  // Options parsed but not listed by --help (what positional() names, e.g. a command and its arguments).
  po::options_description_easy_init hidden() { return hidden_.add_options(); }
  // Positional arguments in order: `name` must be an option added with add() or hidden(); max_count -1 = any number.
  CommandLine& positional(const char* name, int max_count);

  // Parses argv. Returns the status the tool exits with at once — 0 after printing --help (-h) on stdout, 2 after a
  // usage error (one line on stderr) — or nullopt: the values are stored (targets and values()), run the tool.
  std::optional<int> parse(int argc, const char* const argv[]);
  std::optional<int> parse(int argc, char** argv) { return parse(argc, const_cast<const char* const*>(argv)); }

  const po::variables_map& values() const { return values_; }
  // Whether the command line named the option (not just its default).
  bool given(const std::string& name) const { return values_.count(name) > 0 && !values_[name].defaulted(); }
  // A problem found after parse() (a value out of range, options that exclude each other): one line on stderr,
  // "<program>: <problem> (<program> --help prints the usage)"; returns 2.
  int fail(const std::string& problem) const;
  // The --help text.
  std::string help() const;

 private:
  std::string program_, usage_, description_, details_;
  po::options_description options_, hidden_;
  po::positional_options_description positional_;
  po::variables_map values_;
};

}  // namespace cli
}  // namespace vrm_sim
