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

cosim::InputPolynomial Predictor::predict(TimePoint t_start, TimePoint t_end) const {
  std::vector<double> s;
  std::vector<cosim::Value> v;
  const Duration H = t_end - t_start;
  // s of a sample: its time since t_start over H, both in ns as doubles.
  // The latest spec_.samples samples with t <= t_end.
  for (auto it = samples_.rbegin(); it != samples_.rend() && static_cast<int>(s.size()) < spec_.samples; ++it) {
    if (it->first > t_end) continue;
    s.insert(s.begin(), static_cast<double>(cosim::to_ns(it->first - t_start)) /
                            static_cast<double>(cosim::to_ns(H)));
    v.insert(v.begin(), it->second);
  }
  if (s.empty()) throw std::logic_error("predictor has no sample");
  const int order = std::min<int>(spec_.order, static_cast<int>(s.size()) - 1);
  return cosim::fit_polynomial(kind_, s, v, order, s.size() - 1);
}

}  // namespace master
