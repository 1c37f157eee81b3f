#include "cosim/link.hpp"

#include "cosim/bus.hpp"

namespace cosim {

ParticipantInfo Transport::accept_ready(const ready_t& r) const {
  if (!r.ok) throw ParticipantConfigError(r.participant, r.error);
  const std::string what = "participant '" + r.participant + "'";
  try {
    if (r.protocol_version != kProtocolVersion)
      throw ProtocolError("speaks protocol version " + std::to_string(r.protocol_version) +
                          ", the master " + std::to_string(kProtocolVersion));
    ParticipantInfo info;
    info.inputs = ports_from_message(r.inputs, what + " inputs");
    info.outputs = ports_from_message(r.outputs, what + " outputs");
    if (r.inner_step_ns <= 0) throw ProtocolError("reports inner step " + std::to_string(r.inner_step_ns));
    info.inner_step = nanoseconds(r.inner_step_ns);
    info.can_repeat = r.can_repeat;
    info.can_checkpoint = r.can_checkpoint;
    if (!r.can_repeat) info.repeat_note = r.error;
    info.initial_outputs = from_message(r.initial_outputs, what + " initial outputs");
    check_against_ports(info.initial_outputs, info.outputs, what + " initial outputs");
    return info;
  } catch (const ProtocolError& e) {
    throw LinkError(r.participant, what + ": invalid ready message: " + e.what());
  }
}

StepAnswer Transport::accept(const step_request_t& q, const step_reply_t& r,
                             const ParticipantInfo& info, double round_trip) const {
  const std::string what = "participant '" + q.participant + "' step " +
                           std::to_string(q.step_index) + " (t = " +
                           std::to_string(to_seconds(time_point_ns(q.t_start_ns))) + " s)";
  if (r.status == step_reply_t::REJECTED)
    throw LinkError(q.participant, what + " refused the request: " + r.message);
  const bool ended = r.status == step_reply_t::ENDED;
  if (r.status != step_reply_t::OK && !ended)
    throw LinkError(q.participant, what + " failed: " + r.message);
  StepAnswer a;
  try {
    if (r.t_start_ns != q.t_start_ns || (ended ? r.t_end_ns < q.t_start_ns || r.t_end_ns > q.t_end_ns
                                               : r.t_end_ns != q.t_end_ns))
      throw ProtocolError("reply times do not match the request");
    if (ended) {
      a.ended_at = time_point_ns(r.t_end_ns);
      a.ended_reason = r.message;
    }
    a.outputs = from_message(r.outputs, "outputs");
    check_against_ports(a.outputs, info.outputs, "outputs");
    if (q.want_average) {
      if (!r.has_average)
        throw MissingAverageError(q.participant,
                                  what + ": the interval average of its outputs was asked for but "
                                         "not sent (it does not compute averages)");
      a.average = from_message(r.average, "averages");
      check_against_ports(*a.average, info.outputs, "averages");
    }
    for (const auto& d : r.diagnostics) {
      require_valid_name(d.name, "diagnostic");
      a.diagnostics.emplace_back(d.name, d.value);
    }
    if (!std::isfinite(r.compute_seconds) || r.compute_seconds < 0)
      throw ProtocolError("compute_seconds is not a finite non-negative number");
    if (q.checkpoint && !r.checkpointed)
      throw ProtocolError("a checkpoint was asked for but the reply says none was written");
  } catch (const ProtocolError& e) {
    throw LinkError(q.participant, what + ": invalid reply: " + e.what());
  }
  a.compute_seconds = r.compute_seconds;
  a.round_trip_seconds = round_trip;
  a.checkpointed = q.checkpoint && r.checkpointed;
  return a;
}

}  // namespace cosim
