/// @file
/// The VSP shell (see shell.hpp).
#include "shell.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/time.hpp"

namespace mrroc::vsp {

namespace {

using SteadyClock = std::chrono::steady_clock;

double seconds_between(SteadyClock::time_point from, SteadyClock::time_point to) {
  return std::chrono::duration<double>(to - from).count();
}

/// The re-anchoring of a source is reported at most once in this time [s] (a source that keeps
/// stepping back, or a replayer during an outage, cannot flood the SRP; every one is counted).
constexpr double kReanchorReportGapS = 1.0;

}  // namespace

Shell::Shell(comm::Bus& bus, Reporter& reporter, const VspConfig& config,
             std::unique_ptr<SensorPlugin> plugin, WallClock clock)
    : bus_(bus),
      reporter_(reporter),
      config_(config),
      plugin_(std::move(plugin)),
      server_(bus, "vsp/" + config.name, channels::vsp_command(config.name),
              channels::vsp_reply(config.name)),
      clock_(clock ? std::move(clock) : WallClock(now_utime)),
      received_(config.sources.size(), false),
      last_sample_utime_(config.sources.size(), 0),
      last_received_(config.sources.size()) {
  configure_sensor(*plugin_, config);
  for (std::size_t i = 0; i < config.sources.size(); ++i) {
    const std::string channel = channels::raw_sensor(config.sources[i]);
    if (!source_of_channel_.emplace(channel, i).second)
      throw ConfigError(config.where, fmt::format("VSP '{}' lists source '{}' twice", config.name,
                                                  config.sources[i]));
    comm::SubscriberOptions options;
    options.report_malformed = false;  // on_malformed warns once, then only counts
    options.on_malformed = [this](const std::string& ch, const std::string& why) {
      on_malformed(ch, why);
    };
    subscribers_.emplace_back(
        bus_, channel,
        [this](const RawSample& sample, const comm::Received& in) { on_sample(sample, in); },
        std::move(options));
  }
  if (config_.periodic) {
    periodic_ = std::thread([this] {
      auto next = std::chrono::steady_clock::now();
      const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(config_.period_s));
      std::unique_lock lock(mutex_);
      while (!stopping_) {
        next += period;
        cv_.wait_until(lock, next, [&] { return stopping_; });
        if (stopping_) break;
        if (!terminated_) {
          lock.unlock();
          make_reading(Params{});
          lock.lock();
        }
      }
    });
  }
}

Shell::~Shell() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (periodic_.joinable()) periodic_.join();
  subscribers_.clear();
}

std::uint64_t Shell::malformed() const {
  std::lock_guard lock(mutex_);
  return malformed_;
}

void Shell::on_malformed(const std::string& channel, const std::string& why) {
  if (source_of_channel_.count(channel) == 0) return;
  std::unique_lock lock(mutex_);
  ++malformed_;
  if (malformed_reported_) return;
  malformed_reported_ = true;
  lock.unlock();
  reporter_.warning(
      fmt::format("malformed raw sample on {} dropped ({}); further ones "
                  "are only counted",
                  channel, why == "bytes that do not decode" ? "not a raw_sensor_t" : why));
}

std::uint64_t Shell::out_of_order() const {
  std::lock_guard lock(mutex_);
  return out_of_order_;
}

std::uint64_t Shell::from_the_future() const {
  std::lock_guard lock(mutex_);
  return from_the_future_;
}

std::uint64_t Shell::reanchored() const {
  std::lock_guard lock(mutex_);
  return reanchored_;
}

std::uint64_t Shell::unauthenticated() const {
  std::uint64_t n = 0;
  for (const auto& s : subscribers_) n += s.unauthenticated();
  return n;
}

void Shell::on_sample(const RawSample& sample, const comm::Received& in) {
  const std::string& channel = in.channel();
  const auto it = source_of_channel_.find(channel);
  if (it == source_of_channel_.end()) return;
  // With the set's key, only samples signed by the emulator or a driver holding it (counted,
  // reported as unauthenticated): a forged sample could steer a task into its surface.
  if (!in.authentic()) return;
  std::unique_lock lock(mutex_);
  const std::size_t source = it->second;
  const std::int64_t now = clock_();
  const SteadyClock::time_point arrived = SteadyClock::now();
  // A sample time ahead of this VSP's clock is refused beyond a tolerance: ordered by sample
  // time, such a sample would hold back every genuine one until the clock caught up with it, and
  // its negative age would keep the frozen value valid meanwhile. The tolerance is
  // stale_after_ms: the staleness check already needs the hosts' clocks to agree to well within
  // it (a source that far behind is stale), so the same bound holds ahead; a sample taken within
  // it holds genuine ones back for at most stale_after_ms, and the source's age by arrival (see
  // make_reading) makes the reading invalid rather than frozen beyond that. A fixed bound (say
  // 0.5 s) would let a 100 ms VSP serve one value for 500 ms.
  const auto tolerance_us = static_cast<std::int64_t>(std::llround(config_.stale_after_s * 1e6));
  if (sample.sample_utime - now > tolerance_us) {
    ++from_the_future_;
    if (from_the_future_reported_) return;
    from_the_future_reported_ = true;
    const std::string text = fmt::format(
        "raw sample on {} from '{}' taken at {} us, {:.0f} ms ahead of this VSP's clock ({} us; "
        "tolerance {:.0f} ms): dropped (the sender's clock is ahead, or the time is forged); "
        "further ones are only counted",
        channel, in.header().sender, sample.sample_utime,
        static_cast<double>(sample.sample_utime - now) * 1e-3, now, config_.stale_after_s * 1000.0);
    lock.unlock();
    reporter_.warning(text);
    return;
  }
  bool reanchor = false;
  double silent_s = 0.0;
  if (received_[source] && sample.sample_utime <= last_sample_utime_[source]) {
    silent_s = seconds_between(last_received_[source], arrived);
    if (silent_s <= config_.stale_after_s) {
      // Order by the sample's own time: an older (reordered, replayed) sample never replaces a
      // newer one, nor makes its source look fresh.
      ++out_of_order_;
      if (out_of_order_reported_) return;
      out_of_order_reported_ = true;
      const std::string text = fmt::format(
          "raw sample on {} from '{}' taken at {} us, not after the last one ({} us): dropped "
          "(reordered or replayed); further ones are only counted",
          channel, in.header().sender, sample.sample_utime, last_sample_utime_[source]);
      lock.unlock();
      reporter_.warning(text);
      return;
    }
    // Nothing acceptable came for stale_after_ms of this host's time, so the source is stale
    // anyway: its clock stepped back (an NTP step), and waiting for its samples to pass the old
    // last time would keep it stale for as long as the step. Its order starts again here. (A
    // replayed old sample is stale by its own time, and the next genuine one is newer.)
    reanchor = true;
  }
  try {
    plugin_->on_sample(source, sample);
  } catch (const std::exception& e) {
    // A sample the plugin cannot take (e.g. another number of values than its device has) is
    // malformed for this VSP: counted, reported, and the source is not fresher for it.
    const std::string why =
        fmt::format("plugin '{}' refused it: {}", plugin_->plugin_name(), e.what());
    lock.unlock();
    on_malformed(channel, why);
    return;
  }
  const std::int64_t last = last_sample_utime_[source];
  received_[source] = true;
  last_sample_utime_[source] = sample.sample_utime;
  last_received_[source] = arrived;
  if (!reanchor) return;
  ++reanchored_;
  if (reanchor_reported_ && seconds_between(*reanchor_reported_, arrived) < kReanchorReportGapS)
    return;
  reanchor_reported_ = arrived;
  const std::string text = fmt::format(
      "VSP '{}': the clock of source '{}' stepped back: re-anchored to the raw sample on {} "
      "from '{}' taken at {} us, {:.0f} ms before the last one ({} us), after nothing newer for "
      "{:.0f} ms (limit {:.0f} ms)",
      config_.name, config_.sources[source], channel, in.header().sender, sample.sample_utime,
      static_cast<double>(last - sample.sample_utime) * 1e-3, last, silent_s * 1000.0,
      config_.stale_after_s * 1000.0);
  lock.unlock();
  reporter_.warning(text);
}

void Shell::make_reading(const Params& context) {
  std::unique_lock lock(mutex_);
  Reading r;
  // A source's age is that of its newest sample, by the sample's own time (the emulator stamps
  // the modelled latency in; the hosts' clocks must agree): a sample that spent long on the way
  // is as stale as one never sent. It is at least the time since that sample came (this host's
  // steady clock), so a sample time ahead of the VSP's clock never keeps a value fresh, and a
  // sample time far ahead (more than stale_after_ms: on_sample refuses those, so this VSP's
  // clock stepped back since) makes the source stale: its age cannot be known.
  const std::int64_t now = clock_();
  const SteadyClock::time_point steady_now = SteadyClock::now();
  std::string stale;
  for (std::size_t i = 0; i < config_.sources.size() && stale.empty(); ++i) {
    if (!received_[i]) {
      stale = fmt::format("no sample from source '{}' yet", config_.sources[i]);
    } else {
      const double by_time = static_cast<double>(now - last_sample_utime_[i]) * 1e-6;
      const double age = std::max(by_time, seconds_between(last_received_[i], steady_now));
      if (-by_time > config_.stale_after_s)
        stale = fmt::format(
            "source '{}' stale: its newest sample is stamped {:.0f} ms ahead of this VSP's clock "
            "(tolerance {:.0f} ms; did a clock step back?)",
            config_.sources[i], -by_time * 1000.0, config_.stale_after_s * 1000.0);
      else if (age > config_.stale_after_s)
        stale = fmt::format("source '{}' stale for {:.0f} ms (limit {:.0f} ms)", config_.sources[i],
                            age * 1000.0, config_.stale_after_s * 1000.0);
    }
  }
  if (stale.empty()) {
    try {
      r = plugin_->make_reading(context);
    } catch (const std::exception& e) {
      r = Reading{};
      r.valid = false;
      r.invalid_reason = fmt::format("plugin '{}' failed: {}", plugin_->plugin_name(), e.what());
    }
    // A task never gets a valid reading it cannot use (any plugin, also a user's).
    if (r.valid && (r.names.size() != r.values.size() || r.units.size() != r.values.size())) {
      r.valid = false;
      r.invalid_reason =
          fmt::format("plugin '{}' gave {} values with {} names and {} units",
                      plugin_->plugin_name(), r.values.size(), r.names.size(), r.units.size());
    }
    for (std::size_t i = 0; r.valid && i < r.values.size(); ++i) {
      if (std::isfinite(r.values[i])) continue;
      r.valid = false;
      r.invalid_reason = fmt::format("plugin '{}' gave {} = {}, not a finite number",
                                     plugin_->plugin_name(), r.names[i], r.values[i]);
    }
  } else {
    r.valid = false;
    r.invalid_reason = stale;
  }
  std::int64_t oldest = 0;
  for (std::size_t i = 0; i < last_sample_utime_.size(); ++i)
    if (received_[i] && (oldest == 0 || last_sample_utime_[i] < oldest))
      oldest = last_sample_utime_[i];
  r.reading_utime = oldest;
  r.reading_no = ++reading_no_;
  reading_ = r;
  const bool report_invalid = !r.valid && was_valid_;
  const bool report_valid = r.valid && !was_valid_;
  was_valid_ = r.valid;
  lock.unlock();
  if (report_invalid)
    reporter_.warning(fmt::format("VSP '{}': reading invalid: {}", config_.name, r.invalid_reason));
  if (report_valid) reporter_.info(fmt::format("VSP '{}': readings valid again", config_.name));
}

Reply Shell::handle(const Request& request) {
  Reply reply;
  const auto fail = [&](int code, const std::string& text) {
    reply.kind = ReplyKind::error;
    reply.error_code = code;
    reply.error_text = text;
    return reply;
  };
  Params args;
  try {
    args = params_from_toml(request.arguments, std::string(to_string(request.command)));
  } catch (const ConfigError& e) {
    return fail(error_code::bad_argument, e.what());
  }
  switch (request.command) {
    case Command::configure: {
      try {
        std::lock_guard lock(mutex_);
        plugin_->command(args);
        terminated_ = false;
        reading_no_ = 0;
        reading_.reset();
      } catch (const ConfigError& e) {
        return fail(error_code::bad_argument, e.what());
      }
      return reply;
    }
    case Command::initiate_reading: {
      {
        std::lock_guard lock(mutex_);
        if (terminated_)
          return fail(error_code::terminated, fmt::format("VSP '{}' was terminated; CONFIGURE "
                                                          "starts it again",
                                                          config_.name));
      }
      if (!config_.periodic) make_reading(args);
      return reply;
    }
    case Command::get_reading: {
      std::lock_guard lock(mutex_);
      if (terminated_)
        return fail(
            error_code::terminated,
            fmt::format("VSP '{}' was terminated; CONFIGURE starts it again", config_.name));
      if (!reading_)
        return fail(error_code::not_configured,
                    fmt::format("VSP '{}' has no reading yet ({})", config_.name,
                                config_.periodic ? "the first period has not ended"
                                                 : "send INITIATE_READING first"));
      reply.kind = ReplyKind::reading;
      reply.reading = *reading_;
      reply.reading.age_us = reading_->reading_utime > 0
                                 ? std::max<std::int64_t>(0, clock_() - reading_->reading_utime)
                                 : 0;
      return reply;
    }
    case Command::terminate: {
      std::lock_guard lock(mutex_);
      terminated_ = true;
      reading_.reset();
      return reply;
    }
  }
  return fail(error_code::bad_argument, "unknown command");
}

void Shell::serve(const std::function<bool()>& keep_going) {
  while (keep_going()) {
    auto incoming = server_.wait_request(std::chrono::milliseconds(100));
    if (!incoming) continue;
    if (!incoming->request) {
      Reply r;
      r.kind = ReplyKind::error;
      r.error_code = error_code::bad_argument;
      r.error_text = incoming->decode_error;
      incoming->responder.reply(r);
      continue;
    }
    incoming->responder.reply(handle(*incoming->request));
  }
}

}  // namespace mrroc::vsp
