#pragma once
// An LCM message sent through its wire bytes and decoded again, for codec tests.

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace mrroc::test {

/// `m` encoded to bytes and decoded back (each step checked to use every byte).
template <class Msg>
Msg through_bytes(const Msg& m) {
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  Msg out;
  EXPECT_EQ(out.decode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  return out;
}

}  // namespace mrroc::test
