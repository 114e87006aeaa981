#include "console/bus_feed.hpp"

#include <chrono>
#include <exception>
#include <optional>

#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/process_set.hpp"
#include "operator.hpp"

namespace mrroc::ui {

struct BusFeed::Subscribers {
  std::vector<comm::Subscriber<RobotState>> robot_states;
  std::optional<comm::Subscriber<launch::LaunchStatus>> launch_status;
  std::optional<comm::Subscriber<SceneObjects>> scene_objects;
};

struct BusFeed::Clients {
  std::unique_ptr<MpClient> status;
  std::unique_ptr<comm::SrpHistoryClient> history;
};

BusFeed::BusFeed(comm::Bus& bus, ConsoleState& state, std::string no_mp_text)
    : state_(state), no_mp_text_(std::move(no_mp_text)) {
  // Malformed messages are counted and reported to the SRP by the subscribers (comm/edge.hpp).
  subscribers_ = std::make_unique<Subscribers>();
  for (std::size_t i = 0; i < state_.robots().size(); ++i)
    subscribers_->robot_states.emplace_back(
        bus, channels::robot_state(state_.robots()[i].name),
        [this, i](const RobotState& s, const comm::Received& in) {
          // With a key, only an EDP's own states: the jog checks and the view rely on them.
          if (!in.authentic()) return;
          state_.on_robot_state(i, s, in.header().utime);
        });
  subscribers_->launch_status.emplace(
      bus, channels::launch_status,
      [this](const launch::LaunchStatus& m, const comm::Received&) { state_.on_launch_status(m); });
  subscribers_->scene_objects.emplace(
      bus, channels::scene_objects, [this](const SceneObjects& m, const comm::Received& in) {
        if (!in.authentic()) return;  // with a key, only the emulator's own
        state_.on_scene_objects(m, in.header().utime, in.header().seq);
      });
  listener_ = std::make_unique<SystemListener>(
      bus, [this](const SrpMessage& m) { state_.on_message(m); },
      [this](const ProcessStatus& s) { state_.on_process_status(s); });
  clients_ = std::make_unique<Clients>();
  comm::ClientOptions status_options;
  status_options.attempt_timeout = std::chrono::milliseconds(150);
  status_options.max_attempts = 3;
  clients_->status =
      std::make_unique<MpClient>(bus, comm::unique_endpoint_name("ui/status"), "MP",
                                 channels::mp_command, channels::mp_reply, status_options);
  comm::ClientOptions history_options;
  history_options.attempt_timeout = std::chrono::milliseconds(200);
  history_options.max_attempts = 3;
  clients_->history = std::make_unique<comm::SrpHistoryClient>(
      bus, "ui/history", "SRP", channels::srp_history_command, channels::srp_history_reply,
      history_options);
}

BusFeed::~BusFeed() { stop_polling(); }

void BusFeed::start_polling() {
  if (!poller_.joinable()) poller_ = std::thread([this] { poll_loop(); });
}

void BusFeed::stop_polling() {
  {
    std::lock_guard lock(poll_mutex_);
    poll_stop_ = true;
    poll_cv_.notify_all();
  }
  if (poller_.joinable()) poller_.join();
}

void BusFeed::poll_loop() {
  auto next_history = SteadyClock::now();
  for (;;) {
    {
      std::unique_lock lock(poll_mutex_);
      if (poll_cv_.wait_for(lock, std::chrono::milliseconds(400), [&] { return poll_stop_; }))
        return;
    }
    poll_mp();
    if (!state_.history_loaded() && SteadyClock::now() >= next_history) {
      fetch_history();
      next_history = SteadyClock::now() + std::chrono::seconds(2);
    }
  }
}

void BusFeed::poll_mp() {
  try {
    state_.on_mp_status(send_operator_command(*clients_->status, OperatorCommand::status));
  } catch (const std::exception&) {
    state_.on_mp_silent(no_mp_text_);
  }
}

void BusFeed::fetch_history() {
  SrpHistoryRequest request;
  request.after = 0;
  request.max_count = 500;
  request.min_severity = Severity::debug;
  SrpHistoryReply reply;
  try {
    reply = clients_->history->call(request);
  } catch (const std::exception&) {
    return;  // no SRP (yet), or a reply that did not decode: try again later
  }
  std::vector<SrpMessage> history;
  history.reserve(reply.entries.size());
  for (SrpHistoryEntry& entry : reply.entries) history.push_back(std::move(entry.message));
  state_.merge_history(history, reply.last);
}

}  // namespace mrroc::ui
