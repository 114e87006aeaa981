#include "mrroc/comm/reporter.hpp"

#include <unistd.h>

#include <cstdio>

#include <fmt/format.h>

#include "mrroc/comm/edge.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"

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
  comm::Envelope header;
  {
    std::lock_guard lock(mutex_);
    header.seq = ++seq_;
  }
  header.utime = now_utime();
  header.sender = sender_;
  comm::broadcast(bus_, channels::srp, header,
                  SrpMessage{header.utime, process_, robot_, severity, code, text});
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
  comm::Envelope header;
  ProcessStatus status;
  {
    std::lock_guard lock(mutex_);
    header.seq = ++seq_;
    status.state = state_;
    status.detail = detail_;
  }
  header.utime = now_utime();
  header.sender = sender_;
  status.process = process_;
  status.robot = robot_;
  status.pid = static_cast<int>(::getpid());
  status.uptime_us = (monotonic_ns() - started_ns_) / 1000;
  comm::broadcast(bus_, channels::status, header, status);
}

struct SystemListener::Impl {
  comm::Subscriber<SrpMessage> messages;
  comm::Subscriber<ProcessStatus> statuses;
};

SystemListener::SystemListener(comm::Bus& bus, MessageHandler on_message, StatusHandler on_status)
    : impl_(std::make_unique<Impl>(Impl{
          comm::Subscriber<SrpMessage>(
              bus, channels::srp,
              [handler = std::move(on_message)](const SrpMessage& m, const comm::Received& in) {
                if (!handler) return;
                if (in.authentic_unreported()) {  // kept, marked: no drop to report
                  handler(m);
                  return;
                }
                SrpMessage marked = m;
                marked.text = std::string(kUnverifiedMark) + m.text;
                handler(marked);
              }),
          comm::Subscriber<ProcessStatus>(
              bus, channels::status,
              [handler = std::move(on_status)](const ProcessStatus& s, const comm::Received& in) {
                if (handler && in.authentic()) handler(s);
              })})) {}

SystemListener::~SystemListener() = default;

std::uint64_t SystemListener::malformed() const {
  return impl_->messages.malformed() + impl_->statuses.malformed();
}

std::uint64_t SystemListener::unauthenticated() const {
  return impl_->messages.unauthenticated() + impl_->statuses.unauthenticated();
}

}  // namespace mrroc
