#include "console.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <thread>
#include <vector>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc/ecp/generators/trajectory_file.hpp"
#include "mrroc/ecp/robot.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "mrroc_lcm/launch_status_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "mrroc_lcm/srp_history_reply_t.hpp"
#include "mrroc_lcm/srp_history_request_t.hpp"
#include "operator.hpp"

// Last: <resolv.h>, which it includes, defines `_res`, a name Eigen's headers use.
#include <httplib.h>

namespace mrroc::ui {

namespace {

using json = nlohmann::json;
using SteadyClock = std::chrono::steady_clock;
using HistoryClient =
    comm::Client<mrroc_lcm::srp_history_request_t, mrroc_lcm::srp_history_reply_t>;

constexpr std::size_t kMaxSamples = 1500;  // 30 s of robot_state_t at 50 Hz
constexpr std::size_t kMaxLog = 5000;      // SRP messages kept
constexpr double kStateFreshS = 1.0;       // a robot_state_t older than this is stale [s]
constexpr double kLaunchFreshS = 3.0;      // the launcher broadcasts every second

double seconds_since(SteadyClock::time_point t) {
  return std::chrono::duration<double>(SteadyClock::now() - t).count();
}

/// An HTTP error with its status code; the message goes into {"error": ...}.
struct ApiError : Error {
  int status;
  ApiError(int s, const std::string& text) : Error(text), status(s) {}
};

std::string content_type(const std::string& name) {
  auto ends = [&](const char* suffix) {
    const std::string s(suffix);
    return name.size() >= s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0;
  };
  if (ends(".html")) return "text/html; charset=utf-8";
  if (ends(".css")) return "text/css; charset=utf-8";
  if (ends(".js")) return "application/javascript; charset=utf-8";
  if (ends(".svg")) return "image/svg+xml";
  if (ends(".png")) return "image/png";
  return "application/octet-stream";
}

json parse_body(const httplib::Request& req) {
  if (req.body.empty()) return json::object();
  json body = json::parse(req.body, nullptr, false);
  if (body.is_discarded() || !body.is_object())
    throw ApiError(400, "request body is not a JSON object");
  return body;
}

struct Sample {
  std::int64_t step = 0;
  std::int64_t utime = 0;
  std::vector<double> q;
  std::vector<double> dq;
  double lateness_mean_us = 0.0;
  double lateness_max_us = 0.0;
};

struct RobotView {
  std::string name;
  RobotModel model;
  double servo_period_s = kDefaultServoPeriodS;
  std::optional<mrroc_lcm::robot_state_t> state;
  SteadyClock::time_point received{};
  std::deque<Sample> samples;
  std::unique_ptr<ecp::Robot> jog;  // the console's own EDP client for jogging
  std::mutex jog_mutex;
};

struct LogEntry {
  std::int64_t number = 0;
  SrpMessage message;
};

struct SeenProcess {
  ProcessStatus status;
  SteadyClock::time_point received{};
};

struct RobotSubscription {
  struct Shared* shared;
  std::size_t index;
};

/// State written by the bus thread and read by the HTTP threads (under `mutex`).
struct Shared {
  std::mutex mutex;
  std::vector<std::unique_ptr<RobotView>> robots;
  std::optional<mrroc_lcm::launch_status_t> launch;
  SteadyClock::time_point launch_received{};
  std::map<std::string, SeenProcess> processes;
  std::deque<LogEntry> log;
  std::int64_t log_next = 1;
  int log_epoch = 1;  // changes when entries were renumbered (history merged in)
  bool history_loaded = false;
  std::int64_t srp_last = 0;
  std::optional<MpStatus> mp;
  std::string mp_error;  // why the last STATUS got no answer
  SteadyClock::time_point mp_polled{};

  void add_message(const SrpMessage& m) {
    log.push_back(LogEntry{log_next++, m});
    while (log.size() > kMaxLog) log.pop_front();
  }
};

json robot_state_json(const mrroc_lcm::robot_state_t& s, double age_s) {
  return json{{"synchronised", s.synchronised != 0},
              {"moving", s.moving != 0},
              {"estop", s.estop != 0},
              {"fault", s.fault != 0},
              {"error", s.error},
              {"servo_step", s.servo_step},
              {"servo_period_s", s.servo_period_s},
              {"q", s.q},
              {"dq", s.dq},
              {"q_desired", s.q_desired},
              {"lateness_mean_us", s.lateness_mean_us},
              {"lateness_max_us", s.lateness_max_us},
              {"overruns", s.overruns},
              {"utime", s.header.utime},
              {"age_s", age_s}};
}

json mp_json(const MpStatus& s) {
  return json{{"accepted", s.accepted}, {"state", s.state}, {"task", s.task},
              {"runs", s.runs},         {"text", s.text},   {"started_utime", s.started_utime}};
}

json message_json(const LogEntry& e) {
  const SrpMessage& m = e.message;
  return json{{"n", e.number},
              {"utime", m.utime},
              {"time", format_utime(m.utime)},
              {"process", m.process},
              {"robot", m.robot},
              {"severity", static_cast<int>(m.severity)},
              {"severity_name", to_string(m.severity)},
              {"code", m.code},
              {"text", m.text}};
}

bool same_message(const SrpMessage& a, const SrpMessage& b) {
  return a.utime == b.utime && a.process == b.process && a.text == b.text && a.code == b.code;
}

}  // namespace

std::string read_token_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw Error(fmt::format("cannot read the UI token file '{}'", file.string()));
  std::string line;
  std::getline(in, line);
  const auto first = line.find_first_not_of(" \t\r\n");
  const auto last = line.find_last_not_of(" \t\r\n");
  const std::string token = first == std::string::npos ? "" : line.substr(first, last - first + 1);
  if (token.size() < 16)
    throw Error(fmt::format(
        "UI token file '{}': the token on its first line has {} characters, at least 16 needed",
        file.string(), token.size()));
  return token;
}

struct Console::Impl {
  ProcessSetConfig config;
  ConsoleOptions options;
  comm::Bus bus;
  Shared shared;
  std::vector<std::unique_ptr<RobotSubscription>> contexts;
  std::vector<mrroc::comm::Subscription*> subscriptions;
  std::unique_ptr<SystemListener> listener;
  std::unique_ptr<Reporter> reporter;
  std::unique_ptr<MpClient> status_client;
  std::unique_ptr<MpClient> command_client;
  std::unique_ptr<HistoryClient> history_client;
  httplib::Server server;
  std::thread poller;
  std::mutex poll_mutex;
  std::condition_variable poll_cv;
  bool poll_stop = false;

  Impl(const ProcessSetConfig& c, ConsoleOptions o)
      : config(c), options(std::move(o)), bus(c.lcm_url) {
    comm::enable_auth_from_file(bus, config.auth_key_file);
    for (const RobotConfig& r : config.robots) {
      auto view = std::make_unique<RobotView>();
      view->name = r.name;
      view->model = load_robot_model(r.model_dir);
      view->servo_period_s = r.edp.servo_period_s;
      comm::ClientOptions jog_options;
      jog_options.attempt_timeout = std::chrono::milliseconds(250);
      jog_options.max_attempts = 8;
      view->jog = std::make_unique<ecp::Robot>(bus, comm::unique_endpoint_name("ui/jog/" + r.name),
                                               r.name, view->model, jog_options);
      shared.robots.push_back(std::move(view));
    }
    for (std::size_t i = 0; i < shared.robots.size(); ++i) {
      contexts.push_back(std::make_unique<RobotSubscription>(RobotSubscription{&shared, i}));
      subscriptions.push_back(
          bus.subscribe<RobotSubscription*>(channels::robot_state(shared.robots[i]->name),
                                            &Impl::on_robot_state, contexts.back().get()));
    }
    subscriptions.push_back(
        bus.subscribe<Shared*>(channels::launch_status, &Impl::on_launch_status, &shared));
    listener = std::make_unique<SystemListener>(
        bus,
        [this](const SrpMessage& m) {
          std::lock_guard lock(shared.mutex);
          shared.add_message(m);
        },
        [this](const ProcessStatus& s) {
          std::lock_guard lock(shared.mutex);
          shared.processes[s.process] = SeenProcess{s, SteadyClock::now()};
        });
    comm::ClientOptions status_options;
    status_options.attempt_timeout = std::chrono::milliseconds(150);
    status_options.max_attempts = 3;
    status_client =
        std::make_unique<MpClient>(bus, comm::unique_endpoint_name("ui/status"), "MP",
                                   channels::mp_command, channels::mp_reply, status_options);
    comm::ClientOptions command_options;
    command_options.attempt_timeout = std::chrono::milliseconds(250);
    command_options.max_attempts = 8;
    command_client =
        std::make_unique<MpClient>(bus, comm::unique_endpoint_name("ui"), "MP",
                                   channels::mp_command, channels::mp_reply, command_options);
    comm::ClientOptions history_options;
    history_options.attempt_timeout = std::chrono::milliseconds(200);
    history_options.max_attempts = 3;
    history_client = std::make_unique<HistoryClient>(bus, comm::unique_endpoint_name("ui/history"),
                                                     "SRP", channels::srp_history_command,
                                                     channels::srp_history_reply, history_options);
    bus.start();
    reporter = std::make_unique<Reporter>(bus, "ui");
    install_routes();
  }

  ~Impl() {
    {
      std::lock_guard lock(poll_mutex);
      poll_stop = true;
      poll_cv.notify_all();
    }
    if (poller.joinable()) poller.join();
    bus.stop();
    for (mrroc::comm::Subscription* s : subscriptions) bus.unsubscribe(s);
  }

  // --- bus thread -----------------------------------------------------------------------------

  static void on_robot_state(const lcm::ReceiveBuffer* buffer, const std::string&,
                             RobotSubscription* ctx) {
    mrroc_lcm::robot_state_t s;
    if (!comm::detail::decode_received(buffer, s)) return;
    Shared& shared = *ctx->shared;
    std::lock_guard lock(shared.mutex);
    RobotView& view = *shared.robots[ctx->index];
    if (s.n_joints < 0 || static_cast<std::size_t>(s.n_joints) != view.model.axes()) return;
    view.state = s;
    view.received = SteadyClock::now();
    if (!view.samples.empty() && view.samples.back().step >= s.servo_step)
      view.samples.clear();  // the EDP started again
    view.samples.push_back(
        Sample{s.servo_step, s.header.utime, s.q, s.dq, s.lateness_mean_us, s.lateness_max_us});
    while (view.samples.size() > kMaxSamples) view.samples.pop_front();
  }

  static void on_launch_status(const lcm::ReceiveBuffer* buffer, const std::string&,
                               Shared* shared) {
    mrroc_lcm::launch_status_t s;
    if (!comm::detail::decode_received(buffer, s)) return;
    std::lock_guard lock(shared->mutex);
    shared->launch = std::move(s);
    shared->launch_received = SteadyClock::now();
  }

  // --- poller: the MP's state, the SRP's history ----------------------------------------------

  void poll_loop() {
    auto next_history = SteadyClock::now();
    for (;;) {
      {
        std::unique_lock lock(poll_mutex);
        if (poll_cv.wait_for(lock, std::chrono::milliseconds(400), [&] { return poll_stop; }))
          return;
      }
      poll_mp();
      bool loaded = false;
      {
        std::lock_guard lock(shared.mutex);
        loaded = shared.history_loaded;
      }
      if (!loaded && SteadyClock::now() >= next_history) {
        fetch_history();
        next_history = SteadyClock::now() + std::chrono::seconds(2);
      }
    }
  }

  void poll_mp() {
    try {
      const MpStatus s = send_operator_command(*status_client, OperatorCommand::status);
      std::lock_guard lock(shared.mutex);
      shared.mp = s;
      shared.mp_error.clear();
      shared.mp_polled = SteadyClock::now();
    } catch (const std::exception& e) {
      std::lock_guard lock(shared.mutex);
      shared.mp.reset();
      shared.mp_error = no_mp_text();
    }
  }

  std::string no_mp_text() const {
    return fmt::format("no MP answers on '{}' (set '{}', {})", channels::mp_command, config.name,
                       config.file.string());
  }

  void fetch_history() {
    mrroc_lcm::srp_history_request_t request{};
    request.after = 0;
    request.max_count = 500;
    request.min_severity = 0;
    mrroc_lcm::srp_history_reply_t reply;
    try {
      reply = history_client->call(request);
    } catch (const std::exception&) {
      return;  // no SRP (yet): try again later
    }
    std::deque<LogEntry> history;
    for (int i = 0; i < reply.n; ++i) {
      const auto& m = reply.messages[static_cast<std::size_t>(i)];
      SrpMessage message;
      message.utime = m.utime;
      message.process = m.process;
      message.robot = m.robot;
      message.severity = static_cast<Severity>(std::clamp<int>(m.severity, 0, 4));
      message.code = m.code;
      message.text = m.text;
      history.push_back(LogEntry{0, std::move(message)});
    }
    std::lock_guard lock(shared.mutex);
    shared.history_loaded = true;
    shared.srp_last = reply.last;
    // Live messages received meanwhile may also be in the history: keep one copy of each.
    std::deque<LogEntry> merged;
    for (LogEntry& h : history) merged.push_back(std::move(h));
    for (LogEntry& live : shared.log) {
      const bool duplicate = std::any_of(merged.begin(), merged.end(), [&](const LogEntry& h) {
        return same_message(h.message, live.message);
      });
      if (!duplicate) merged.push_back(std::move(live));
    }
    std::int64_t n = 1;
    for (LogEntry& e : merged) e.number = n++;
    shared.log = std::move(merged);
    shared.log_next = n;
    ++shared.log_epoch;
  }

  // --- HTTP --------------------------------------------------------------------------------------

  static void reply_json(httplib::Response& res, const json& body, int status = 200) {
    res.status = status;
    res.set_content(body.dump(), "application/json");
  }

  void install_routes() {
    // A browser keeps several connections open; give them and API clients enough threads.
    server.new_task_queue = [] { return new httplib::ThreadPool(16); };
    server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      if (req.path.rfind("/api/", 0) != 0) return httplib::Server::HandlerResponse::Unhandled;
      if (!options.token.empty() && !token_ok(req)) {
        reply_json(res,
                   json{{"error",
                         "missing or wrong token: send 'Authorization: Bearer "
                         "TOKEN' (the token of [ui] token_file)"}},
                   401);
        return httplib::Server::HandlerResponse::Handled;
      }
      // A form or image of another web site cannot set this header without a CORS preflight,
      // which the console never allows: no cross-site requests.
      if (req.method == "POST" && req.get_header_value("X-Mrroc-Request") != "1") {
        reply_json(res, json{{"error", "POST requests need the header 'X-Mrroc-Request: 1'"}}, 403);
        return httplib::Server::HandlerResponse::Handled;
      }
      return httplib::Server::HandlerResponse::Unhandled;
    });
    server.set_exception_handler(
        [](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
          try {
            std::rethrow_exception(ep);
          } catch (const ApiError& e) {
            reply_json(res, json{{"error", e.what()}}, e.status);
          } catch (const TimeoutError& e) {
            reply_json(res, json{{"error", e.what()}}, 504);
          } catch (const json::exception& e) {
            // A field of the request body has the wrong type (e.g. "robot": 5).
            reply_json(res, json{{"error", fmt::format("request body: {}", e.what())}}, 400);
          } catch (const std::exception& e) {
            reply_json(res, json{{"error", e.what()}}, 500);
          } catch (...) {
            reply_json(res, json{{"error", "unknown exception"}}, 500);
          }
        });
    server.Get("/", [](const httplib::Request&, httplib::Response& res) {
      serve_asset("index.html", res);
    });
    server.Get(R"(/([A-Za-z0-9_.-]+))", [](const httplib::Request& req, httplib::Response& res) {
      serve_asset(req.matches[1], res);
    });
    server.Get("/api/state", [this](const httplib::Request&, httplib::Response& res) {
      reply_json(res, state_json());
    });
    server.Get(R"(/api/robots/([a-z][a-z0-9_]*)/samples)",
               [this](const httplib::Request& req, httplib::Response& res) {
                 reply_json(res, samples_json(req.matches[1], integer_param(req, "after", 0)));
               });
    server.Get("/api/srp", [this](const httplib::Request& req, httplib::Response& res) {
      reply_json(res,
                 srp_json(integer_param(req, "after", 0), integer_param(req, "min_severity", 0),
                          integer_param(req, "max", 1000)));
    });
    server.Post(R"(/api/command/([a-z]+))",
                [this](const httplib::Request& req, httplib::Response& res) {
                  command(req.matches[1], res);
                });
    server.Post("/api/estop", [this](const httplib::Request& req, httplib::Response& res) {
      // Stopping is always safe: a request whose body cannot be understood (not JSON, a field
      // of the wrong type, an unknown robot) stops every robot instead of none.
      json body;
      std::string doubt;
      try {
        body = parse_body(req);
        if (body.contains("robot") && !body["robot"].is_string())
          throw ApiError(400, "'robot' is not a string");
        if (body.contains("reason") && !body["reason"].is_string())
          throw ApiError(400, "'reason' is not a string");
        if (const std::string robot = body.value("robot", std::string()); !robot.empty()) {
          std::lock_guard lock(shared.mutex);
          (void)robot_view(robot);
        }
      } catch (const ApiError& e) {
        doubt = e.what();
        body = json{{"reason", fmt::format("operator console (request not understood: {}; every "
                                           "robot is stopped)",
                                           doubt)}};
      }
      emergency_stop(true, body, res);
      if (!doubt.empty()) {
        json out = json::parse(res.body);
        out["error"] = fmt::format("request not understood ({}): every robot was stopped", doubt);
        reply_json(res, out, 400);
      }
    });
    server.Post("/api/release", [this](const httplib::Request& req, httplib::Response& res) {
      emergency_stop(false, parse_body(req), res);
    });
    server.Post("/api/jog", [this](const httplib::Request& req, httplib::Response& res) {
      reply_json(res, jog(parse_body(req)));
    });
    server.Post("/api/teach", [this](const httplib::Request& req, httplib::Response& res) {
      reply_json(res, teach(parse_body(req)));
    });
  }

  bool token_ok(const httplib::Request& req) const {
    std::string given = req.get_header_value("Authorization");
    if (given.rfind("Bearer ", 0) == 0) given = given.substr(7);
    if (given.empty() && req.has_param("token")) given = req.get_param_value("token");
    // Compare in constant time (the length is not secret).
    if (given.size() != options.token.size()) return false;
    unsigned char diff = 0;
    for (std::size_t i = 0; i < given.size(); ++i)
      diff = static_cast<unsigned char>(diff | (given[i] ^ options.token[i]));
    return diff == 0;
  }

  static void serve_asset(const std::string& name, httplib::Response& res) {
    const auto& assets = web_assets();
    const auto it = assets.find(name);
    if (it == assets.end()) {
      res.status = 404;
      res.set_content(fmt::format("no file '{}' in the console", name), "text/plain");
      return;
    }
    res.set_header("Cache-Control", "no-cache");
    res.set_content(std::string(it->second), content_type(name).c_str());
  }

  static std::int64_t integer_param(const httplib::Request& req, const char* name,
                                    std::int64_t fallback) {
    if (!req.has_param(name)) return fallback;
    const std::string text = req.get_param_value(name);
    try {
      std::size_t used = 0;
      const long long v = std::stoll(text, &used);
      if (used == text.size()) return v;
    } catch (const std::exception&) {
    }
    throw ApiError(400,
                   fmt::format("query parameter '{}' is '{}', expected an integer", name, text));
  }

  RobotView& robot_view(const std::string& name) {
    for (auto& r : shared.robots)
      if (r->name == name) return *r;
    std::string names;
    for (auto& r : shared.robots) names += (names.empty() ? "" : ", ") + r->name;
    throw ApiError(404,
                   fmt::format("no robot '{}' in set '{}' (robots: {})", name, config.name, names));
  }

  json state_json() {
    std::lock_guard lock(shared.mutex);
    json out;
    out["set"] = config.name;
    out["config"] = config.file.string();
    out["utime"] = now_utime();
    out["operator_start"] = config.mp_waits_for_operator;
    json mp = shared.mp ? mp_json(*shared.mp) : json{{"state", "NO MP"}};
    mp["available"] = shared.mp.has_value();
    mp["error"] = shared.mp_error;
    out["mp"] = mp;
    const bool launch_fresh =
        shared.launch && seconds_since(shared.launch_received) < kLaunchFreshS;
    if (launch_fresh) {
      const auto& l = *shared.launch;
      json table = json::array();
      for (const auto& p : l.processes)
        table.push_back(json{{"name", p.name},
                             {"group", p.group},
                             {"host", p.host},
                             {"state", p.state},
                             {"pid", p.pid},
                             {"cpu_percent", p.cpu_percent},
                             {"rss_kb", p.rss_kb},
                             {"restarts", p.restarts},
                             {"uptime_s", p.uptime_s},
                             {"last_exit_code", p.last_exit_code},
                             {"required", p.required != 0},
                             {"restart", p.restart}});
      out["launch"] = json{{"set_name", l.set_name},
                           {"state", l.state},
                           {"launcher_pid", l.launcher_pid},
                           {"uptime_s", l.uptime_s},
                           {"processes", table}};
    } else {
      out["launch"] = nullptr;
    }
    json processes = json::array();
    for (const auto& [name, seen] : shared.processes)
      processes.push_back(json{{"name", name},
                               {"robot", seen.status.robot},
                               {"state", to_string(seen.status.state)},
                               {"pid", seen.status.pid},
                               {"uptime_s", static_cast<double>(seen.status.uptime_us) * 1e-6},
                               {"detail", seen.status.detail},
                               {"silent_s", seconds_since(seen.received)}});
    out["processes"] = processes;
    json robots = json::array();
    for (const auto& r : shared.robots) {
      json j{{"name", r->name},
             {"joint_names", r->model.joint_names},
             {"lower_limits", r->model.lower_limits},
             {"upper_limits", r->model.upper_limits},
             {"max_velocity", r->model.max_velocity},
             {"max_acceleration", r->model.max_acceleration},
             {"servo_period_s", r->servo_period_s}};
      j["state"] = r->state ? robot_state_json(*r->state, seconds_since(r->received)) : json();
      robots.push_back(std::move(j));
    }
    out["robots"] = robots;
    out["srp"] = json{{"last", shared.log.empty() ? 0 : shared.log.back().number},
                      {"epoch", shared.log_epoch},
                      {"history_loaded", shared.history_loaded}};
    out["teach_dir"] = teach_dir().string();
    out["jog_max_step_rad"] = options.jog_max_step_rad;
    return out;
  }

  json samples_json(const std::string& robot, std::int64_t after) {
    std::lock_guard lock(shared.mutex);
    RobotView& view = robot_view(robot);
    json samples = json::array();
    for (const Sample& s : view.samples) {
      if (s.step <= after) continue;
      samples.push_back(json{{"step", s.step},
                             {"utime", s.utime},
                             {"q", s.q},
                             {"dq", s.dq},
                             {"lateness_mean_us", s.lateness_mean_us},
                             {"lateness_max_us", s.lateness_max_us}});
    }
    return json{{"robot", robot}, {"servo_period_s", view.servo_period_s}, {"samples", samples}};
  }

  json srp_json(std::int64_t after, std::int64_t min_severity, std::int64_t max) {
    if (min_severity < 0 || min_severity > 4)
      throw ApiError(400, fmt::format("min_severity {} is not a severity 0 (DEBUG) .. 4 (FATAL)",
                                      min_severity));
    if (max < 1 || max > 5000)
      throw ApiError(400, fmt::format("max {} is out of range 1..5000", max));
    std::lock_guard lock(shared.mutex);
    json messages = json::array();
    for (const LogEntry& e : shared.log) {
      if (e.number <= after || static_cast<int>(e.message.severity) < min_severity) continue;
      messages.push_back(message_json(e));
    }
    // The newest `max` of them.
    if (messages.size() > static_cast<std::size_t>(max))
      messages.erase(messages.begin(),
                     messages.begin() + static_cast<std::ptrdiff_t>(messages.size() -
                                                                    static_cast<std::size_t>(max)));
    return json{{"last", shared.log.empty() ? 0 : shared.log.back().number},
                {"epoch", shared.log_epoch},
                {"history_loaded", shared.history_loaded},
                {"srp_last", shared.srp_last},
                {"messages", messages}};
  }

  void command(const std::string& word, httplib::Response& res) {
    const auto command = operator_command_from_string(word);
    if (!command)
      throw ApiError(404, fmt::format("unknown command '{}' (start, pause, resume, stop, "
                                      "terminate, status)",
                                      word));
    MpStatus s;
    try {
      s = send_operator_command(*command_client, *command);
    } catch (const TimeoutError&) {
      throw ApiError(504, no_mp_text());
    }
    {
      std::lock_guard lock(shared.mutex);
      shared.mp = s;
      shared.mp_error.clear();
    }
    std::string upper = word;
    for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    if (*command != OperatorCommand::status)
      reporter->info(fmt::format("operator: {} {} (MP {}{})", upper,
                                 s.accepted ? "accepted" : "refused", s.state,
                                 s.text.empty() ? "" : ": " + s.text));
    json body = mp_json(s);
    body["command"] = word;
    if (!s.accepted) body["error"] = fmt::format("the MP refused {}: {}", upper, s.text);
    reply_json(res, body, s.accepted ? 200 : 409);
  }

  void emergency_stop(bool engage, const json& body, httplib::Response& res) {
    const std::string robot = body.value("robot", std::string());
    if (!robot.empty()) {
      std::lock_guard lock(shared.mutex);
      (void)robot_view(robot);
    }
    // The servo step each EDP is in now, estimated from its last robot_state_t.
    json steps = json::object();
    {
      std::lock_guard lock(shared.mutex);
      for (const auto& r : shared.robots) {
        if (!r->state || (!robot.empty() && r->name != robot)) continue;
        const double period =
            r->state->servo_period_s > 0 ? r->state->servo_period_s : r->servo_period_s;
        steps[r->name] =
            r->state->servo_step +
            static_cast<std::int64_t>(std::llround(seconds_since(r->received) / period));
      }
    }
    const std::string reason = body.value("reason", std::string("operator console"));
    // Sent, then confirmed from every robot's robot_state_t within kEstopConfirmDeadline.
    std::vector<std::string> names;
    for (const RobotConfig& r : config.robots) names.push_back(r.name);
    const EstopConfirmation c = send_and_confirm_emergency_stop(bus, engage, names, robot, reason);
    const std::string what =
        describe_emergency_stop(engage, robot, reason) + ": " + describe_confirmation(engage, c);
    if (engage || !c.all())
      reporter->report(Severity::error, 10, what);
    else
      reporter->warning(what);
    json latency = json::object();
    for (const auto& [name, ms] : c.latency_ms) latency[name] = ms;
    reply_json(res, json{{"ok", true},
                         {"text", what},
                         {"servo_step_at_send", steps},
                         {"confirmed", c.confirmed},
                         {"unconfirmed", c.unconfirmed},
                         {"confirm_ms", latency},
                         {"deadline_ms", kEstopConfirmDeadline.count()},
                         {"latched_by", c.latched_by}});
  }

  json jog(const json& body) {
    const std::string robot = body.value("robot", std::string());
    if (!body.contains("axis") || !body["axis"].is_number_integer())
      throw ApiError(400, "jog needs an integer 'axis'");
    if (!body.contains("step_rad") || !body["step_rad"].is_number())
      throw ApiError(400, "jog needs a number 'step_rad' [rad]");
    const std::int64_t axis = body["axis"].get<std::int64_t>();
    const double step = body["step_rad"].get<double>();
    if (body.contains("direction") && !body["direction"].is_number_integer())
      throw ApiError(400, "jog 'direction' must be +1 or -1");
    const int direction = body.value("direction", 1);
    if (direction != 1 && direction != -1)
      throw ApiError(400, fmt::format("jog direction {} is neither +1 nor -1", direction));
    RobotView* view = nullptr;
    std::vector<double> q;
    {
      std::lock_guard lock(shared.mutex);
      view = &robot_view(robot);
      const std::size_t axes = view->model.axes();
      if (axis < 0 || static_cast<std::size_t>(axis) >= axes)
        throw ApiError(400, fmt::format("axis {} is out of range: robot {} has axes 0..{}", axis,
                                        robot, axes - 1));
      if (!std::isfinite(step) || step <= 0.0 || step > options.jog_max_step_rad)
        throw ApiError(400, fmt::format("jog step {} rad is outside (0, {}] rad", step,
                                        options.jog_max_step_rad));
      if (shared.mp && (shared.mp->state == "RUNNING" || shared.mp->state == "PAUSED" ||
                        shared.mp->state == "STOPPING"))
        throw ApiError(409, fmt::format("jogging refused: the MP task is {}; stop it first",
                                        shared.mp->state));
      if (!view->state || seconds_since(view->received) > kStateFreshS)
        throw ApiError(409, fmt::format("jogging refused: no robot_state_t from EDP {} in the "
                                        "last {} s",
                                        robot, kStateFreshS));
      const auto& s = *view->state;
      if (s.estop)
        throw ApiError(409, fmt::format("jogging refused: the emergency stop of {} is engaged; "
                                        "release it first",
                                        robot));
      if (s.fault)
        throw ApiError(409,
                       fmt::format("jogging refused: {} has a hardware fault: {}", robot, s.error));
      if (!s.synchronised)
        throw ApiError(409, fmt::format("jogging refused: {} is not synchronised (run a task "
                                        "first: its ECP synchronises the robot)",
                                        robot));
      if (s.moving) throw ApiError(409, fmt::format("jogging refused: {} is moving", robot));
      q = s.q;
    }
    std::unique_lock jog_lock(view->jog_mutex, std::try_to_lock);
    if (!jog_lock.owns_lock())
      throw ApiError(409, fmt::format("jogging refused: a jog of {} is in progress", robot));
    const auto a = static_cast<std::size_t>(axis);
    // One macro-step from rest to rest; the EDP accelerates uniformly over its first half and
    // decelerates over its second (docs/edp.md, "Acceleration"), so the velocity peaks at 2 d / T
    // and the acceleration is 4 d / T^2: T keeps both within jog_velocity_fraction of the axis'
    // limits (and lasts at least 0.1 s).
    const double period = view->servo_period_s;
    std::vector<double> delta(view->model.axes(), 0.0);
    delta[a] = step;
    const int steps =
        ecp::rest_to_rest_steps(view->model, delta, options.jog_velocity_fraction, period, 0.1);
    ecp::Robot& edp = *view->jog;
    edp::Instruction& c = edp.image().command;
    c = edp::Instruction{};
    c.type = edp::InstructionType::set;
    c.set = edp::item::arm;
    c.set_arm_type = edp::ArmRepresentation::joint;
    c.motion_type = edp::MotionType::relative;
    c.motion_steps = steps;
    c.value_in_step_no = steps + 1;
    c.arm.assign(view->model.axes(), 0.0);
    c.arm[a] = direction * step;
    const std::string joint = view->model.joint_names[a];
    SteadyClock::time_point jog_done{};
    try {
      // The console drives the EDP only after an explicit take-over, which the EDP accepts only
      // while the robot is at rest (the MP was checked to be idle above).
      edp.take_over_next();
      edp.execute();
      jog_done = SteadyClock::now();
    } catch (const ecp::EdpRefused& e) {
      reporter->warning(fmt::format("operator jog of {} axis {} ({}) by {:+.4f} rad refused: {}",
                                    robot, axis, joint, direction * step, e.what()));
      throw ApiError(409, e.what());
    } catch (const TimeoutError& e) {
      throw ApiError(504, e.what());
    }
    // Answer once the EDP's broadcast shows the robot at rest (the next jog is then allowed).
    for (int i = 0; i < 10; ++i) {
      {
        std::lock_guard lock(shared.mutex);
        if (view->state && !view->state->moving && view->received > jog_done) break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    const auto& after = edp.image().joints;
    const std::string text = fmt::format(
        "{} axis {} ({}) moved {:+.4f} rad in {} servo steps ({:.3f} s): {:.4f} rad", robot, axis,
        joint, direction * step, steps, steps * period, a < after.size() ? after[a] : std::nan(""));
    reporter->info("operator jog: " + text);
    return json{
        {"ok", true}, {"text", text}, {"q", after}, {"q_before", q}, {"motion_steps", steps}};
  }

  std::filesystem::path teach_dir() const {
    return config.ui.teach_dir.empty() ? std::filesystem::current_path() : config.ui.teach_dir;
  }

  json teach(const json& body) {
    const std::string robot = body.value("robot", std::string());
    const std::string file = body.value("file", robot + ".traj");
    static const std::regex good_name("[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}");
    if (!std::regex_match(file, good_name))
      throw ApiError(400, fmt::format("trajectory file name '{}' is not a plain file name "
                                      "(letters, digits, '_', '.', '-'; at most 100)",
                                      file));
    std::vector<double> q;
    const RobotModel* model = nullptr;
    {
      std::lock_guard lock(shared.mutex);
      RobotView& view = robot_view(robot);
      if (!view.state || seconds_since(view.received) > kStateFreshS)
        throw ApiError(
            409, fmt::format("no robot_state_t from EDP {} in the last {} s", robot, kStateFreshS));
      if (!view.state->synchronised)
        throw ApiError(409, fmt::format("{} is not synchronised: its joint positions are not "
                                        "known yet",
                                        robot));
      q = view.state->q;
      model = &view.model;
    }
    const std::filesystem::path dir = teach_dir();
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    const std::filesystem::path path = dir / file;
    ecp::TrajectoryFile trajectory;
    if (std::filesystem::exists(path)) {
      trajectory = ecp::TrajectoryFile::load(path);
      if (trajectory.representation != edp::ArmRepresentation::joint ||
          trajectory.axes != model->axes() ||
          (!trajectory.robot.empty() && trajectory.robot != model->name))
        throw ApiError(409,
                       fmt::format("'{}' holds a {} trajectory of {} axes for robot '{}', "
                                   "not JOINT poses of {} ({} axes)",
                                   path.string(), edp::to_string(trajectory.representation),
                                   trajectory.axes, trajectory.robot, model->name, model->axes()));
    } else {
      trajectory.representation = edp::ArmRepresentation::joint;
      trajectory.axes = model->axes();
      trajectory.robot = model->name;
    }
    ecp::TrajectoryPoint point;
    point.values = q;
    trajectory.points.push_back(point);
    trajectory.save(path);
    const std::string text =
        fmt::format("pose {} of {} recorded in {}", trajectory.points.size(), robot, path.string());
    reporter->info("teach-in: " + text);
    return json{{"ok", true},
                {"file", path.string()},
                {"points", trajectory.points.size()},
                {"pose", q},
                {"text", text}};
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
    poller = std::thread([this] { poll_loop(); });
    std::atomic<bool> listening_ended{false};
    std::thread listener_thread([this, &listening_ended] {
      server.listen_after_bind();
      listening_ended.store(true);
    });
    const std::string url = fmt::format("http://{}:{}/", options.bind, options.port);
    reporter->set_state(ProcessState::ready);
    reporter->info(fmt::format("web console at {}{}", url,
                               options.token.empty() ? "" : " (API token required)"));
    std::printf("mrroc-ui: web console of set '%s' at %s\n", config.name.c_str(), url.c_str());
    std::fflush(stdout);
    while (!stop_requested() && !listening_ended.load())
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    reporter->set_state(ProcessState::stopping);
    server.stop();
    listener_thread.join();
    {
      std::lock_guard lock(poll_mutex);
      poll_stop = true;
      poll_cv.notify_all();
    }
    if (poller.joinable()) poller.join();
    reporter->set_state(ProcessState::finished);
    return 0;
  }
};

Console::Console(const ProcessSetConfig& config, ConsoleOptions options)
    : impl_(std::make_unique<Impl>(config, std::move(options))) {}
Console::~Console() = default;
int Console::run() { return impl_->run(); }

}  // namespace mrroc::ui
