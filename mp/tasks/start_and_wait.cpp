// Stock MP task "start_and_wait": independent robots. Sends START_TASK to every ECP at once and
// waits for each to answer TASK_TERMINATED (success) or ERROR (the task fails, naming the robot).
#include <fmt/format.h>

#include <thread>

#include "mrroc/mp/task.hpp"

namespace mrroc::mp {

class StartAndWait : public MpTask {
 public:
  explicit StartAndWait(TaskContext& context) : context_(context) {
    context.args.reject_unread("mp.args");
  }

  void main_task() override {
    std::vector<std::thread> threads;
    std::vector<ecp::EcpReply> replies(context_.robots.size());
    std::vector<std::string> failures(context_.robots.size());
    for (std::size_t i = 0; i < context_.robots.size(); ++i) {
      threads.emplace_back([&, i] {
        const RobotLink& link = context_.robots[i];
        try {
          ecp::MpCommand start;
          start.type = ecp::MpCommandType::start_task;
          context_.reporter.info(fmt::format("START_TASK -> ecp/{}", link.name));
          replies[i] = link.ecp->call(start);
        } catch (const std::exception& e) {
          failures[i] = e.what();
        }
      });
    }
    for (auto& t : threads) t.join();
    std::string failed;
    int code = 0;
    for (std::size_t i = 0; i < replies.size(); ++i) {
      const std::string& name = context_.robots[i].name;
      if (!failures[i].empty()) {
        failed += fmt::format("{}{}: {}", failed.empty() ? "" : "; ", name, failures[i]);
      } else if (replies[i].type == ecp::EcpReplyType::task_terminated) {
        context_.reporter.info(fmt::format("ecp/{}: TASK_TERMINATED", name));
      } else {
        code = replies[i].error_code;
        failed += fmt::format("{}{}: {}", failed.empty() ? "" : "; ", name, replies[i].error_text);
      }
    }
    if (!failed.empty()) throw EcpFailed(code, "task failed: " + failed);
  }

 private:
  TaskContext& context_;
};

MRROC_REGISTER_MP_TASK("start_and_wait", StartAndWait);

}  // namespace mrroc::mp
