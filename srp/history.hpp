#pragma once
// The SRP's memory of the last messages, numbered from 1 in arrival order, and the answer to a
// history request (srp_history_request_t) built from it.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "mrroc/comm/reporter.hpp"

namespace mrroc::srp {

/// One entry: an SRP message, or a status change of a process written as a message.
struct Entry {
  std::int64_t number = 0;  ///< 1, 2, 3, ... in the order the SRP received them
  bool status = false;      ///< a process status change rather than a message
  SrpMessage message;
};

/// A status change as a history entry: severity info (error for FAILED), code 0, text
/// "status: <state> (pid N)" plus ": <detail>" when there is one.
SrpMessage status_as_message(const ProcessStatus& status);

/// What a history request asks for, after clamping: entries numbered above `after` with severity
/// at least `min_severity`, at most `max_count` of them (the newest if more match).
struct HistoryQuery {
  std::int64_t after = 0;
  int max_count = 100;
  Severity min_severity = Severity::debug;
};

/// Largest `max_count` a request may ask for; larger values are clamped to it, smaller than 1 to 1.
inline constexpr int kMaxHistoryCount = 500;
/// Encoded size the entries of one reply stay below [bytes]: one UDP datagram of LCM's
/// multicast transport holds 65 507 bytes; a reply that fits in one is never lost in part.
inline constexpr std::size_t kMaxReplyBytes = 60000;
/// Texts longer than this are cut in history replies (not in the log) [bytes].
inline constexpr std::size_t kMaxReplyTextBytes = 4096;

/// Clamps the raw request fields into a query (max_count to 1..500, min_severity to 0..4).
HistoryQuery clamp_query(std::int64_t after, std::int32_t max_count, std::int8_t min_severity);

class History {
 public:
  /// @param capacity  entries kept (the oldest are forgotten); at least 1.
  explicit History(std::size_t capacity);

  /// Stores a copy of `message` under the next number and returns the entry.
  const Entry& add(const SrpMessage& message, bool status);

  /// The entries matching `query`, oldest first. The answer is cut (oldest entries dropped) so that
  /// its estimated encoded size stays below kMaxReplyBytes; texts are cut to kMaxReplyTextBytes.
  [[nodiscard]] std::vector<Entry> select(const HistoryQuery& query) const;

  /// Number of the newest entry (0 if none yet).
  [[nodiscard]] std::int64_t last() const { return next_ - 1; }
  [[nodiscard]] std::size_t size() const { return entries_.size(); }

 private:
  std::size_t capacity_;
  std::int64_t next_ = 1;
  std::deque<Entry> entries_;
};

/// Encoded size of one srp_message_t in a reply, as lcm-gen's encoder writes it [bytes].
std::size_t encoded_size(const Entry& entry);

}  // namespace mrroc::srp
