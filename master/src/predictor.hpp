// Per-connection predictor: keeps the latest samples of the source output and fits the input
// polynomial for the next step (extrapolation from the past, or interpolation when a sample at
// the step's end exists: Gauss-Seidel and start-up iterations). A connection with
// `use: average` keeps the source's interval means instead and fits them by histopolation
// (docs/config.md, "Interval averages").
#pragma once

#include <cosim/polynomial.hpp>
#include <cosim/time.hpp>

#include <deque>

#include "config.hpp"

namespace master {

class Predictor {
 public:
  Predictor(cosim::SignalKind kind, PredictorSpec spec, Use use = Use::End)
      : kind_(kind), spec_(spec), use_(use) {}
  // Adds the sample at t, replacing one already there (an iterated step's newer value). With
  // use = Average only the initial output is recorded this way: the constant until a mean exists.
  void record(TimePoint t, const cosim::Value& value);
  // Adds the source's mean over [t_start, t_end] (use = Average), replacing one already there.
  void record_mean(TimePoint t_start, TimePoint t_end, const cosim::Value& mean);
  // The polynomial over [t_start, t_end] from the latest samples at times <= t_end (use = End),
  // or from the latest means of intervals ending at or before t_end (use = Average; the latest
  // point sample as a constant while there is none). With fewer samples than the predictor
  // needs (the first steps), the order drops to what they allow.
  cosim::InputPolynomial predict(TimePoint t_start, TimePoint t_end) const;
  const PredictorSpec& spec() const { return spec_; }
  Use use() const { return use_; }

 private:
  struct Mean {
    TimePoint t_start, t_end;
    cosim::Value value;
  };
  cosim::SignalKind kind_;
  PredictorSpec spec_;
  Use use_;
  std::deque<std::pair<TimePoint, cosim::Value>> samples_;
  std::deque<Mean> means_;
};

}  // namespace master
