#pragma once
/// @file
/// The VSP shell: raw samples in (mrroc/raw/<device> for every source), readings out
/// (CONFIGURE, INITIATE_READING, GET_READING, TERMINATE on vsp/<name>/cmd), staleness, SRP reports.
///
/// Readings: on demand (default) a reading is made at INITIATE_READING; periodic VSPs make one
/// every period and INITIATE_READING only acknowledges. GET_READING returns the last reading with
/// its age. A reading is invalid when any source has sent nothing for longer than
/// `stale_after_ms` (or nothing yet), or when the plugin failed or found its samples unusable;
/// the reason says which source. A source's age is the larger of its newest sample's age by the
/// sample's own time and the time since that sample came (this host's steady clock); a sample
/// time more than `stale_after_ms` ahead of the VSP's clock is refused on arrival, and one that
/// is ahead so far at reading time (the VSP's clock stepped back) makes the source stale. A source
/// that sent nothing acceptable for `stale_after_ms` of local time is re-anchored: its next sample
/// is taken even when older than the last one (its clock stepped back), with a warning. The first
/// invalid reading after valid ones (and the return to valid) is reported to the SRP naming the VSP
/// and the source. TERMINATE stops the readings (GET_READING answers an error) until the next
/// CONFIGURE; the process keeps running.
#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/vsp/sensor.hpp"

namespace mrroc::vsp {

class Shell {
 public:
  /// The wall clock the samples' times are compared with [us since the Unix epoch].
  using WallClock = std::function<std::int64_t()>;

  /// @param clock  now_utime unless a test moves this VSP's clock
  Shell(comm::Bus& bus, Reporter& reporter, const VspConfig& config,
        std::unique_ptr<SensorPlugin> plugin, WallClock clock = {});
  ~Shell();
  Shell(const Shell&) = delete;
  Shell& operator=(const Shell&) = delete;

  /// Answers requests until `keep_going()` returns false.
  void serve(const std::function<bool()>& keep_going);

  /// Raw samples that did not decode or that the plugin refused (counted and dropped).
  [[nodiscard]] std::uint64_t malformed() const;
  /// Raw samples not newer (by their own sample time) than the last one of their source:
  /// reordered or replayed (counted and dropped), unless the source was re-anchored.
  [[nodiscard]] std::uint64_t out_of_order() const;
  /// Raw samples taken (by their own time) more than `stale_after_ms` after this VSP's now: the
  /// sender's clock is ahead, or the time is forged (counted, dropped, the first reported).
  [[nodiscard]] std::uint64_t from_the_future() const;
  /// Times a source's clock was re-anchored: after it went stale by this host's clock, a sample
  /// older than its last one was taken (counted, reported).
  [[nodiscard]] std::uint64_t reanchored() const;
  /// Raw samples that were not authentic with the set's key (counted, dropped, reported).
  [[nodiscard]] std::uint64_t unauthenticated() const;

 private:
  void on_sample(const RawSample& sample, const comm::Received& in);
  void on_malformed(const std::string& channel, const std::string& why);
  void make_reading(const Params& context);
  Reply handle(const Request& request);

  comm::Bus& bus_;
  Reporter& reporter_;
  VspConfig config_;
  std::unique_ptr<SensorPlugin> plugin_;
  comm::VspServer server_;
  std::map<std::string, std::size_t> source_of_channel_;
  WallClock clock_;

  mutable std::mutex mutex_;
  std::vector<bool> received_;                   ///< per source: a sample taken
  std::vector<std::int64_t> last_sample_utime_;  ///< per source: its sample time [us]
  /// per source: when its last sample was taken here (this host's steady clock)
  std::vector<std::chrono::steady_clock::time_point> last_received_;
  std::optional<Reading> reading_;
  std::int64_t reading_no_ = 0;
  bool terminated_ = false;
  bool was_valid_ = true;
  std::uint64_t malformed_ = 0;
  bool malformed_reported_ = false;
  std::uint64_t out_of_order_ = 0;
  bool out_of_order_reported_ = false;
  std::uint64_t from_the_future_ = 0;
  bool from_the_future_reported_ = false;
  std::uint64_t reanchored_ = 0;
  std::optional<std::chrono::steady_clock::time_point> reanchor_reported_;  ///< the last report
  std::vector<comm::Subscriber<RawSample>> subscribers_;  ///< last: end before what they use

  std::thread periodic_;
  bool stopping_ = false;
  std::condition_variable cv_;
};

}  // namespace mrroc::vsp
