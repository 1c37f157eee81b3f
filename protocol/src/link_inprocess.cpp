// The same protocol without the bus: messages are encoded and decoded as on the wire and
// handed to ParticipantCore objects directly. Used by tests and analysis tools to run a
// schedule in one process and compare it with the multi-process run.
#include <vector>

#include "cosim/link.hpp"
#include "cosim/stopwatch.hpp"

namespace cosim {
namespace {

template <class Message>
Message through_wire(const Message& m) {
  std::vector<uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  Message out;
  if (out.decode(buf.data(), 0, static_cast<int>(buf.size())) < 0)
    throw ProtocolError("message does not decode");
  return out;
}

class InProcessTransport final : public Transport {
 public:
  InProcessTransport(int64_t session, std::map<std::string, ParticipantCore*> cores)
      : session_(session), cores_(std::move(cores)) {}

  int64_t session() const override { return session_; }
  std::string describe() const override { return "in-process"; }

  std::map<std::string, ParticipantInfo> connect(const std::vector<configure_t>& configs,
                                                 double) override {
    std::map<std::string, ParticipantInfo> out;
    for (const auto& c : configs) {
      auto it = cores_.find(c.participant);
      if (it == cores_.end())
        throw LinkError(c.participant, "no in-process participant named '" + c.participant + "'");
      auto ready = it->second->configure(through_wire(c));
      if (!ready) throw LinkError(c.participant, "participant ignored its configuration");
      out[c.participant] = infos_[c.participant] = accept_ready(through_wire(*ready));
    }
    return out;
  }

  std::vector<StepAnswer> exchange(const std::vector<step_request_t>& requests) override {
    std::vector<StepAnswer> out;
    for (const auto& q : requests) {
      const Stopwatch start;
      auto reply = cores_.at(q.participant)->handle(through_wire(q));
      if (!reply) throw LinkError(q.participant, "participant ignored step " +
                                                     std::to_string(q.step_index));
      const double rt = start.seconds();
      out.push_back(accept(q, through_wire(*reply), infos_.at(q.participant), rt));
    }
    return out;
  }

  void terminate(bool, const std::string&) override {}

 private:
  int64_t session_;
  std::map<std::string, ParticipantCore*> cores_;
  std::map<std::string, ParticipantInfo> infos_;
};

}  // namespace

std::unique_ptr<Transport> make_in_process_transport(
    int64_t session, std::map<std::string, ParticipantCore*> participants) {
  return std::make_unique<InProcessTransport>(session, std::move(participants));
}

}  // namespace cosim
