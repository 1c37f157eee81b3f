// Per-connection predictor: keeps the latest samples of the source output and fits the input
// polynomial for the next step (extrapolation from the past, or interpolation when a sample at
// the step's end exists: Gauss-Seidel and start-up iterations).
#pragma once

#include <cosim/polynomial.hpp>
#include <cosim/time.hpp>

#include <deque>

#include "config.hpp"

namespace master {

class Predictor {
 public:
  Predictor(cosim::SignalKind kind, PredictorSpec spec) : kind_(kind), spec_(spec) {}
  // Adds the sample at t, replacing one already there (an iterated step's newer value).
  void record(TimePoint t, const cosim::Value& value);
  // The polynomial over [t_start, t_end] from the latest samples at times <= t_end. With fewer
  // samples than the predictor needs (the first steps), the order drops to what they allow.
  cosim::InputPolynomial predict(TimePoint t_start, TimePoint t_end) const;
  const PredictorSpec& spec() const { return spec_; }

 private:
  cosim::SignalKind kind_;
  PredictorSpec spec_;
  std::deque<std::pair<TimePoint, cosim::Value>> samples_;
};

}  // namespace master
