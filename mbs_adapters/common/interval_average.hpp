// The interval average a machine reports over one macro step (a connection with use: average,
// docs/config.md#interval-averages-use-average): the trapezoid mean of the samples after each
// inner step and the one at the step's start, component by component; the orientation as the
// normalized mean quaternion, every sample's sign kept on the first sample's hemisphere (q and
// -q are one orientation).
#pragma once

#include <vector>

#include "cosim/quantities.hpp"

namespace mbs {

// What a machine outputs at one instant: the coupled body's kinematics and its scalars.
struct MachineSample {
  cosim::Kinematics body;
  std::vector<double> scalars;
};

class IntervalAverage {
 public:
  // The sample at the start of the interval.
  explicit IntervalAverage(const MachineSample& first);
  // The sample after the next inner step (the same scalars, in the same order).
  void add(MachineSample next);
  // The mean over the samples added so far; needs at least one.
  MachineSample mean() const;

 private:
  void add_half(const MachineSample& x);

  MachineSample first_, last_, sum_;
  cosim::Value body_sum_;
  int n_ = 0;
};

}  // namespace mbs
