#include "console/http_api.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <exception>
#include <fstream>
#include <sstream>
#include <system_error>

#include "mrroc/core/error.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/time.hpp"

// Last: <httplib.h>, which it includes, includes <resolv.h>, which defines `_res`, a name Eigen's
// headers use.
#include "console/http_server.hpp"

// The 3D view's libraries relative to the programs' folder: ui/CMakeLists.txt sets it from the
// install layout (the build tree has the same); a build without it (the fuzzer) uses the default.
#ifndef MRROC_UI_VENDOR_DIR
#define MRROC_UI_VENDOR_DIR "../share/mrroc/ui-vendor"
#endif

namespace mrroc::ui {

namespace {

using json = nlohmann::json;

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
  if (ends(".urdf") || ends(".xml")) return "application/xml; charset=utf-8";
  if (ends(".json")) return "application/json";
  if (ends("LICENSE")) return "text/plain; charset=utf-8";
  return "application/octet-stream";
}

void reply_json(httplib::Response& res, const json& body, int status = 200) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

void serve_asset(const std::string& name, httplib::Response& res) {
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

/// The text of `file`, nothing when it cannot be read.
std::optional<std::string> read_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return std::nullopt;
  return std::move(text).str();
}

/// A file of the 3D view's libraries: `path` is relative to `dir`, made of names of letters,
/// digits, '_', '-' and '.' that do not start with '.' (the route's pattern), so it stays in `dir`.
void serve_vendor(const std::filesystem::path& dir, const std::string& path,
                  httplib::Response& res) {
  const std::filesystem::path file = dir / path;
  std::error_code ec;
  std::optional<std::string> text;
  // No folder set (a console without the view's libraries): nothing, not the current folder's.
  if (!dir.empty() && std::filesystem::is_regular_file(file, ec)) text = read_file(file);
  if (!text) {
    res.status = 404;
    res.set_content(
        // Without the folder's path: this answer needs no token (the console's start names the
        // folder when the libraries are missing).
        fmt::format("no file '{}' among the 3D view's libraries (when they are missing, install "
                    "them with `npm ci --prefix ui/vendor` in the source tree, then build "
                    "mrroc-ui again)",
                    path),
        "text/plain");
    return;
  }
  res.set_header("Cache-Control", "no-cache");
  res.set_content(*text, content_type(path).c_str());
}

std::int64_t integer_param(const httplib::Request& req, const char* name, std::int64_t fallback) {
  if (!req.has_param(name)) return fallback;
  const std::string text = req.get_param_value(name);
  try {
    std::size_t used = 0;
    const long long v = std::stoll(text, &used);
    if (used == text.size()) return v;
  } catch (const std::exception&) {
  }
  throw ApiError(400, fmt::format("query parameter '{}' is '{}', expected an integer", name, text));
}

/// Host names compare without case.
std::string lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

}  // namespace

std::filesystem::path default_vendor_dir() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::filesystem::path bin = ec ? std::filesystem::current_path() : exe.parent_path();
  return (bin / MRROC_UI_VENDOR_DIR).lexically_normal();
}

std::string read_token_file(const std::filesystem::path& file) {
  require_private_file(file, "UI token file");
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

json parse_body(const std::string& text) {
  if (text.empty()) return json::object();
  json body = json::parse(text, nullptr, false);
  if (body.is_discarded() || !body.is_object())
    throw ApiError(400, "request body is not a JSON object");
  return body;
}

JogRequest jog_request_from_json(const json& body) {
  JogRequest r;
  r.robot = body.value("robot", std::string());
  if (!body.contains("axis") || !body["axis"].is_number_integer())
    throw ApiError(400, "jog needs an integer 'axis'");
  const std::string space = body.value("space", std::string("joint"));
  if (space == "tool")
    r.space = JogSpace::tool;
  else if (space != "joint")
    throw ApiError(400, fmt::format("jog space '{}' is neither 'joint' nor 'tool'", space));
  // "step" in the axis' unit; "step_rad", its older name, for joint jogs.
  const char* key = body.contains("step") || r.space == JogSpace::tool ? "step" : "step_rad";
  if (!body.contains(key) || !body[key].is_number())
    throw ApiError(400, fmt::format("jog needs a number '{}' [{}]", key,
                                    r.space == JogSpace::tool ? "m or rad" : "rad or m"));
  r.axis = body["axis"].get<std::int64_t>();
  r.step = body[key].get<double>();
  if (body.contains("direction") && !body["direction"].is_number_integer())
    throw ApiError(400, "jog 'direction' must be +1 or -1");
  r.direction = body.value("direction", 1);
  if (r.direction != 1 && r.direction != -1)
    throw ApiError(400, fmt::format("jog direction {} is neither +1 nor -1", r.direction));
  return r;
}

json mp_json(const MpStatus& s) {
  return json{{"accepted", s.accepted}, {"state", s.state}, {"task", s.task},
              {"runs", s.runs},         {"text", s.text},   {"started_utime", s.started_utime}};
}

json robot_state_json(const RobotReading& r, double age_s) {
  const RobotState& s = r.state;
  return json{{"synchronised", s.synchronised},
              {"moving", s.moving},
              {"estop", s.estop},
              {"fault", s.fault},
              {"error", s.error},
              {"servo_step", s.servo_step},
              {"servo_period_s", s.servo_period_s},
              {"q", s.q},
              {"dq", s.dq},
              {"q_desired", s.q_desired},
              {"lateness_mean_us", s.lateness_mean_us},
              {"lateness_max_us", s.lateness_max_us},
              {"overruns", s.overruns},
              {"utime", r.utime},
              {"age_s", age_s}};
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

std::vector<std::string> joint_units(const RobotModel& model) {
  std::vector<std::string> units;
  for (std::size_t j = 0; j < model.axes(); ++j) units.emplace_back(model.unit(j));
  return units;
}

json jog_json(const JogResult& r) {
  return json{{"ok", true},
              {"text", r.text},
              {"q", r.q},
              {"q_before", r.q_before},
              {"motion_steps", r.motion_steps},
              {"synchronised", r.synchronised}};
}

json teach_json(const TeachResult& r) {
  return json{{"ok", true},
              {"file", r.file.string()},
              {"points", r.points},
              {"pose", r.pose},
              {"text", r.text}};
}

json estop_json(const EstopResult& r) {
  json steps = json::object();
  for (const auto& [name, step] : r.servo_step_at_send) steps[name] = step;
  json latency = json::object();
  for (const auto& [name, ms] : r.confirmation.latency_ms) latency[name] = ms;
  return json{{"ok", true},
              {"text", r.text},
              {"servo_step_at_send", steps},
              {"confirmed", r.confirmation.confirmed},
              {"unconfirmed", r.confirmation.unconfirmed},
              {"confirm_ms", latency},
              {"deadline_ms", kEstopConfirmDeadline.count()},
              {"latched_by", r.confirmation.latched_by}};
}

HttpApi::HttpApi(const ConsoleState& state, ApiSettings settings, ConsoleActions& actions)
    : state_(state), settings_(std::move(settings)), actions_(actions) {
  for (std::string& h : settings_.hosts) h = lower(std::move(h));
  if (settings_.token.size() < 16)
    throw Error(
        fmt::format("the console's API token has {} characters, at least 16 needed (every "
                    "/api request must carry one)",
                    settings_.token.size()));
}

bool HttpApi::token_ok(const std::string& authorization) const {
  if (authorization.rfind("Bearer ", 0) != 0) return false;
  const std::string given = authorization.substr(7);
  // Compare in constant time (the length is not secret).
  const std::string& token = settings_.token;
  if (given.size() != token.size()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < given.size(); ++i)
    diff = static_cast<unsigned char>(diff | (given[i] ^ token[i]));
  return diff == 0;
}

json HttpApi::state_json() const {
  const StateSnapshot snap = state_.snapshot();
  json out;
  out["set"] = settings_.set_name;
  out["config"] = settings_.config_file.string();
  out["utime"] = now_utime();
  out["operator_start"] = settings_.operator_start;
  json mp = snap.mp ? mp_json(*snap.mp) : json{{"state", "NO MP"}};
  mp["available"] = snap.mp.has_value();
  mp["error"] = snap.mp_error;
  out["mp"] = mp;
  if (snap.launch) {
    const auto& l = *snap.launch;
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
                           {"required", p.required},
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
  for (const auto& [name, seen] : snap.processes)
    processes.push_back(json{{"name", name},
                             {"robot", seen.status.robot},
                             {"state", to_string(seen.status.state)},
                             {"pid", seen.status.pid},
                             {"uptime_s", static_cast<double>(seen.status.uptime_us) * 1e-6},
                             {"detail", seen.status.detail},
                             {"silent_s", seen.silent_s}});
  out["processes"] = processes;
  json robots = json::array();
  for (std::size_t i = 0; i < state_.robots().size(); ++i) {
    const ConsoleRobot& r = state_.robots()[i];
    const StateSnapshot::Robot& seen = snap.robots[i];
    json j{{"name", r.name},
           {"joint_names", r.model.joint_names},
           {"units", joint_units(r.model)},
           {"cartesian", r.cartesian},
           {"lower_limits", r.model.lower_limits},
           {"upper_limits", r.model.upper_limits},
           {"max_velocity", r.model.max_velocity},
           {"max_acceleration", r.model.max_acceleration},
           {"servo_period_s", r.servo_period_s}};
    j["prismatic"] = r.model.prismatic;
    const auto base = settings_.robot_base.find(r.name);
    j["base"] = base == settings_.robot_base.end() ? std::array<double, 6>{} : base->second;
    j["state"] = seen.reading ? robot_state_json(*seen.reading, seen.age_s) : json();
    robots.push_back(std::move(j));
  }
  out["robots"] = robots;
  out["srp"] = json{
      {"last", snap.log_last}, {"epoch", snap.log_epoch}, {"history_loaded", snap.history_loaded}};
  out["teach_dir"] = settings_.teach_dir.string();
  out["jog_max_step_rad"] = settings_.jog_max_step_rad;
  out["jog_max_step_m"] = settings_.jog_max_step_m;
  return out;
}

json HttpApi::joints_json() const {
  json robots = json::array();
  for (std::size_t i = 0; i < state_.robots().size(); ++i) {
    json j{{"name", state_.robots()[i].name}};
    if (const auto reading = state_.reading(i)) {
      const RobotState& s = reading->state;
      j["step"] = s.servo_step;
      j["utime"] = reading->utime;
      j["age_s"] = seconds_since(reading->received);
      j["q"] = s.q;
      j["q_desired"] = s.q_desired;
    } else {
      j["step"] = nullptr;
    }
    robots.push_back(std::move(j));
  }
  json objects = nullptr;
  if (const auto reading = state_.scene_objects()) {
    json poses = json::array();
    for (const SceneObjectPose& o : reading->objects.objects) {
      const auto& p = o.position;
      const auto& q = o.quaternion;
      poses.push_back(json::array({p[0], p[1], p[2], q[0], q[1], q[2], q[3]}));
    }
    objects = json{{"seq", reading->seq},
                   {"utime", reading->utime},
                   {"age_s", seconds_since(reading->received)},
                   {"poses", std::move(poses)}};
  }
  return json{{"utime", now_utime()}, {"robots", robots}, {"objects", objects}};
}

namespace {
const char* shape_text(SceneObjectShape shape) {
  switch (shape) {
    case SceneObjectShape::box: return "box";
    case SceneObjectShape::sphere: return "sphere";
    case SceneObjectShape::cylinder: return "cylinder";
    case SceneObjectShape::capsule: return "capsule";
  }
  return "?";
}
}  // namespace

json HttpApi::objects_json() const {
  json objects = json::array();
  const auto reading = state_.scene_objects();
  if (!reading)
    return json{{"scene", nullptr}, {"seq", nullptr},        {"utime", nullptr},
                {"age_s", nullptr}, {"sim_time_s", nullptr}, {"objects", objects}};
  for (const SceneObjectPose& o : reading->objects.objects)
    objects.push_back(json{{"name", o.name},
                           {"shape", shape_text(o.shape)},
                           {"size", o.size},
                           {"rgba", o.rgba},
                           {"attach", o.attach},
                           {"local_position", o.local_position},
                           {"local_quaternion", o.local_quaternion},
                           {"position", o.position},
                           {"quaternion", o.quaternion}});
  return json{{"scene", reading->objects.scene},
              {"seq", reading->seq},
              {"utime", reading->utime},
              {"age_s", seconds_since(reading->received)},
              {"sim_time_s", reading->objects.sim_time_s},
              {"objects", std::move(objects)}};
}

std::string HttpApi::model_text(const std::string& robot, const std::string& kind) const {
  const RobotModel& model = state_.robot(robot).model;
  const std::filesystem::path& file = kind == "mjcf" ? model.mjcf : model.urdf;
  if (file.empty()) throw ApiError(404, fmt::format("robot '{}' has no {} file", robot, kind));
  if (auto text = read_file(file)) return std::move(*text);
  throw ApiError(
      500, fmt::format("cannot read the {} file of robot '{}': '{}'", kind, robot, file.string()));
}

json HttpApi::samples_json(const std::string& robot, std::int64_t after) const {
  const std::size_t index = state_.robot_index(robot);
  json samples = json::array();
  for (const Sample& s : state_.samples_after(index, after))
    samples.push_back(json{{"step", s.step},
                           {"utime", s.utime},
                           {"q", s.q},
                           {"dq", s.dq},
                           {"lateness_mean_us", s.lateness_mean_us},
                           {"lateness_max_us", s.lateness_max_us}});
  return json{{"robot", robot},
              {"servo_period_s", state_.robots()[index].servo_period_s},
              {"samples", samples}};
}

json HttpApi::srp_json(std::int64_t after, std::int64_t min_severity, std::int64_t max) const {
  if (min_severity < 0 || min_severity > 4)
    throw ApiError(
        400, fmt::format("min_severity {} is not a severity 0 (DEBUG) .. 4 (FATAL)", min_severity));
  if (max < 1 || max > 5000)
    throw ApiError(400, fmt::format("max {} is out of range 1..5000", max));
  const LogView log =
      state_.messages(after, static_cast<int>(min_severity), static_cast<std::size_t>(max));
  json messages = json::array();
  for (const LogEntry& e : log.entries) messages.push_back(message_json(e));
  return json{{"last", log.last},
              {"epoch", log.epoch},
              {"history_loaded", log.history_loaded},
              {"srp_last", log.srp_last},
              {"messages", messages}};
}

std::string HttpApi::host_of(std::string_view value, bool origin) {
  if (origin) {
    const auto scheme = value.find("://");
    if (scheme == std::string_view::npos) return "";
    const std::string_view s = value.substr(0, scheme);
    if (s != "http" && s != "https") return "";
    value.remove_prefix(scheme + 3);
    if (value.find('/') != std::string_view::npos) return "";
  }
  std::string_view host = value;
  if (!host.empty() && host.front() == '[') {  // [v6 address]:port
    const auto close = host.find(']');
    if (close == std::string_view::npos) return "";
    const std::string_view rest = host.substr(close + 1);
    if (!rest.empty() && rest.front() != ':') return "";
    host = host.substr(1, close - 1);
  } else if (const auto colon = host.find(':'); colon != std::string_view::npos) {
    if (host.find(':', colon + 1) != std::string_view::npos) return "";  // bare v6: not a Host
    host = host.substr(0, colon);
  }
  return lower(std::string(host));
}

std::optional<std::string> HttpApi::refuse_host(const std::string& host,
                                                const std::string& origin) const {
  const auto allowed = [this](const std::string& name) {
    return !name.empty() &&
           std::find(settings_.hosts.begin(), settings_.hosts.end(), name) != settings_.hosts.end();
  };
  std::string names;
  for (const std::string& h : settings_.hosts) names += (names.empty() ? "" : ", ") + h;
  if (!allowed(host_of(host, false)))
    return fmt::format("Host '{}' is not a name of this console ({}; more in [ui] hosts)", host,
                       names);
  if (!origin.empty() && !allowed(host_of(origin, true)))
    return fmt::format("requests from pages of '{}' are refused (this console's names: {})", origin,
                       names);
  return std::nullopt;
}

void HttpApi::install(ConsoleServer& server) {
  server.set_payload_max_length(kMaxBodyBytes);
  server.set_read_timeout(kIoTimeoutS, 0);
  server.set_write_timeout(kIoTimeoutS, 0);
  server.set_keep_alive_timeout(kIoTimeoutS);
  // No other site may frame the console (clickjacking) or make a browser guess content types.
  server.set_default_headers({{"X-Frame-Options", "DENY"},
                              {"Content-Security-Policy", "frame-ancestors 'none'"},
                              {"X-Content-Type-Options", "nosniff"},
                              {"Referrer-Policy", "no-referrer"}});
  // A client that asks before sending its body (curl does above 1 MiB) is refused before it
  // sends it.
  server.set_expect_100_continue_handler([](const httplib::Request& req, httplib::Response& res) {
    if (const auto refusal = refuse_declared_body(req, kMaxBodyBytes)) {
      reply_json(res, json{{"error", refusal->text}}, refusal->status);
      return refusal->status;
    }
    return 100;
  });
  server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    // Before anything else, so that no body above the limit is read (the server closes the
    // connection after this answer).
    if (const auto refusal = refuse_declared_body(req, kMaxBodyBytes)) {
      reply_json(res, json{{"error", refusal->text}}, refusal->status);
      return httplib::Server::HandlerResponse::Handled;
    }
    // DNS rebinding (a name of another site resolving to this host) and pages of other sites.
    if (const auto why =
            refuse_host(req.get_header_value("Host"), req.get_header_value("Origin"))) {
      reply_json(res, json{{"error", *why}}, 403);
      return httplib::Server::HandlerResponse::Handled;
    }
    if (req.path.rfind("/api/", 0) != 0) return httplib::Server::HandlerResponse::Unhandled;
    // Only in the header: a query string lands in proxies' and servers' logs and in the
    // browser's history. `?token=` is for opening the page, whose script moves it to the header.
    if (!token_ok(req.get_header_value("Authorization"))) {
      reply_json(res,
                 json{{"error", fmt::format("missing or wrong token: send the header "
                                            "'Authorization: Bearer TOKEN' (a browser: open the "
                                            "page once as /?token=TOKEN; the API takes the token "
                                            "only in the header){}; {}",
                                            req.has_param("token") ? ", not as ?token=" : "",
                                            settings_.token_hint)}},
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
  server.Get(
      "/", [](const httplib::Request&, httplib::Response& res) { serve_asset("index.html", res); });
  server.Get(R"(/([A-Za-z0-9_.-]+))", [](const httplib::Request& req, httplib::Response& res) {
    serve_asset(req.matches[1], res);
  });
  server.Get(R"(/vendor/((?:[A-Za-z0-9_-][A-Za-z0-9_.-]*/)*[A-Za-z0-9_-][A-Za-z0-9_.-]*))",
             [this](const httplib::Request& req, httplib::Response& res) {
               serve_vendor(settings_.vendor_dir, req.matches[1], res);
             });
  server.Get("/api/joints", [this](const httplib::Request&, httplib::Response& res) {
    reply_json(res, joints_json());
  });
  server.Get("/api/objects", [this](const httplib::Request&, httplib::Response& res) {
    reply_json(res, objects_json());
  });
  server.Get(R"(/api/robots/([a-z][a-z0-9_]*)/(urdf|mjcf))", [this](const httplib::Request& req,
                                                                    httplib::Response& res) {
    res.set_content(model_text(req.matches[1], req.matches[2]), "application/xml; charset=utf-8");
  });
  server.Get("/api/state", [this](const httplib::Request&, httplib::Response& res) {
    reply_json(res, state_json());
  });
  server.Get(R"(/api/robots/([a-z][a-z0-9_]*)/samples)",
             [this](const httplib::Request& req, httplib::Response& res) {
               reply_json(res, samples_json(req.matches[1], integer_param(req, "after", 0)));
             });
  server.Get("/api/srp", [this](const httplib::Request& req, httplib::Response& res) {
    reply_json(res, srp_json(integer_param(req, "after", 0), integer_param(req, "min_severity", 0),
                             integer_param(req, "max", 1000)));
  });
  server.Post(
      R"(/api/command/([a-z]+))", [this](const httplib::Request& req, httplib::Response& res) {
        const std::string word = req.matches[1];
        const auto command = operator_command_from_string(word);
        if (!command)
          throw ApiError(404, fmt::format("unknown command '{}' (start, pause, resume, stop, "
                                          "terminate, status)",
                                          word));
        const MpStatus s = actions_.command(*command);
        json body = mp_json(s);
        body["command"] = word;
        if (!s.accepted) {
          std::string upper = word;
          for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
          body["error"] = fmt::format("the MP refused {}: {}", upper, s.text);
        }
        reply_json(res, body, s.accepted ? 200 : 409);
      });
  server.Post("/api/estop", [this](const httplib::Request& req, httplib::Response& res) {
    // Stopping is always safe: a request whose body cannot be understood (not JSON, a field
    // of the wrong type, an unknown robot) stops every robot instead of none.
    std::string robot;
    std::string reason = "operator console";
    std::string doubt;
    try {
      const json body = parse_body(req.body);
      if (body.contains("robot") && !body["robot"].is_string())
        throw ApiError(400, "'robot' is not a string");
      if (body.contains("reason") && !body["reason"].is_string())
        throw ApiError(400, "'reason' is not a string");
      robot = body.value("robot", std::string());
      if (!robot.empty()) (void)state_.robot(robot);
      reason = body.value("reason", reason);
    } catch (const ApiError& e) {
      doubt = e.what();
      robot.clear();
      reason = fmt::format("operator console (request not understood: {}; every robot is stopped)",
                           doubt);
    }
    json out = estop_json(actions_.emergency_stop(true, robot, reason));
    if (doubt.empty()) {
      reply_json(res, out);
    } else {
      out["error"] = fmt::format("request not understood ({}): every robot was stopped", doubt);
      reply_json(res, out, 400);
    }
  });
  server.Post("/api/release", [this](const httplib::Request& req, httplib::Response& res) {
    const json body = parse_body(req.body);
    const std::string robot = body.value("robot", std::string());
    if (!robot.empty()) (void)state_.robot(robot);
    const std::string reason = body.value("reason", std::string("operator console"));
    reply_json(res, estop_json(actions_.emergency_stop(false, robot, reason)));
  });
  server.Post("/api/jog", [this](const httplib::Request& req, httplib::Response& res) {
    reply_json(res, jog_json(actions_.jog(jog_request_from_json(parse_body(req.body)))));
  });
  server.Post("/api/synchronise", [this](const httplib::Request& req, httplib::Response& res) {
    const json body = parse_body(req.body);
    const auto robot = body.find("robot");
    if (robot == body.end() || !robot->is_string())
      throw ApiError(400, "synchronise needs a string 'robot'");
    reply_json(res, jog_json(actions_.synchronise(robot->get<std::string>())));
  });
  server.Post("/api/teach", [this](const httplib::Request& req, httplib::Response& res) {
    const json body = parse_body(req.body);
    const std::string robot = body.value("robot", std::string());
    const std::string file = body.value("file", robot + ".traj");
    reply_json(res, teach_json(actions_.teach(robot, file)));
  });
}

}  // namespace mrroc::ui
