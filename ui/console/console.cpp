#include "console/console.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <system_error>
#include <thread>
#include <vector>

#include "console/bus_feed.hpp"
#include "console/edp_jog_link.hpp"
#include "console/http_api.hpp"
#include "console/jog.hpp"
#include "console/state.hpp"
#include "console/teach_in.hpp"
#include "console/token.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "operator.hpp"

// Last: <httplib.h>, which it includes, includes <resolv.h>, which defines `_res`, a name Eigen's
// headers use.
#include "console/http_server.hpp"

namespace mrroc::ui {

namespace {

std::vector<ConsoleRobot> load_robots(const ProcessSetConfig& config) {
  std::vector<ConsoleRobot> robots;
  for (const RobotConfig& r : config.robots) {
    RobotModel model = load_robot_model(r.model_dir);
    const bool cartesian = edp::make_arm_kinematics(model)->cartesian();
    robots.push_back(ConsoleRobot{r.name, std::move(model), r.edp.servo_period_s, cartesian,
                                  std::min(r.edp.unsynchronised_velocity_fraction,
                                           r.edp.unsynchronised_acceleration_fraction),
                                  r.edp.unsynchronised_max_move});
  }
  return robots;
}

}  // namespace

struct Console::Impl : ConsoleActions {
  ProcessSetConfig config;
  ConsoleOptions options;
  comm::Bus bus;
  ConsoleState state;
  std::unique_ptr<BusFeed> feed;
  std::unique_ptr<Reporter> reporter;
  std::unique_ptr<MpClient> command_client;
  std::unique_ptr<Jogger> jogger;
  std::unique_ptr<TeachIn> teach_in;
  std::unique_ptr<HttpApi> api;
  ConsoleServer server;
  /// The token was generated here (no [ui] token_file); its file.
  bool token_generated = false;
  std::filesystem::path token_path;

  Impl(const ProcessSetConfig& c, ConsoleOptions o)
      : config(c), options(std::move(o)), bus(c.lcm_url), state(c.name, load_robots(c)) {
    if (options.token.empty()) {
      options.token = generate_token();
      token_generated = true;
      token_path = generated_token_file(config.launch.log_dir, options.port);
    }
    comm::enable_auth_from_file(bus, config.auth_key_file);
    const ReportFn report = [this](Severity severity, const std::string& text) {
      reporter->report(severity, 0, text);
    };
    std::map<std::string, std::unique_ptr<JogLink>> links;
    for (const ConsoleRobot& r : state.robots()) links[r.name] = make_edp_jog_link(bus, r.name);
    jogger = std::make_unique<Jogger>(state, options.jog, std::move(links), report);
    feed = std::make_unique<BusFeed>(bus, state, no_mp_text());
    comm::ClientOptions command_options;
    command_options.attempt_timeout = std::chrono::milliseconds(250);
    command_options.max_attempts = 8;
    command_client =
        std::make_unique<MpClient>(bus, comm::unique_endpoint_name("ui"), "MP",
                                   channels::mp_command, channels::mp_reply, command_options);
    bus.start();
    reporter = std::make_unique<Reporter>(bus, "ui");
    teach_in = std::make_unique<TeachIn>(state, config.ui.teach_dir, report);
    ApiSettings settings;
    settings.set_name = config.name;
    settings.config_file = config.file;
    settings.operator_start = config.mp_waits_for_operator;
    settings.teach_dir = teach_in->dir();
    settings.jog_max_step_rad = options.jog.max_step_rad;
    settings.jog_max_step_m = options.jog.max_step_m;
    settings.vendor_dir = default_vendor_dir();
    for (const RobotConfig& r : config.robots) settings.robot_base[r.name] = r.base;
    // The page works without them, but its 3D view stays empty: say why.
    if (std::error_code ec; !std::filesystem::is_regular_file(
            settings.vendor_dir / "three" / "build" / "three.module.js", ec))
      reporter->warning(fmt::format(
          "the 3D view's libraries are missing in '{}': the console's page shows no 3D view "
          "(install them with `npm ci --prefix ui/vendor` in the source tree and build mrroc-ui "
          "again)",
          settings.vendor_dir.string()));
    settings.token = options.token;
    settings.token_hint =
        token_generated
            ? fmt::format(
                  "mrroc-ui serve wrote the token to '{}' (and printed the page's URL with "
                  "it when its standard output was a terminal)",
                  token_path.string())
            : fmt::format("the token is the first line of [ui] token_file '{}'",
                          config.ui.token_file.string());
    // Browsers name the console by its bind address, a loopback name, or a configured name.
    if (options.bind != "0.0.0.0" && options.bind != "::") settings.hosts.push_back(options.bind);
    for (const std::string& h : config.ui.hosts) settings.hosts.push_back(h);
    api = std::make_unique<HttpApi>(state, settings, *this);
    api->install(server);
  }

  ~Impl() override {
    feed->stop_polling();
    bus.stop();
    feed.reset();  // unsubscribes
  }

  std::string no_mp_text() const {
    return fmt::format("no MP answers on '{}' (set '{}', {})", channels::mp_command, config.name,
                       config.file.string());
  }

  // --- ConsoleActions: what the API's POST requests do ------------------------------------------

  MpStatus command(OperatorCommand command) override {
    MpStatus s;
    try {
      s = send_operator_command(*command_client, command);
    } catch (const TimeoutError&) {
      throw ApiError(504, no_mp_text());
    }
    state.on_mp_status(s);
    std::string upper = to_string(command);
    for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    if (command != OperatorCommand::status)
      reporter->info(fmt::format("operator: {} {} (MP {}{})", upper,
                                 s.accepted ? "accepted" : "refused", s.state,
                                 s.text.empty() ? "" : ": " + s.text));
    return s;
  }

  EstopResult emergency_stop(bool engage, const std::string& robot,
                             const std::string& reason) override {
    EstopResult r;
    r.servo_step_at_send = state.estimated_servo_steps(robot);
    // Sent, then confirmed from every robot's robot_state_t within kEstopConfirmDeadline.
    std::vector<std::string> names;
    for (const RobotConfig& c : config.robots) names.push_back(c.name);
    r.confirmation = send_and_confirm_emergency_stop(bus, engage, names, robot, reason);
    r.text = describe_emergency_stop(engage, robot, reason) + ": " +
             describe_confirmation(engage, r.confirmation);
    if (engage || !r.confirmation.all())
      reporter->report(Severity::error, 10, r.text);
    else
      reporter->warning(r.text);
    return r;
  }

  JogResult jog(const JogRequest& request) override { return jogger->jog(request); }
  JogResult synchronise(const std::string& robot) override { return jogger->synchronise(robot); }

  TeachResult teach(const std::string& robot, const std::string& file) override {
    return teach_in->record(robot, file);
  }

  int run() {
    if (!server.bind_to_port(options.bind, options.port)) {
      const std::string text =
          fmt::format("cannot listen on {}:{} (in use, or not an address of this host)",
                      options.bind, options.port);
      reporter->report(Severity::fatal, 0, text);
      reporter->set_state(ProcessState::failed, text);
      throw Error(text);
    }
    // After binding: a console that cannot bind (the port is taken) leaves the file of the one
    // that did alone.
    std::optional<TokenFile> token_file;
    // The token itself is printed only to a terminal: standard output that goes to a pipe or a
    // file (the launcher's output, its log files, a service's journal) gets the file's path.
    const bool terminal = ::isatty(STDOUT_FILENO) == 1;
    if (token_generated) {
      try {
        token_file.emplace(token_path, options.token);
      } catch (const Error& e) {
        if (!terminal) {
          // Nobody could learn the token: a console nobody can use.
          const std::string text = fmt::format(
              "{}; the token is printed only on a terminal, and standard output is none: set [ui] "
              "token_file, or make the folder writable",
              e.what());
          reporter->report(Severity::fatal, 0, text);
          reporter->set_state(ProcessState::failed, text);
          throw Error(text);
        }
        reporter->warning(e.what());  // the URL with the token is still printed below
        std::fprintf(stderr, "mrroc-ui: %s\n", e.what());
      }
    }
    feed->start_polling();
    std::atomic<bool> listening_ended{false};
    std::thread listener_thread([this, &listening_ended] {
      server.listen_after_bind();
      listening_ended.store(true);
    });
    const std::string host =
        options.bind.find(':') != std::string::npos ? "[" + options.bind + "]" : options.bind;
    const std::string url = fmt::format("http://{}:{}/", host, options.port);
    reporter->set_state(ProcessState::ready);
    // The token never goes to the SRP, whose log more people may read.
    if (token_generated) {
      reporter->info(fmt::format(
          "web console at {} (API token required{})", url,
          token_file ? fmt::format("; it is in '{}'", token_path.string()) : std::string()));
      if (terminal)
        std::printf("mrroc-ui: web console of set '%s' at %s?token=%s\n", config.name.c_str(),
                    url.c_str(), options.token.c_str());
      else
        std::printf(
            "mrroc-ui: web console of set '%s' at %s (open it once as %s?token=TOKEN, TOKEN "
            "being the first line of the file below)\n",
            config.name.c_str(), url.c_str(), url.c_str());
      if (token_file)
        std::printf("mrroc-ui: API token in %s (removed when the console ends)\n",
                    token_path.c_str());
    } else {
      reporter->info(fmt::format("web console at {} (API token required: [ui] token_file)", url));
      std::printf("mrroc-ui: web console of set '%s' at %s (API token: [ui] token_file %s)\n",
                  config.name.c_str(), url.c_str(), config.ui.token_file.c_str());
    }
    std::fflush(stdout);
    while (!stop_requested() && !listening_ended.load())
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    reporter->set_state(ProcessState::stopping);
    server.stop();
    listener_thread.join();
    feed->stop_polling();
    reporter->set_state(ProcessState::finished);
    return 0;
  }
};

Console::Console(const ProcessSetConfig& config, ConsoleOptions options)
    : impl_(std::make_unique<Impl>(config, std::move(options))) {}
Console::~Console() = default;
int Console::run() { return impl_->run(); }

}  // namespace mrroc::ui
