#pragma once
// The console's HTTP side: the page's files, the JSON API's routes, the encoding of the state and
// of the actions' answers, the decoding of request bodies, errors as {"error": text} with their
// status, the token and the cross-site check (docs/operating.md, "JSON API"). It reads a
// ConsoleState and hands every POST to ConsoleActions, so that it runs without a bus.

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "console/jog.hpp"
#include "console/state.hpp"
#include "console/teach_in.hpp"
#include "operator.hpp"

namespace mrroc::ui {

class ConsoleServer;  // console/http_server.hpp

/// The page's files (ui/web/), embedded at build time (generated web_assets.cpp).
const std::map<std::string, std::string_view>& web_assets();

/// Reads the token file: its first line without surrounding blanks, at least 16 characters.
/// @throws Error naming the file when it cannot be read or the token is too short.
std::string read_token_file(const std::filesystem::path& file);

/// What /api/state shows besides the state.
struct ApiSettings {
  std::string set_name;
  std::filesystem::path config_file;
  bool operator_start = false;  ///< the MP waits for the operator's START
  std::filesystem::path teach_dir;
  double jog_max_step_rad = JogOptions{}.max_step_rad;  ///< [rad]
  double jog_max_step_m = JogOptions{}.max_step_m;      ///< tool translation [m]
  /// The names and addresses a request's Host (and a browser's Origin) may carry, without the
  /// port: others are refused (DNS rebinding; a page of another site). Compared in lower case.
  std::vector<std::string> hosts{"localhost", "127.0.0.1", "::1"};
  /// Every /api request must carry it in the header `Authorization: Bearer TOKEN` (never in
  /// the query string, which logs and histories keep); at least 16 characters.
  std::string token;
  /// Where a client finds the token, for the answer to a request without it, e.g. "it is the
  /// first line of [ui] token_file '/etc/mrroc/ui.token'".
  std::string token_hint;
  /// Where the 3D view's browser libraries are (three.js, urdf-loader: ui/vendor.cmake copies
  /// them there at build time; default_vendor_dir()); GET /vendor/<path> serves its files.
  std::filesystem::path vendor_dir;
  /// Each robot's base in the cell, as [[robot]] base gives it: x, y, z [m] and a rotation
  /// vector [rad]; a robot not named here stands at the origin.
  std::map<std::string, std::array<double, 6>> robot_base;
};

/// The folder of the 3D view's browser libraries next to the running program:
/// <folder of /proc/self/exe>/MRROC_UI_VENDOR_DIR (a path relative to the programs' folder, set by
/// ui/CMakeLists.txt; in the build tree and in an install alike).
std::filesystem::path default_vendor_dir();

/// An emergency stop or release as sent and confirmed.
struct EstopResult {
  std::string text;  ///< "EMERGENCY STOP (...) for every robot: confirmed by ..."
  /// The servo step each EDP was in when the stop was sent, estimated from its last state.
  std::map<std::string, std::int64_t> servo_step_at_send;
  EstopConfirmation confirmation;
};

/// What the POST routes do (the console does it over the bus).
class ConsoleActions {
 public:
  virtual ~ConsoleActions() = default;
  /// Sends an operator command to the MP. @throws ApiError 504 when no MP answers.
  virtual MpStatus command(OperatorCommand command) = 0;
  /// `robot` empty: every robot; it was checked to be one of the set's.
  virtual EstopResult emergency_stop(bool engage, const std::string& robot,
                                     const std::string& reason) = 0;
  /// @throws ApiError as Jogger::jog.
  virtual JogResult jog(const JogRequest& request) = 0;
  /// @throws ApiError as Jogger::synchronise.
  virtual JogResult synchronise(const std::string& robot) = 0;
  /// @throws ApiError as TeachIn::record.
  virtual TeachResult teach(const std::string& robot, const std::string& file) = 0;
};

/// A request body: {} when empty. @throws ApiError 400 when it is not a JSON object.
nlohmann::json parse_body(const std::string& body);
/// {"robot", "axis", "step_rad", "direction"?}. @throws ApiError 400 naming the missing or
/// mistyped field; nlohmann::json::exception for a "robot" that is not a string.
JogRequest jog_request_from_json(const nlohmann::json& body);

nlohmann::json mp_json(const MpStatus& status);
nlohmann::json robot_state_json(const RobotReading& reading, double age_s);
nlohmann::json message_json(const LogEntry& entry);
nlohmann::json jog_json(const JogResult& result);
/// Per joint "rad" (revolute) or "m" (prismatic): the unit of its values, per second for its
/// velocities.
std::vector<std::string> joint_units(const RobotModel& model);
nlohmann::json teach_json(const TeachResult& result);
nlohmann::json estop_json(const EstopResult& result);

class HttpApi {
 public:
  /// @throws Error when settings.token has fewer than 16 characters (every request needs one).
  HttpApi(const ConsoleState& state, ApiSettings settings, ConsoleActions& actions);

  /// Installs the routes, the Host/Origin, token and cross-site checks, the anti-framing
  /// headers, the request limits (kMaxBodyBytes, kIoTimeoutS) and the error answers on `server`
  /// (whose own limits bound connections and the time and size of a request).
  void install(ConsoleServer& server);

  /// Largest request body accepted [bytes]: a larger Content-Length gets 413 and a chunked body
  /// 411, before any of it is read (refuse_declared_body).
  static constexpr std::size_t kMaxBodyBytes = 64 * 1024;
  /// A connection that sends or takes nothing for this long is closed [s].
  static constexpr int kIoTimeoutS = 5;

  /// The host of a Host header or an Origin ("http://name:8080" with `origin`), lower case and
  /// without the port; "" when it does not parse.
  [[nodiscard]] static std::string host_of(std::string_view value, bool origin);
  /// Whether a request with these Host and Origin headers ("" when absent) may be served; else
  /// the reason.
  [[nodiscard]] std::optional<std::string> refuse_host(const std::string& host,
                                                       const std::string& origin) const;

  /// GET /api/state.
  [[nodiscard]] nlohmann::json state_json() const;
  /// GET /api/joints: every robot's latest measured and commanded joints (the 3D view polls it).
  /// With the emulator's scene objects, "objects": the seq, utime and age_s of their latest
  /// message and "poses": per object (in the order of /api/objects) x y z [m], qw qx qy qz;
  /// null before any came.
  [[nodiscard]] nlohmann::json joints_json() const;
  /// GET /api/objects: the cell emulator's scene objects ("scene", "seq", "utime", "age_s",
  /// "sim_time_s" and "objects": name, shape, size [m], rgba, attach, local_position [m] and
  /// local_quaternion (w x y z: in the frame of attach), position [m], quaternion w x y z);
  /// "objects" empty and "seq" null before any message came.
  [[nodiscard]] nlohmann::json objects_json() const;
  /// GET /api/robots/<robot>/urdf and /mjcf: the text of the robot's URDF or MJCF (`kind`),
  /// the files its model folder's parameters.toml names.
  /// @throws ApiError 404 for an unknown robot, 500 naming the file when it cannot be read.
  [[nodiscard]] std::string model_text(const std::string& robot, const std::string& kind) const;
  /// GET /api/robots/<robot>/samples?after=STEP. @throws ApiError 404 for an unknown robot.
  [[nodiscard]] nlohmann::json samples_json(const std::string& robot, std::int64_t after) const;
  /// GET /api/srp. @throws ApiError 400 for a severity outside 0..4 or max outside 1..5000.
  [[nodiscard]] nlohmann::json srp_json(std::int64_t after, std::int64_t min_severity,
                                        std::int64_t max) const;
  /// Whether `authorization` (the header's value) is "Bearer TOKEN"; compared in constant time.
  [[nodiscard]] bool token_ok(const std::string& authorization) const;

 private:
  const ConsoleState& state_;
  ApiSettings settings_;
  ConsoleActions& actions_;
};

}  // namespace mrroc::ui
