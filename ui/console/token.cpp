#include "console/token.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/random.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include "mrroc/core/error.hpp"

namespace mrroc::ui {

std::string generate_token() {
  std::array<unsigned char, kTokenBytes> bytes{};
  std::size_t got = 0;
  while (got < bytes.size()) {
    const ssize_t n = ::getrandom(bytes.data() + got, bytes.size() - got, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw Error(fmt::format("cannot generate the console's API token: getrandom: {}",
                              std::strerror(errno)));
    got += static_cast<std::size_t>(n);
  }
  std::string hex;
  for (const unsigned char b : bytes) hex += fmt::format("{:02x}", b);
  return hex;
}

std::filesystem::path generated_token_file(const std::filesystem::path& log_dir, int port) {
  const std::filesystem::path dir = log_dir.empty() ? std::filesystem::current_path() : log_dir;
  return dir / fmt::format("ui-{}.token", port);
}

TokenFile::TokenFile(std::filesystem::path file, std::string token)
    : file_(std::move(file)), token_(std::move(token)) {
  const auto fail = [this](const std::string& why) {
    return Error(
        fmt::format("cannot write the console's API token to '{}': {}", file_.string(), why));
  };
  const std::filesystem::path dir = file_.parent_path();
  std::error_code ec;
  if (!dir.empty()) std::filesystem::create_directories(dir, ec);
  if (ec) throw fail(ec.message());
  std::string name(1, '.');  // piece by piece: GCC 12's -O3 warns about `"." + std::string`
  name += file_.filename().string();
  name += ".XXXXXX";
  std::string temp = (dir / name).string();
  const int fd = ::mkostemp(temp.data(), O_CLOEXEC);  // mode 0600
  if (fd < 0) throw fail(std::strerror(errno));
  const std::string line = token_ + "\n";
  const bool written = ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
  const int write_errno = errno;
  if (::close(fd) != 0 || !written || ::rename(temp.c_str(), file_.c_str()) != 0) {
    const int e = written ? errno : write_errno;
    ::unlink(temp.c_str());
    throw fail(std::strerror(e));
  }
}

TokenFile::~TokenFile() {
  // Another console (e.g. in another network namespace, same port and folder) may have written
  // its own token since: leave that one.
  std::ifstream in(file_);
  std::string line;
  std::getline(in, line);
  in.close();
  if (line == token_) {
    std::error_code ec;
    std::filesystem::remove(file_, ec);
  }
}

}  // namespace mrroc::ui
