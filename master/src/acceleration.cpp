#include "acceleration.hpp"

#include <cmath>
#include <stdexcept>

namespace master {

namespace {

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

std::vector<double> residual(const std::vector<double>& x_in, const std::vector<double>& x) {
  if (x_in.size() != x.size()) throw std::logic_error("acceleration: vectors of different sizes");
  std::vector<double> r(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) r[i] = x[i] - x_in[i];
  return r;
}

std::vector<double> relax(const std::vector<double>& x_in, const std::vector<double>& x, double omega) {
  std::vector<double> out(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) out[i] = x_in[i] + omega * (x[i] - x_in[i]);
  return out;
}

}  // namespace

std::vector<double> ConstantRelaxation::next(const std::vector<double>& x_in, const std::vector<double>& x, int) {
  if (omega_ == 1.0) return x;  // plain iteration, bit for bit
  return relax(x_in, x, omega_);
}

std::vector<double> AitkenRelaxation::next(const std::vector<double>& x_in, const std::vector<double>& x, int iteration) {
  const auto r = residual(x_in, x);
  if (iteration == 0 || r_prev_.size() != r.size()) {
    omega_ = initial_;
  } else {
    std::vector<double> dr(r.size());
    for (std::size_t i = 0; i < r.size(); ++i) dr[i] = r[i] - r_prev_[i];
    const double den = dot(dr, dr);
    if (den > 0) omega_ = -omega_ * dot(r_prev_, dr) / den;  // else: converged, keep omega
  }
  r_prev_ = r;
  return relax(x_in, x, omega_);
}

std::vector<double> IqnIls::next(const std::vector<double>& x_in, const std::vector<double>& x, int iteration) {
  const auto r = residual(x_in, x);
  const std::size_t n = r.size();
  if (iteration > 0 && r_prev_.size() == n) {
    Column c{std::vector<double>(n), std::vector<double>(n)};
    for (std::size_t i = 0; i < n; ++i) c.v[i] = r[i] - r_prev_[i], c.w[i] = x[i] - x_prev_[i];
    current_.push_front(std::move(c));
  }
  r_prev_ = r;
  x_prev_ = x;
  std::vector<double> w(n, 1.0);
  if (weights_.size() == n) w = weights_;
  // Candidate columns, newest first: this step's, then the past steps'.
  std::vector<const Column*> cols;
  for (const auto& c : current_) cols.push_back(&c);
  for (const auto& step : past_)
    for (const auto& c : step) cols.push_back(&c);
  if (cols.size() > static_cast<std::size_t>(max_columns_)) cols.resize(static_cast<std::size_t>(max_columns_));
  // Modified Gram-Schmidt on the scaled columns with the QR2 filter.
  std::vector<std::vector<double>> Q;
  std::vector<std::vector<double>> R;  // R[j] = column j of R (entries 0..j)
  std::vector<const Column*> kept;
  for (const Column* c : cols) {
    std::vector<double> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = w[i] * c->v[i];
    const double norm0 = std::sqrt(dot(v, v));
    if (!(norm0 > 0) || !std::isfinite(norm0)) continue;
    std::vector<double> rcol(Q.size() + 1, 0.0);
    for (std::size_t j = 0; j < Q.size(); ++j) {
      rcol[j] = dot(Q[j], v);
      for (std::size_t i = 0; i < n; ++i) v[i] -= rcol[j] * Q[j][i];
    }
    const double norm = std::sqrt(dot(v, v));
    if (norm < filter_ * norm0 || norm == 0) continue;  // nearly dependent on newer columns
    rcol.back() = norm;
    for (auto& e : v) e /= norm;
    Q.push_back(std::move(v));
    R.push_back(std::move(rcol));
    kept.push_back(c);
  }
  used_ = static_cast<int>(kept.size());
  if (kept.empty()) return relax(x_in, x, initial_);
  // R alpha = -Q^T (w r)
  const std::size_t m = kept.size();
  std::vector<double> rhs(m), wr(n);
  for (std::size_t i = 0; i < n; ++i) wr[i] = w[i] * r[i];
  for (std::size_t j = 0; j < m; ++j) rhs[j] = -dot(Q[j], wr);
  std::vector<double> alpha(m);
  for (std::size_t jj = m; jj-- > 0;) {
    double s = rhs[jj];
    for (std::size_t k = jj + 1; k < m; ++k) s -= R[k][jj] * alpha[k];
    alpha[jj] = s / R[jj][jj];
  }
  std::vector<double> out = x;
  for (std::size_t j = 0; j < m; ++j)
    for (std::size_t i = 0; i < n; ++i) out[i] += alpha[j] * kept[j]->w[i];
  return out;
}

void IqnIls::end_step() {
  pushed_ = false;
  dropped_.clear();
  if (reuse_ > 0 && !current_.empty()) {
    past_.push_front(std::move(current_));
    pushed_ = true;
    while (past_.size() > static_cast<std::size_t>(reuse_)) {
      dropped_.push_front(std::move(past_.back()));
      past_.pop_back();
    }
  }
  current_.clear();
  r_prev_.clear();
  x_prev_.clear();
}

void Acceleration::restore(const std::vector<double>& state) {
  if (!state.empty()) throw std::runtime_error("this acceleration keeps no state across macro steps, but some was given");
}

// [steps, then per step: columns, size, then per column v..., w...]
std::vector<double> IqnIls::save() const {
  std::vector<double> out{static_cast<double>(past_.size())};
  for (const auto& step : past_) {
    out.push_back(static_cast<double>(step.size()));
    out.push_back(step.empty() ? 0.0 : static_cast<double>(step.front().v.size()));
    for (const auto& c : step) {
      out.insert(out.end(), c.v.begin(), c.v.end());
      out.insert(out.end(), c.w.begin(), c.w.end());
    }
  }
  return out;
}

void IqnIls::restore(const std::vector<double>& s) {
  std::size_t at = 0;
  auto count = [&]() {
    if (at >= s.size() || !(s[at] >= 0) || s[at] != std::floor(s[at]) || s[at] > 1e9)
      throw std::runtime_error("IQN-ILS state: a count is missing or not a count");
    return static_cast<std::size_t>(s[at++]);
  };
  std::deque<std::deque<Column>> past;
  const std::size_t steps = count();
  for (std::size_t k = 0; k < steps; ++k) {
    const std::size_t cols = count(), n = count();
    std::deque<Column> step;
    for (std::size_t j = 0; j < cols; ++j) {
      if (s.size() - at < 2 * n) throw std::runtime_error("IQN-ILS state: shorter than its counts say");
      Column c{std::vector<double>(s.begin() + static_cast<std::ptrdiff_t>(at), s.begin() + static_cast<std::ptrdiff_t>(at + n)),
               std::vector<double>(s.begin() + static_cast<std::ptrdiff_t>(at + n), s.begin() + static_cast<std::ptrdiff_t>(at + 2 * n))};
      at += 2 * n;
      step.push_back(std::move(c));
    }
    past.push_back(std::move(step));
  }
  if (at != s.size()) throw std::runtime_error("IQN-ILS state: longer than its counts say");
  past_ = std::move(past);
  current_.clear(), r_prev_.clear(), x_prev_.clear();
  pushed_ = false;
  dropped_.clear();
}

void IqnIls::forget_step() {
  if (pushed_) past_.pop_front();
  for (auto& d : dropped_) past_.push_back(std::move(d));
  pushed_ = false;
  dropped_.clear();
}

std::unique_ptr<Acceleration> make_acceleration(const AccelerationSpec& spec) {
  switch (spec.type) {
    case AccelerationType::None: return std::make_unique<ConstantRelaxation>(1.0);
    case AccelerationType::Constant: return std::make_unique<ConstantRelaxation>(spec.relaxation);
    case AccelerationType::Aitken: return std::make_unique<AitkenRelaxation>(spec.relaxation);
    case AccelerationType::IqnIls:
      return std::make_unique<IqnIls>(spec.relaxation, spec.reuse, spec.max_columns, spec.filter);
  }
  throw std::logic_error("unknown acceleration");
}

}  // namespace master
