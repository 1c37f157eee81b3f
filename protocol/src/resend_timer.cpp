#include "cosim/resend_timer.hpp"

#include <algorithm>
#include <cmath>

namespace cosim {

void ResendTimer::sample(double round_trip_s, double compute_s) {
  if (!std::isfinite(round_trip_s) || !std::isfinite(compute_s)) return;
  compute_s = std::clamp(compute_s, 0.0, round_trip_s > 0 ? round_trip_s : 0.0);
  const double network = std::max(0.0, round_trip_s - compute_s);
  if (samples_ == 0) {  // RFC 6298 (2.2)
    srtt_ = network;
    rttvar_ = network / 2;
    compute_ = compute_s;
    compute_var_ = compute_s / 2;
  } else {  // (2.3), alpha = 1/8, beta = 1/4; RTTVAR first, with the old SRTT
    rttvar_ = 0.75 * rttvar_ + 0.25 * std::abs(srtt_ - network);
    srtt_ = 0.875 * srtt_ + 0.125 * network;
    compute_var_ = 0.75 * compute_var_ + 0.25 * std::abs(compute_ - compute_s);
    compute_ = 0.875 * compute_ + 0.125 * compute_s;
  }
  ++samples_;
}

double ResendTimer::expected_compute() const { return compute_ + 4 * compute_var_; }

double ResendTimer::base() const {
  if (samples_ == 0) return kInitial;
  return std::max(kFloor, srtt_ + 4 * rttvar_) + expected_compute();
}

double ResendTimer::timeout(int resends) const {
  const double b = base();
  const double cap = std::max(b, kCap + expected_compute());
  double t = b;
  for (int i = 0; i < resends && t < cap; ++i) t *= 2;
  return std::min(t, cap);
}

}  // namespace cosim
