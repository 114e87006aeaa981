#include "history.hpp"

#include <algorithm>

#include <fmt/format.h>

namespace mrroc::srp {

SrpMessage status_as_message(const ProcessStatus& status) {
  SrpMessage m;
  m.utime = status.utime;
  m.process = status.process;
  m.robot = status.robot;
  m.severity = status.state == ProcessState::failed ? Severity::error : Severity::info;
  m.code = 0;
  m.text = fmt::format("status: {} (pid {}){}", to_string(status.state), status.pid,
                       status.detail.empty() ? "" : ": " + status.detail);
  return m;
}

HistoryQuery clamp_query(std::int64_t after, std::int32_t max_count, std::int8_t min_severity) {
  HistoryQuery q;
  q.after = std::max<std::int64_t>(after, 0);
  q.max_count = std::clamp(max_count, 1, kMaxHistoryCount);
  q.min_severity = static_cast<Severity>(std::clamp<std::int8_t>(min_severity, 0, 4));
  return q;
}

History::History(std::size_t capacity) : capacity_(std::max<std::size_t>(capacity, 1)) {}

const Entry& History::add(const SrpMessage& message, bool status) {
  if (entries_.size() >= capacity_) entries_.pop_front();
  entries_.push_back(Entry{next_++, status, message});
  return entries_.back();
}

std::size_t encoded_size(const Entry& entry) {
  // header_t: 8 + (4+len+1)*2 + 8 + 1 + 8 + 2 (no tag); strings are a 4-byte length, the bytes and
  // a terminating zero. srp_message_t adds utime 8, process, robot, severity 1, code 4, text, plus
  // the 8-byte number in the reply.
  const auto str = [](const std::string& s) { return 4 + s.size() + 1; };
  const std::size_t header = 8 + str("") * 2 + 8 + 1 + 8 + 2;
  return header + 8 + str(entry.message.process) + str(entry.message.robot) + 1 + 4 +
         str(entry.message.text) + 8;
}

std::vector<Entry> History::select(const HistoryQuery& query) const {
  std::vector<Entry> newest_first;
  std::size_t bytes = 0;
  for (auto it = entries_.rbegin(); it != entries_.rend(); ++it) {
    if (it->number <= query.after) break;
    if (it->message.severity < query.min_severity) continue;
    Entry e = *it;
    if (e.message.text.size() > kMaxReplyTextBytes) {
      // Cut at a UTF-8 character boundary: never between the bytes of one character.
      std::size_t cut = kMaxReplyTextBytes - 3;
      while (cut > 0 && (static_cast<unsigned char>(e.message.text[cut]) & 0xC0U) == 0x80U) --cut;
      e.message.text.resize(cut);
      e.message.text += "...";
    }
    bytes += encoded_size(e);
    if (bytes > kMaxReplyBytes) break;
    newest_first.push_back(std::move(e));
    if (newest_first.size() >= static_cast<std::size_t>(query.max_count)) break;
  }
  return {newest_first.rbegin(), newest_first.rend()};
}

}  // namespace mrroc::srp
