#pragma once
/// @file
/// The fixed key of fuzz_auth and of its seeds (make_seeds.cpp signs them with it).

#include <cstddef>
#include <cstdint>
#include <vector>

namespace fuzz_auth {

/// How many message types fuzz_auth's selector byte picks from (fuzz_auth.cpp, kTypes).
inline constexpr std::size_t kMessageTypes = 13;

/// 32 bytes: 0x00, 0x07, 0x0e, ... (i * 7 mod 256).
inline const std::vector<std::uint8_t>& key() {
  static const std::vector<std::uint8_t> k = [] {
    std::vector<std::uint8_t> out;
    for (unsigned i = 0; i < 32; ++i) out.push_back(static_cast<std::uint8_t>((i * 7U) & 0xffU));
    return out;
  }();
  return k;
}

}  // namespace fuzz_auth
