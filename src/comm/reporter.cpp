#include "mrroc/comm/reporter.hpp"

#include <unistd.h>

#include <cstdio>

#include <fmt/format.h>

#include "mrroc/comm/request_reply.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/process_status_t.hpp"
#include "mrroc_lcm/srp_message_t.hpp"

namespace mrroc {

const char* to_string(Severity s) {
  switch (s) {
    case Severity::debug: return "debug";
    case Severity::info: return "info";
    case Severity::warning: return "warning";
    case Severity::error: return "error";
    case Severity::fatal: return "fatal";
  }
  return "?";
}

const char* to_string(ProcessState s) {
  switch (s) {
    case ProcessState::starting: return "starting";
    case ProcessState::ready: return "ready";
    case ProcessState::running: return "running";
    case ProcessState::stopping: return "stopping";
    case ProcessState::failed: return "failed";
    case ProcessState::finished: return "finished";
  }
  return "?";
}

Reporter::Reporter(comm::Bus& bus, std::string process, std::string robot)
    : bus_(bus),
      process_(std::move(process)),
      robot_(std::move(robot)),
      sender_(process_ + "#" + std::to_string(::getpid())),
      started_ns_(monotonic_ns()) {
  // Messages the comm layer drops (malformed, unauthenticated) are reported to the SRP.
  bus_.set_drop_sink(
      [this](int code, const std::string& text) { report(Severity::warning, code, text); });
  heartbeat_ = std::thread([this] {
    std::unique_lock lock(mutex_);
    while (!stopping_) {
      cv_.wait_for(lock, std::chrono::seconds(1));
      if (stopping_) break;
      lock.unlock();
      publish_status();
      lock.lock();
    }
  });
}

Reporter::~Reporter() {
  bus_.set_drop_sink({});
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  heartbeat_.join();
}

void Reporter::report(Severity severity, int code, const std::string& text) {
  // Console first: the message is not lost when the bus is down.
  std::fprintf(stderr, "%s: %s: %s\n", process_.c_str(), to_string(severity), text.c_str());
  std::fflush(stderr);
  mrroc_lcm::srp_message_t m{};
  {
    std::lock_guard lock(mutex_);
    m.header.seq = ++seq_;
  }
  m.header.utime = now_utime();
  m.header.sender = sender_;
  m.header.kind = mrroc_lcm::header_t::BROADCAST;
  m.utime = m.header.utime;
  m.process = process_;
  m.robot = robot_;
  m.severity = static_cast<std::int8_t>(severity);
  m.code = code;
  m.text = text;
  comm::publish(bus_, channels::srp, m);
}

void Reporter::set_state(ProcessState state, const std::string& detail) {
  {
    std::lock_guard lock(mutex_);
    state_ = state;
    detail_ = detail;
  }
  publish_status();
}

ProcessState Reporter::state() const {
  std::lock_guard lock(mutex_);
  return state_;
}

void Reporter::publish_status() {
  mrroc_lcm::process_status_t m{};
  {
    std::lock_guard lock(mutex_);
    m.header.seq = ++seq_;
    m.state = static_cast<std::int8_t>(state_);
    m.detail = detail_;
  }
  m.header.utime = now_utime();
  m.header.sender = sender_;
  m.header.kind = mrroc_lcm::header_t::BROADCAST;
  m.process = process_;
  m.robot = robot_;
  m.pid = static_cast<std::int32_t>(::getpid());
  m.uptime_us = (monotonic_ns() - started_ns_) / 1000;
  comm::publish(bus_, channels::status, m);
}

struct SystemListener::Impl {
  comm::Bus& bus;
  MessageHandler on_message;
  StatusHandler on_status;
  std::atomic<std::uint64_t>* malformed;
  mrroc::comm::Subscription* srp_sub = nullptr;
  mrroc::comm::Subscription* status_sub = nullptr;

  static void on_srp(const lcm::ReceiveBuffer* buffer, const std::string& channel, Impl* self) {
    mrroc_lcm::srp_message_t m;
    if (!comm::detail::decode_received(buffer, m)) {
      ++*self->malformed;
      comm::detail::report_malformed(self->bus, channel, static_cast<int>(buffer->data_size));
      return;
    }
    self->message(&m);
  }
  static void on_status_message(const lcm::ReceiveBuffer* buffer, const std::string& channel,
                                Impl* self) {
    mrroc_lcm::process_status_t m;
    if (!comm::detail::decode_received(buffer, m)) {
      ++*self->malformed;
      comm::detail::report_malformed(self->bus, channel, static_cast<int>(buffer->data_size));
      return;
    }
    self->status(&m);
  }
  void message(const mrroc_lcm::srp_message_t* m) {
    if (!on_message) return;
    if (m->severity < 0 || m->severity > 4) {
      ++*malformed;
      return;
    }
    on_message(SrpMessage{m->utime, m->process, m->robot, static_cast<Severity>(m->severity),
                          m->code, m->text});
  }
  void status(const mrroc_lcm::process_status_t* m) {
    if (!on_status) return;
    if (m->state < 1 || m->state > 6) {
      ++*malformed;
      return;
    }
    on_status(ProcessStatus{m->header.utime, m->process, m->robot, m->pid,
                            static_cast<ProcessState>(m->state), m->uptime_us, m->detail});
  }
};

SystemListener::SystemListener(comm::Bus& bus, MessageHandler on_message, StatusHandler on_status)
    : impl_(std::make_unique<Impl>(
          Impl{bus, std::move(on_message), std::move(on_status), &malformed_})) {
  impl_->srp_sub = bus.subscribe<Impl*>(channels::srp, &Impl::on_srp, impl_.get());
  impl_->status_sub = bus.subscribe<Impl*>(channels::status, &Impl::on_status_message, impl_.get());
}

SystemListener::~SystemListener() {
  impl_->bus.unsubscribe(impl_->srp_sub);
  impl_->bus.unsubscribe(impl_->status_sub);
}

}  // namespace mrroc
