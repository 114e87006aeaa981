#pragma once
/// @file
/// Typed links: request/reply with plain C++ values on both ends (the LCM types stay inside).
///
///   EdpClient  (ECP side)  <-> EdpServer (EDP side)   channels <robot>/edp/cmd, <robot>/edp/reply
///   EcpClient  (MP side)   <-> EcpServer (ECP side)   channels <robot>/ecp/cmd, <robot>/ecp/reply

#include <chrono>
#include <functional>
#include <optional>
#include <string>

#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/messages.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"

namespace mrroc::comm {

template <class PlainReq, class PlainRep, class LcmReq, class LcmRep>
class PlainClient {
 public:
  PlainClient(Bus& bus, const std::string& name, const std::string& peer,
              const std::string& request_channel, const std::string& reply_channel,
              ClientOptions options = {})
      : client_(bus, unique_endpoint_name(name), peer, request_channel, reply_channel, options) {}

  /// @throws TimeoutError, DecodeError (a reply that does not decode).
  PlainRep call(const PlainReq& request) { return decode(client_.call(encode(request))); }
  /// Client::abandon: the call in progress throws CallAbandoned at once.
  void abandon() { client_.abandon(); }
  [[nodiscard]] LinkStats stats() const { return client_.stats(); }

 private:
  Client<LcmReq, LcmRep> client_;
};

template <class PlainReq, class PlainRep, class LcmReq, class LcmRep>
class PlainServer {
  using Raw = Server<LcmReq, LcmRep>;

 public:
  class Responder {
   public:
    Responder() = default;
    explicit Responder(typename Raw::Responder raw) : raw_(std::move(raw)) {}
    void reply(const PlainRep& rep) const { raw_.reply(encode(rep)); }
    [[nodiscard]] const std::string& client() const { return raw_.client(); }

   private:
    typename Raw::Responder raw_;
  };

  /// A request as received: either decoded, or the reason it could not be decoded.
  struct Incoming {
    std::optional<PlainReq> request;
    std::string decode_error;
    Responder responder;
  };

  /// Queue mode: requests wait for `wait_request`.
  PlainServer(Bus& bus, const std::string& name, const std::string& request_channel,
              const std::string& reply_channel, ServerOptions options = {})
      : server_(bus, name, request_channel, reply_channel, {}, options) {}

  /// Handler mode: `handler` gets every new request on the bus thread, as soon as it is decoded
  /// (one thread hand-off less than the queue); it must not block.
  using Handler = std::function<void(Incoming)>;
  PlainServer(Bus& bus, const std::string& name, const std::string& request_channel,
              const std::string& reply_channel, Handler handler, ServerOptions options = {})
      : server_(
            bus, name, request_channel, reply_channel,
            [handler = std::move(handler)](const LcmReq& raw, typename Raw::Responder responder) {
              handler(convert(raw, std::move(responder)));
            },
            options) {}

  /// Queue mode only: the next request, or nothing after `timeout`.
  std::optional<Incoming> wait_request(std::chrono::milliseconds timeout) {
    auto raw = server_.wait_request(timeout);
    if (!raw) return std::nullopt;
    return convert(raw->request, raw->responder);
  }
  [[nodiscard]] LinkStats stats() const { return server_.stats(); }

 private:
  static Incoming convert(const LcmReq& raw, typename Raw::Responder responder) {
    Incoming in;
    in.responder = Responder(std::move(responder));
    try {
      in.request = decode(raw);
    } catch (const DecodeError& e) {
      in.decode_error = e.what();
    }
    return in;
  }

  Raw server_;
};

using EdpClient =
    PlainClient<edp::Instruction, edp::Reply, mrroc_lcm::edp_instruction_t, mrroc_lcm::edp_reply_t>;
using EdpServer =
    PlainServer<edp::Instruction, edp::Reply, mrroc_lcm::edp_instruction_t, mrroc_lcm::edp_reply_t>;
using EcpClient = PlainClient<ecp::MpCommand, ecp::EcpReply, mrroc_lcm::mp_ecp_command_t,
                              mrroc_lcm::ecp_mp_reply_t>;
using EcpServer = PlainServer<ecp::MpCommand, ecp::EcpReply, mrroc_lcm::mp_ecp_command_t,
                              mrroc_lcm::ecp_mp_reply_t>;

/// ECP or MP (client) <-> VSP (server), channels vsp/<name>/cmd and vsp/<name>/reply.
using VspClient =
    PlainClient<vsp::Request, vsp::Reply, mrroc_lcm::vsp_command_t, mrroc_lcm::vsp_reply_t>;
using VspServer =
    PlainServer<vsp::Request, vsp::Reply, mrroc_lcm::vsp_command_t, mrroc_lcm::vsp_reply_t>;

/// UI (client) <-> MP (server), channels mrroc/mp/cmd and mrroc/mp/reply.
using OperatorClient = PlainClient<mp::OperatorCommand, mp::OperatorReply,
                                   mrroc_lcm::operator_command_t, mrroc_lcm::operator_reply_t>;
using OperatorServer = PlainServer<mp::OperatorCommand, mp::OperatorReply,
                                   mrroc_lcm::operator_command_t, mrroc_lcm::operator_reply_t>;
/// Console (client) <-> SRP (server), channels mrroc/srp/history/cmd and .../reply.
using SrpHistoryClient =
    PlainClient<SrpHistoryRequest, SrpHistoryReply, mrroc_lcm::srp_history_request_t,
                mrroc_lcm::srp_history_reply_t>;
using SrpHistoryServer =
    PlainServer<SrpHistoryRequest, SrpHistoryReply, mrroc_lcm::srp_history_request_t,
                mrroc_lcm::srp_history_reply_t>;

}  // namespace mrroc::comm
