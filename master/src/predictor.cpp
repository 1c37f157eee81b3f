#include "predictor.hpp"

#include <stdexcept>

namespace master {

void Predictor::record(TimePoint t, const cosim::Value& value) {
  if (!samples_.empty() && samples_.back().first == t) {
    samples_.back().second = value;
    return;
  }
  if (!samples_.empty() && samples_.back().first > t)
    throw std::logic_error("predictor samples must arrive in time order");
  samples_.emplace_back(t, value);
  // One extra beyond what a fit needs, so a pending sample at t_end never pushes out history.
  while (samples_.size() > static_cast<std::size_t>(spec_.samples) + 1) samples_.pop_front();
}

void Predictor::record_mean(TimePoint t_start, TimePoint t_end, const cosim::Value& mean) {
  if (use_ != Use::Average) throw std::logic_error("interval mean recorded for a use: end connection");
  if (!means_.empty() && means_.back().t_end == t_end) {
    means_.back() = {t_start, t_end, mean};
    return;
  }
  if (!means_.empty() && means_.back().t_end > t_start)
    throw std::logic_error("predictor means must arrive in time order");
  means_.push_back({t_start, t_end, mean});
  // As for samples: one extra, so a pending mean over the current step never pushes out history.
  while (means_.size() > static_cast<std::size_t>(spec_.samples) + 1) means_.pop_front();
}

cosim::InputPolynomial Predictor::predict(TimePoint t_start, TimePoint t_end) const {
  const Duration H = t_end - t_start;
  // s of a time: its time since t_start over H, both in ns as doubles.
  const auto s_of = [&](TimePoint t) {
    return static_cast<double>(cosim::to_ns(t - t_start)) / static_cast<double>(cosim::to_ns(H));
  };
  if (use_ == Use::Average) {
    // The latest spec_.samples means of intervals ending at or before t_end: histopolation.
    std::vector<std::pair<double, double>> intervals;
    std::vector<cosim::Value> v;
    for (auto it = means_.rbegin(); it != means_.rend() && static_cast<int>(v.size()) < spec_.samples; ++it) {
      if (it->t_end > t_end) continue;
      intervals.insert(intervals.begin(), {s_of(it->t_start), s_of(it->t_end)});
      v.insert(v.begin(), it->value);
    }
    if (!v.empty()) {
      const int order = std::min<int>(spec_.order, static_cast<int>(v.size()) - 1);
      return cosim::fit_polynomial_to_means(kind_, intervals, v, order);
    }
    // No mean yet (the first pass of step 0): the latest point sample, the initial output.
    for (auto it = samples_.rbegin(); it != samples_.rend(); ++it)
      if (it->first <= t_end) return cosim::InputPolynomial::constant(kind_, it->second);
    throw std::logic_error("predictor has no sample");
  }
  std::vector<double> s;
  std::vector<cosim::Value> v;
  // The latest spec_.samples samples with t <= t_end.
  for (auto it = samples_.rbegin(); it != samples_.rend() && static_cast<int>(s.size()) < spec_.samples; ++it) {
    if (it->first > t_end) continue;
    s.insert(s.begin(), s_of(it->first));
    v.insert(v.begin(), it->second);
  }
  if (s.empty()) throw std::logic_error("predictor has no sample");
  const int order = std::min<int>(spec_.order, static_cast<int>(s.size()) - 1);
  return cosim::fit_polynomial(kind_, s, v, order, s.size() - 1);
}

}  // namespace master
