// The master's adaptive resend timeout for one participant, after TCP's retransmission timer
// (RFC 6298): a smoothed round trip SRTT and its variation RTTVAR, RTO = SRTT + 4 RTTVAR with a
// floor, doubled on every resend of one request (backoff) up to a cap. The round trip of a
// step includes the participant's compute time, which says nothing about the network: the
// estimator keeps the network part (round trip - reported compute seconds) and the compute
// time apart, and waits for both. Karn's rule is the caller's: only a reply to a request that
// was sent once gives a sample (a reply to a resent request could answer either copy).
// Liveness is not decided here (heartbeats decide it, see docs/protocol.md).
#pragma once

namespace cosim {

class ResendTimer {
 public:
  // s: the shortest wait. A lost message costs about this much, so it is a few loopback round
  // trips (45-200 us) rather than the 10 ms that scheduling hiccups of a loaded host can reach:
  // a resend that comes too early costs one cached reply, a late one a wait per lost message.
  static constexpr double kFloor = 0.002;
  static constexpr double kCap = 0.5;       // s: longest wait between resends (+ expected compute)
  static constexpr double kInitial = 0.25;  // s: before the first sample (one heartbeat period)

  // One reply to a request sent once: its round trip and the compute seconds it reported.
  void sample(double round_trip_s, double compute_s);
  bool has_sample() const { return samples_ > 0; }
  long samples() const { return samples_; }
  double srtt() const { return srtt_; }            // network part, smoothed
  double rttvar() const { return rttvar_; }
  double expected_compute() const;                  // smoothed compute + 4 x its variation
  // The wait before the first resend of a request: max(floor, SRTT + 4 RTTVAR) + expected
  // compute (kInitial before any sample).
  double base() const;
  // The wait before resend number `resends` + 1 (0: the first): base x 2^resends, at most
  // kCap + expected compute (and never below base).
  double timeout(int resends) const;

 private:
  long samples_ = 0;
  double srtt_ = 0, rttvar_ = 0;
  double compute_ = 0, compute_var_ = 0;
};

}  // namespace cosim
