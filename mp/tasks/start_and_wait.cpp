// Stock MP task "start_and_wait": independent robots. Sends START_TASK to every ECP at once and
// waits for each to terminate; fails, naming the robots, if any ECP reports an error.
#include <fmt/format.h>

#include "mrroc/mp/task.hpp"

namespace mrroc::mp {

class StartAndWait : public MpTask {
 public:
  explicit StartAndWait(TaskContext& context) : context_(context) {
    context.args.reject_unread("mp.args");
  }

  void main_task() override {
    for (Robot* r : context_.robots)
      context_.reporter.info(fmt::format("START_TASK -> ecp/{}", r->name()));
    parallel(context_.robots, [this](Robot& r) {
      r.start_task();
      context_.reporter.info(fmt::format("ecp/{}: TASK_TERMINATED", r.name()));
    });
  }

 private:
  TaskContext& context_;
};

MRROC_REGISTER_MP_TASK("start_and_wait", StartAndWait);

}  // namespace mrroc::mp
