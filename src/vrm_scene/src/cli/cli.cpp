#include "vrm_scene/cli/cli.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <sstream>
#include <utility>

namespace vrm_sim {
namespace cli {

namespace {

// A bad value, reported by program_options with the option's name filled in ("... for option '--rate' ...").
[[noreturn]] void badValue(const std::string& token, const std::string& expected) {
  po::error_with_option_name error("the argument '%value%' for option '%canonical_option%' is not " + expected);
  error.set_substitute("value", token);
  throw error;
}

// Strict single-token values: program_options' typed_value with its parse step replaced.
template <typename T>
class StrictValue : public po::typed_value<T> {
 public:
  StrictValue(T* target, std::string expected, T (*convert)(const std::string&, const std::string&))
      : po::typed_value<T>(target), expected_(std::move(expected)), convert_(convert) {}
  void xparse(boost::any& store, const std::vector<std::string>& tokens) const override {
    po::validators::check_first_occurrence(store);
    const std::string& token = po::validators::get_single_string(tokens);
    store = convert_(token, expected_);
  }

 private:
  std::string expected_;
  T (*convert_)(const std::string&, const std::string&);
};

double toReal(const std::string& token, const std::string& expected) {
  const std::optional<double> value = parseReal(token);
  if (!value) badValue(token, expected);
  return *value;
}

template <typename T>
T toInteger(const std::string& token, const std::string& expected) {
  if constexpr (std::is_signed_v<T>) {
    const std::optional<std::int64_t> value = parseInteger(token);
    if (!value || *value < std::numeric_limits<T>::min() || *value > std::numeric_limits<T>::max()) {
      badValue(token, expected);
    }
    return static_cast<T>(*value);
  } else {
    const std::optional<std::uint64_t> value = parseUnsigned(token);
    if (!value || *value > std::numeric_limits<T>::max()) badValue(token, expected);
    return static_cast<T>(*value);
  }
}

class RealsValue : public po::typed_value<std::vector<double>> {
 public:
  RealsValue(std::vector<double>* target, unsigned count)
      : po::typed_value<std::vector<double>>(target), count_(count) {}
  unsigned min_tokens() const override { return count_; }
  unsigned max_tokens() const override { return count_; }
  void xparse(boost::any& store, const std::vector<std::string>& tokens) const override {
    po::validators::check_first_occurrence(store);
    std::vector<double> values;
    for (const std::string& token : tokens) values.push_back(toReal(token, "a finite number"));
    store = values;
  }

 private:
  unsigned count_;
};

class ChoiceValue : public po::typed_value<std::string> {
 public:
  ChoiceValue(std::string* target, std::vector<std::string> allowed)
      : po::typed_value<std::string>(target), allowed_(std::move(allowed)) {}
  void xparse(boost::any& store, const std::vector<std::string>& tokens) const override {
    po::validators::check_first_occurrence(store);
    const std::string& token = po::validators::get_single_string(tokens);
    for (const std::string& allowed : allowed_) {
      if (token == allowed) {
        store = token;
        return;
      }
    }
    std::string list;
    for (std::size_t i = 0; i < allowed_.size(); ++i) {
      list += (i == 0 ? "" : i + 1 == allowed_.size() ? " or " : ", ") + allowed_[i];
    }
    badValue(token, list);
  }

 private:
  std::vector<std::string> allowed_;
};

}  // namespace

std::optional<double> parseReal(const std::string& text) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text[0]))) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || !std::isfinite(value) || errno == ERANGE) return std::nullopt;
  return value;
}

std::optional<std::int64_t> parseInteger(const std::string& text) {
  if (text.empty() || !(std::isdigit(static_cast<unsigned char>(text[0])) || text[0] == '-' || text[0] == '+')) {
    return std::nullopt;
  }
  char* end = nullptr;
  errno = 0;
  const long long value = std::strtoll(text.c_str(), &end, 10);
  if (end != text.c_str() + text.size() || errno == ERANGE) return std::nullopt;
  return value;
}

std::optional<std::uint64_t> parseUnsigned(const std::string& text) {
  // strtoull accepts "-1" (as 2^64 - 1): only digits here.
  if (text.empty() || !std::isdigit(static_cast<unsigned char>(text[0]))) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const unsigned long long value = std::strtoull(text.c_str(), &end, 10);
  if (end != text.c_str() + text.size() || errno == ERANGE) return std::nullopt;
  return value;
}

po::typed_value<double>* real(double* target) { return new StrictValue<double>(target, "a finite number", &toReal); }

po::typed_value<std::vector<double>>* reals(std::vector<double>* target, unsigned count) {
  return new RealsValue(target, count);
}

po::typed_value<int>* integer(int* target) { return new StrictValue<int>(target, "an integer", &toInteger<int>); }

po::typed_value<std::uint32_t>* uint32(std::uint32_t* target) {
  return new StrictValue<std::uint32_t>(target, "an integer in [0, 2^32)", &toInteger<std::uint32_t>);
}

po::typed_value<std::uint64_t>* uint64(std::uint64_t* target) {
  return new StrictValue<std::uint64_t>(target, "a non-negative integer", &toInteger<std::uint64_t>);
}

po::typed_value<std::string>* choice(std::string* target, std::vector<std::string> allowed) {
  return new ChoiceValue(target, std::move(allowed));
}

CommandLine::CommandLine(std::string program, std::string usage, std::string description, std::string details)
    : program_(std::move(program)),
      usage_(std::move(usage)),
      description_(std::move(description)),
      details_(std::move(details)),
      options_("Options", 120, 60) {
  options_.add_options()("help,h", "print this help and exit");
}

CommandLine& CommandLine::positional(const char* name, int max_count) {
  positional_.add(name, max_count);
  return *this;
}

std::string CommandLine::help() const {
  std::ostringstream text;
  std::istringstream forms(usage_);
  std::string form;
  for (bool first = true; std::getline(forms, form); first = false) {
    text << (first ? "usage: " : "       ") << program_ << (form.empty() ? "" : " ") << form << '\n';
  }
  text << description_ << "\n\n" << options_;
  if (!details_.empty()) text << '\n' << details_ << (details_.back() == '\n' ? "" : "\n");
  return text.str();
}

int CommandLine::fail(const std::string& problem) const {
  std::fprintf(stderr, "%s: %s (%s --help prints the usage)\n", program_.c_str(), problem.c_str(), program_.c_str());
  return 2;
}

std::optional<int> CommandLine::parse(int argc, const char* const argv[]) {
  // --help wins over every other problem of the command line (a user asking how to call the tool).
  for (int i = 1; i < argc; ++i) {
    const std::string argument = argv[i];
    if (argument == "--") break;
    if (argument == "--help" || argument == "-h") {
      std::cout << help() << std::flush;
      return 0;
    }
  }
  // No abbreviations (--sce for --scene): a script that relies on one breaks when an option is added.
  const int style = po::command_line_style::unix_style & ~po::command_line_style::allow_guessing;
  // "--pin=" is an empty value, as "--pin ''" is (program_options would reject the empty text after '=').
  std::vector<std::string> arguments;
  for (int i = 1; i < argc; ++i) {
    const std::string argument = argv[i];
    if (argument.size() > 3 && argument.compare(0, 2, "--") == 0 && argument.back() == '=' &&
        argument.find('=') == argument.size() - 1) {
      arguments.push_back(argument.substr(0, argument.size() - 1));
      arguments.emplace_back();
    } else {
      arguments.push_back(argument);
    }
  }
  po::options_description all;
  all.add(options_).add(hidden_);
  try {
    po::store(po::command_line_parser(arguments).options(all).positional(positional_).style(style).run(), values_);
    po::notify(values_);
  } catch (const po::too_many_positional_options_error&) {
    // program_options does not say which argument is one too many; name it.
    const po::parsed_options parsed =
        po::command_line_parser(arguments).options(all).style(style).allow_unregistered().run();
    unsigned index = 0;
    for (const po::option& option : parsed.options) {
      if (option.position_key < 0 || option.value.empty()) continue;
      if (index++ == positional_.max_total_count()) return fail("unexpected argument '" + option.value[0] + "'");
    }
    return fail("too many arguments");
  } catch (const po::error& error) {
    return fail(error.what());
  }
  return std::nullopt;
}

}  // namespace cli
}  // namespace vrm_sim
