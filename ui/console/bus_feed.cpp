#include "console/bus_feed.hpp"

#include <algorithm>
#include <chrono>
#include <exception>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc_lcm/srp_history_reply_t.hpp"
#include "mrroc_lcm/srp_history_request_t.hpp"
#include "operator.hpp"

namespace mrroc::ui {

namespace {

using HistoryClient =
    comm::Client<mrroc_lcm::srp_history_request_t, mrroc_lcm::srp_history_reply_t>;

}  // namespace

struct BusFeed::Clients {
  std::unique_ptr<MpClient> status;
  std::unique_ptr<HistoryClient> history;
};

BusFeed::BusFeed(comm::Bus& bus, ConsoleState& state, std::string no_mp_text)
    : bus_(bus), state_(state), no_mp_text_(std::move(no_mp_text)) {
  for (std::size_t i = 0; i < state_.robots().size(); ++i) {
    contexts_.push_back(std::make_unique<RobotContext>(RobotContext{&state_, i}));
    subscriptions_.push_back(bus_.subscribe<RobotContext*>(
        channels::robot_state(state_.robots()[i].name),
        +[](const lcm::ReceiveBuffer* buffer, const std::string&, RobotContext* ctx) {
          mrroc_lcm::robot_state_t s;
          if (!comm::detail::decode_received(buffer, s)) return;
          ctx->state->on_robot_state(ctx->index, s);
        },
        contexts_.back().get()));
  }
  subscriptions_.push_back(bus_.subscribe<ConsoleState*>(
      channels::launch_status,
      +[](const lcm::ReceiveBuffer* buffer, const std::string&, ConsoleState* s) {
        mrroc_lcm::launch_status_t m;
        if (!comm::detail::decode_received(buffer, m)) return;
        s->on_launch_status(m);
      },
      &state_));
  listener_ = std::make_unique<SystemListener>(
      bus_, [this](const SrpMessage& m) { state_.on_message(m); },
      [this](const ProcessStatus& s) { state_.on_process_status(s); });
  clients_ = std::make_unique<Clients>();
  comm::ClientOptions status_options;
  status_options.attempt_timeout = std::chrono::milliseconds(150);
  status_options.max_attempts = 3;
  clients_->status =
      std::make_unique<MpClient>(bus_, comm::unique_endpoint_name("ui/status"), "MP",
                                 channels::mp_command, channels::mp_reply, status_options);
  comm::ClientOptions history_options;
  history_options.attempt_timeout = std::chrono::milliseconds(200);
  history_options.max_attempts = 3;
  clients_->history = std::make_unique<HistoryClient>(
      bus_, comm::unique_endpoint_name("ui/history"), "SRP", channels::srp_history_command,
      channels::srp_history_reply, history_options);
}

BusFeed::~BusFeed() {
  stop_polling();
  for (comm::Subscription* s : subscriptions_) bus_.unsubscribe(s);
}

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
  mrroc_lcm::srp_history_request_t request{};
  request.after = 0;
  request.max_count = 500;
  request.min_severity = 0;
  mrroc_lcm::srp_history_reply_t reply;
  try {
    reply = clients_->history->call(request);
  } catch (const std::exception&) {
    return;  // no SRP (yet): try again later
  }
  std::vector<SrpMessage> history;
  for (int i = 0; i < reply.n; ++i) {
    const auto& m = reply.messages[static_cast<std::size_t>(i)];
    SrpMessage message;
    message.utime = m.utime;
    message.process = m.process;
    message.robot = m.robot;
    message.severity = static_cast<Severity>(std::clamp<int>(m.severity, 0, 4));
    message.code = m.code;
    message.text = m.text;
    history.push_back(std::move(message));
  }
  state_.merge_history(history, reply.last);
}

}  // namespace mrroc::ui
