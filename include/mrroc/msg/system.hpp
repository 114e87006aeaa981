#pragma once
/// @file
/// Plain values of the system messages: an SRP message (channel mrroc/srp), a process' status
/// (mrroc/status) and the SRP's message history (mrroc/srp/history/cmd and .../reply). The LCM
/// types and their codecs stay in comm/messages.hpp.

#include <cstdint>
#include <string>
#include <vector>

namespace mrroc {

/// srp_message_t severity constants.
enum class Severity : std::int8_t { debug = 0, info = 1, warning = 2, error = 3, fatal = 4 };
const char* to_string(Severity s);

/// process_status_t state constants.
enum class ProcessState : std::int8_t {
  starting = 1,
  ready = 2,
  running = 3,
  stopping = 4,
  failed = 5,
  finished = 6
};
const char* to_string(ProcessState s);

/// A message for the System Response Process (srp_message_t).
struct SrpMessage {
  std::int64_t utime = 0;  ///< time of the event [us since the Unix epoch]
  std::string process;     ///< e.g. "edp/irb6"
  std::string robot;
  Severity severity = Severity::info;
  int code = 0;  ///< 0 for informational messages
  std::string text;
};

/// A process' status or heartbeat (process_status_t).
struct ProcessStatus {
  std::int64_t utime = 0;  ///< decoded: the message's time of sending (header.utime) [us]; not
                           ///< encoded (the sender's header carries it)
  std::string process;
  std::string robot;
  int pid = 0;
  ProcessState state = ProcessState::starting;
  std::int64_t uptime_us = 0;
  std::string detail;
};

/// Request for the SRP's message history (srp_history_request_t).
struct SrpHistoryRequest {
  std::int64_t after = 0;  ///< only entries numbered above this (0: from the start)
  int max_count = 100;     ///< at most this many, the newest of them (the SRP clamps to 1..500)
  Severity min_severity = Severity::debug;
};

/// One entry of the history: its number (from 1, in the order the SRP received it) and message.
struct SrpHistoryEntry {
  std::int64_t number = 0;
  SrpMessage message;
};

/// The SRP's answer (srp_history_reply_t).
struct SrpHistoryReply {
  std::int64_t last = 0;  ///< number of the newest entry the SRP holds (0 if none)
  std::vector<SrpHistoryEntry> entries;
};

}  // namespace mrroc
