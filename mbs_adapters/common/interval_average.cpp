#include "interval_average.hpp"

#include <stdexcept>
#include <utility>

namespace mbs {

IntervalAverage::IntervalAverage(const MachineSample& first)
    : first_(first), last_(first), sum_(first), body_sum_(first.body.to_value()) {
  for (auto& v : body_sum_) v *= 0.5;
  for (auto& v : sum_.scalars) v *= 0.5;
}

void IntervalAverage::add_half(const MachineSample& x) {
  if (x.scalars.size() != sum_.scalars.size())
    throw std::logic_error("IntervalAverage: a sample with another number of scalars");
  const cosim::Value b = x.body.to_value();
  for (std::size_t i = 0; i < b.size(); ++i) body_sum_[i] += b[i] * 0.5;
  for (std::size_t i = 0; i < sum_.scalars.size(); ++i) sum_.scalars[i] += x.scalars[i] * 0.5;
}

// Each inner interval [k-1, k] adds half of both ends: the running sum is
// first/2 + s1 + ... + s(n-1) + sn/2 once the next sample's first half is in.
void IntervalAverage::add(MachineSample next) {
  if (n_ > 0) add_half(last_);
  last_ = std::move(next);
  cosim::Quat& q = last_.body.orientation;
  const cosim::Quat& q0 = first_.body.orientation;
  if (q[0] * q0[0] + q[1] * q0[1] + q[2] * q0[2] + q[3] * q0[3] < 0)
    for (double& c : q) c = -c;
  add_half(last_);
  ++n_;
}

MachineSample IntervalAverage::mean() const {
  if (n_ < 1) throw std::logic_error("IntervalAverage: no sample after the first");
  cosim::Value body = body_sum_;
  MachineSample m = sum_;
  for (auto& v : body) v /= n_;
  for (auto& v : m.scalars) v /= n_;
  m.body = cosim::Kinematics::from_value(body);
  m.body.orientation = cosim::quat_normalized(m.body.orientation);
  return m;
}

}  // namespace mbs
