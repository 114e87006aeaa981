#include "mrroc/comm/auth.hpp"

#include "mrroc/comm/bus.hpp"

#include <fmt/format.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>

#include <cctype>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string_view>

#include "mrroc/core/error.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/time.hpp"

namespace mrroc::comm {

std::vector<std::uint8_t> load_auth_key(const std::filesystem::path& file) {
  require_private_file(file, "authentication key file");
  std::ifstream in(file);
  if (!in) throw Error(fmt::format("authentication key file '{}' cannot be read", file.string()));
  std::stringstream text;
  text << in.rdbuf();
  std::string hex;
  for (const char c : text.str()) {
    if (std::isspace(static_cast<unsigned char>(c)) != 0) continue;
    if (std::isxdigit(static_cast<unsigned char>(c)) == 0)
      throw Error(fmt::format("authentication key file '{}': '{}' is not a hexadecimal digit",
                              file.string(), c));
    hex += c;
  }
  if (hex.size() % 2 != 0 || hex.size() < 64)
    throw Error(
        fmt::format("authentication key file '{}' holds {} hexadecimal digits; it needs an "
                    "even number, at least 64 (32 bytes; e.g. openssl rand -hex 32)",
                    file.string(), hex.size()));
  std::vector<std::uint8_t> key;
  for (std::size_t i = 0; i < hex.size(); i += 2)
    key.push_back(static_cast<std::uint8_t>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  return key;
}

void enable_auth_from_file(Bus& bus, const std::filesystem::path& key_file) {
  if (key_file.empty()) return;
  bus.enable_auth(load_auth_key(key_file));
}

Authenticator::Authenticator(std::vector<std::uint8_t> key, std::int64_t epoch_utime)
    : key_(std::move(key)), epoch_utime_(epoch_utime != 0 ? epoch_utime : now_utime()) {
  if (key_.size() < 32)
    throw Error(
        fmt::format("authentication key of {} bytes is too short (at least 32)", key_.size()));
}

std::int64_t Authenticator::next_counter() {
  std::lock_guard lock(mutex_);
  last_counter_ = std::max(last_counter_ + 1, now_utime());
  return last_counter_;
}

namespace {
constexpr std::string_view kDomain{"mrroc-auth-2"};
}  // namespace

std::size_t Authenticator::mac_input_size(const std::string& channel, std::size_t size) {
  return kDomain.size() + 4 + channel.size() + size;
}

Authenticator::Tag Authenticator::mac(const std::string& channel, const std::uint8_t* data,
                                      std::size_t size) const {
  std::vector<std::uint8_t> scratch;
  scratch.reserve(mac_input_size(channel, size));
  return mac(channel, data, size, scratch);
}

Authenticator::Tag Authenticator::mac(const std::string& channel, const std::uint8_t* data,
                                      std::size_t size, std::vector<std::uint8_t>& input) const {
  // The domain, the channel's length (4 bytes, big-endian), the channel, then the message: no
  // two (channel, message) pairs give the same input.
  input.resize(mac_input_size(channel, size));  // no allocation within the capacity
  std::uint8_t* out = input.data();
  std::memcpy(out, kDomain.data(), kDomain.size());
  out += kDomain.size();
  const auto channel_length = static_cast<std::uint32_t>(channel.size());
  for (const unsigned shift : {24U, 16U, 8U, 0U})
    *out++ = static_cast<std::uint8_t>(channel_length >> shift);
  if (!channel.empty()) std::memcpy(out, channel.data(), channel.size());
  out += channel.size();
  if (size > 0) std::memcpy(out, data, size);
  Tag tag{};
  unsigned int length = 0;
  if (HMAC(EVP_sha256(), key_.data(), static_cast<int>(key_.size()), input.data(), input.size(),
           tag.data(), &length) == nullptr)
    throw Error("HMAC-SHA256 failed in OpenSSL");
  return tag;
}

bool Authenticator::same(const std::uint8_t* a, const std::uint8_t* b, std::size_t n) {
  return CRYPTO_memcmp(a, b, n) == 0;
}

Authenticator::Verdict Authenticator::accept_counter(const std::string& sender,
                                                     const std::string& channel,
                                                     std::int64_t counter) {
  // Signed before this process started: recorded earlier (also when the reorder window below
  // would take it).
  if (counter < epoch_utime_) return Verdict::stale;
  std::lock_guard lock(mutex_);
  auto it = seen_.find(std::pair(sender, channel));
  if (it == seen_.end()) it = seen_.emplace(std::pair(sender, channel), Seen{}).first;
  Seen& s = it->second;
  if (counter > s.highest) {
    s.highest = counter;
  } else if (counter <= s.highest - kReorderWindowUs || s.recent.count(counter) != 0 ||
             counter == s.highest) {
    return Verdict::replayed;
  }
  s.recent.insert(counter);
  while (!s.recent.empty() && *s.recent.begin() <= s.highest - kReorderWindowUs)
    s.recent.erase(s.recent.begin());
  return Verdict::ok;
}

const char* to_string(Authenticator::Verdict verdict) {
  switch (verdict) {
    case Authenticator::Verdict::ok: return "ok";
    case Authenticator::Verdict::missing: return "no authentication tag";
    case Authenticator::Verdict::bad_tag: return "wrong authentication tag";
    case Authenticator::Verdict::replayed: return "replayed (counter already seen)";
    case Authenticator::Verdict::stale:
      return "stale (signed before this process started: recorded, or the hosts' clocks disagree)";
  }
  return "?";
}

}  // namespace mrroc::comm
