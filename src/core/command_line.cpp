#include "mrroc/core/command_line.hpp"

#include <fmt/format.h>

#include <CLI/CLI.hpp>

#include "mrroc_build_options.hpp"

namespace mrroc {

namespace {

CLI::Option* opt(void* p) { return static_cast<CLI::Option*>(p); }
CLI::App* app_of(void* p) { return static_cast<CLI::App*>(p); }

/// A check that `in` is a number `rule` accepts (it returns "" or what is wrong, naming the value
/// and the limit as written: CLI::Range prints them with six decimals).
template <class Rule>
CLI::Validator numeric(Rule rule, std::string description) {
  return CLI::Validator(
      [rule](std::string& in) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(in, v)) return fmt::format("'{}' is not a number", in);
        return rule(v, in);
      },
      std::move(description));
}

}  // namespace

struct CommandLine::Impl {
  CLI::App app;
  Impl(const std::string& description, const std::string& program) : app(description, program) {}
};

CommandLineOption& CommandLineOption::required() {
  opt(option_)->required();
  return *this;
}

CommandLineOption& CommandLineOption::range(double min, double max) {
  opt(option_)->check(numeric(
      [min, max](double v, const std::string& in) -> std::string {
        if (v < min) return fmt::format("{} is below {}", in, min);
        if (v > max) return fmt::format("{} is above {}", in, max);
        return {};
      },
      fmt::format("in {}..{}", min, max)));
  return *this;
}

CommandLineOption& CommandLineOption::positive() {
  opt(option_)->check(numeric(
      [](double v, const std::string& in) {
        return v > 0.0 ? std::string() : fmt::format("{} is not above 0", in);
      },
      "above 0"));
  return *this;
}

CommandLineOption& CommandLineOption::one_of(const std::vector<std::string>& values) {
  opt(option_)->check(CLI::IsMember(values));
  return *this;
}

CommandLineOption& CommandLineOption::show_default() {
  opt(option_)->capture_default_str();
  return *this;
}

CommandLine::CommandLine(const std::string& program, const std::string& description)
    : root_(std::make_shared<Impl>(description, program)), app_(&root_->app) {
  root_->app.set_version_flag("--version", std::string(program) + " (mrroc) " + kVersion);
}

CommandLine::CommandLine(std::shared_ptr<Impl> root, void* app)
    : root_(std::move(root)), app_(app) {}

CommandLine::~CommandLine() = default;

CommandLineOption CommandLine::option(const std::string& names, std::string& value,
                                      const std::string& help) {
  return CommandLineOption(app_of(app_)->add_option(names, value, help));
}

CommandLineOption CommandLine::option(const std::string& names, int& value,
                                      const std::string& help) {
  return CommandLineOption(app_of(app_)->add_option(names, value, help));
}

CommandLineOption CommandLine::option(const std::string& names, double& value,
                                      const std::string& help) {
  return CommandLineOption(app_of(app_)->add_option(names, value, help));
}

CommandLineOption CommandLine::option(const std::string& names, std::vector<std::string>& values,
                                      const std::string& help) {
  return CommandLineOption(app_of(app_)->add_option(names, values, help));
}

CommandLineOption CommandLine::flag(const std::string& names, bool& value,
                                    const std::string& help) {
  return CommandLineOption(app_of(app_)->add_flag(names, value, help));
}

CommandLine& CommandLine::subcommand(const std::string& name, const std::string& description) {
  CLI::App* sub = app_of(app_)->add_subcommand(name, description);
  children_.push_back(std::unique_ptr<CommandLine>(new CommandLine(root_, sub)));
  return *children_.back();
}

void CommandLine::require_subcommand() { app_of(app_)->require_subcommand(1); }

bool CommandLine::got(const std::string& name) const { return app_of(app_)->got_subcommand(name); }

std::optional<int> CommandLine::parse(int argc, const char* const* argv) {
  CLI::App& app = root_->app;
  try {
    app.parse(argc, argv);
    return std::nullopt;
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);  // prints the error and the hint to stderr
    return kUsageError;
  }
}

}  // namespace mrroc
