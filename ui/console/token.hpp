#pragma once
// The console's API token when the set configures none ([ui] token_file): generated from the
// operating system's random source at start, printed once (with the page's URL) on standard
// output, and written to a file only the user can read, removed again at a clean exit
// (docs/operating.md, "Access and the token").

#include <cstddef>
#include <filesystem>
#include <string>

namespace mrroc::ui {

/// Random bytes in a generated token (192 bits).
inline constexpr std::size_t kTokenBytes = 24;

/// kTokenBytes from getrandom(2) as lower-case hex digits. @throws Error when the system gives
/// none.
[[nodiscard]] std::string generate_token();

/// Where `mrroc-ui serve` writes a token it generated: `<log_dir>/ui-<port>.token`, or in the
/// folder it runs in when `log_dir` ([launch] log_dir) is empty.
[[nodiscard]] std::filesystem::path generated_token_file(const std::filesystem::path& log_dir,
                                                         int port);

/// `token` in a file readable by its owner only (mode 0600), written whole (a temporary file in the
/// same folder renamed over it, so that no reader sees part of it and a file or link already there
/// is replaced, not written through); removed on destruction unless another token replaced it.
class TokenFile {
 public:
  /// Creates the folder when missing. @throws Error naming the file.
  TokenFile(std::filesystem::path file, std::string token);
  ~TokenFile();
  TokenFile(const TokenFile&) = delete;
  TokenFile& operator=(const TokenFile&) = delete;

  [[nodiscard]] const std::filesystem::path& path() const { return file_; }

 private:
  std::filesystem::path file_;
  std::string token_;
};

}  // namespace mrroc::ui
