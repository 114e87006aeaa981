#pragma once
/// @file
/// The command line of every mrroc program: options, flags, positional arguments and subcommands,
/// `--help` and `--version` on each, and one convention for the exit code: a usage error prints
/// what was wrong and `Run with --help for more information.` on stderr and ends the program with
/// kUsageError (2). It wraps CLI11, compiled once in the library, so that a program's own file
/// does not compile the parser again.
///
///   mrroc::CommandLine cli("mrroc-edp", "Effector Driver Process: ...");
///   std::string config;
///   cli.option("-c,--config", config, "process-set config file (TOML)").required();
///   if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace mrroc {

/// Exit code of a program given a bad command line.
inline constexpr int kUsageError = 2;

class CommandLine;

/// An option just added; its methods add rules and return it for chaining.
class CommandLineOption {
 public:
  /// The option must be given.
  CommandLineOption& required();
  /// The value must lie within [min, max] (numeric options).
  CommandLineOption& range(double min, double max);
  /// The value must be above 0 (numeric options).
  CommandLineOption& positive();
  /// The value must be one of `values`.
  CommandLineOption& one_of(const std::vector<std::string>& values);
  /// `--help` shows the variable's value at the time of adding the option as its default.
  CommandLineOption& show_default();

 private:
  friend class CommandLine;
  explicit CommandLineOption(void* option) : option_(option) {}
  void* option_;  // CLI::Option*
};

class CommandLine {
 public:
  /// `program` is the name `--help` and `--version` show (e.g. "mrroc-edp").
  CommandLine(const std::string& program, const std::string& description);
  ~CommandLine();
  CommandLine(const CommandLine&) = delete;
  CommandLine& operator=(const CommandLine&) = delete;

  /// An option taking a value (`names` as "-c,--config"), or a positional argument (a name
  /// without dashes). The variable keeps its value when the option is not given.
  CommandLineOption option(const std::string& names, std::string& value, const std::string& help);
  CommandLineOption option(const std::string& names, int& value, const std::string& help);
  CommandLineOption option(const std::string& names, double& value, const std::string& help);
  /// An option that may be repeated; each occurrence appends its value.
  CommandLineOption option(const std::string& names, std::vector<std::string>& values,
                           const std::string& help);
  /// A flag: true when given.
  CommandLineOption flag(const std::string& names, bool& value, const std::string& help);

  /// A subcommand (`mrroc-ui estop ...`); its options are added to the CommandLine returned,
  /// which lives as long as this one.
  CommandLine& subcommand(const std::string& name, const std::string& description);
  /// Exactly one subcommand must be given.
  void require_subcommand();
  /// True after parse() when the subcommand `name` was given.
  [[nodiscard]] bool got(const std::string& name) const;

  /// Parses the command line. Returns nothing when the program should go on; otherwise the code
  /// to exit with: 0 after printing `--help` or `--version`, kUsageError after printing what was
  /// wrong with the command line.
  [[nodiscard]] std::optional<int> parse(int argc, const char* const* argv);

 private:
  struct Impl;
  CommandLine(std::shared_ptr<Impl> root, void* app);
  std::shared_ptr<Impl> root_;  // owns the parser and the subcommands' objects
  void* app_;                   // CLI::App* of this (sub)command
  std::vector<std::unique_ptr<CommandLine>> children_;  // subcommands
};

}  // namespace mrroc
