// Acceleration of an implicit coupling's fixed-point iteration (docs/coupling.md). Within a
// macro step, iteration k gave the coupling values x_in (what was in place at its start) and
// x = H(x_in) (what the sources answered); next() returns the values in place for iteration
// k + 1. Plain iteration takes x; the others mix x_in and x. All act on one flat vector (the
// fed-back connections' end values in config order), scaled per entry by set_weights.
#pragma once

#include <deque>
#include <memory>
#include <vector>

#include "config.hpp"

namespace master {

class Acceleration {
 public:
  virtual ~Acceleration() = default;
  // A new macro step; weights scale each entry in the least-squares problems (IQN-ILS).
  virtual void start_step(const std::vector<double>& weights) { weights_ = weights; }
  virtual std::vector<double> next(const std::vector<double>& x_in, const std::vector<double>& x, int iteration) = 0;
  // The macro step was accepted.
  virtual void end_step() {}
  // The macro step end_step closed last was rejected after all (an adaptive step redoes it
  // shorter): the state is put back to before it.
  virtual void forget_step() {}
  // Columns the last next() used (IQN-ILS; 0 otherwise), after the QR filter.
  virtual int columns_used() const { return 0; }
  // What carries over from one macro step to the next (IQN-ILS: the reused columns), as numbers
  // (for a checkpoint); restore takes them back and raises std::runtime_error for a bad list.
  virtual std::vector<double> save() const { return {}; }
  virtual void restore(const std::vector<double>& state);

 protected:
  std::vector<double> weights_;
};

// x_in + omega (x - x_in); omega = 1 (AccelerationType::None) is plain iteration.
class ConstantRelaxation final : public Acceleration {
 public:
  explicit ConstantRelaxation(double omega) : omega_(omega) {}
  std::vector<double> next(const std::vector<double>& x_in, const std::vector<double>& x, int iteration) override;

 private:
  double omega_;
};

// Aitken's dynamic relaxation (Irons & Tuck): omega_k = -omega_{k-1} r_{k-1}.(r_k - r_{k-1}) /
// |r_k - r_{k-1}|^2, with r = x - x_in; the first iteration of every macro step uses `initial`.
class AitkenRelaxation final : public Acceleration {
 public:
  explicit AitkenRelaxation(double initial) : initial_(initial) {}
  std::vector<double> next(const std::vector<double>& x_in, const std::vector<double>& x, int iteration) override;
  double omega() const { return omega_; }

 private:
  double initial_, omega_ = 0;
  std::vector<double> r_prev_;
};

// Interface quasi-Newton, inverse least squares (IQN-ILS, Degroote et al. 2009): the columns
// V = [dr ...] (differences of residuals of successive iterations) and W = [dx ...] (of outputs),
// newest first, including those of up to `reuse` past macro steps; alpha = argmin |V alpha + r|,
// x_next = x + W alpha. A QR decomposition of V by modified Gram-Schmidt drops a column whose part
// orthogonal to the newer ones is below filter x its norm (preCICE's QR2 filter). Without any
// column (a run's first iteration): x_in + initial (x - x_in).
class IqnIls final : public Acceleration {
 public:
  IqnIls(double initial, int reuse, int max_columns, double filter)
      : initial_(initial), reuse_(reuse), max_columns_(max_columns), filter_(filter) {}
  std::vector<double> next(const std::vector<double>& x_in, const std::vector<double>& x, int iteration) override;
  void end_step() override;
  void forget_step() override;
  int columns_used() const override { return used_; }
  std::vector<double> save() const override;
  void restore(const std::vector<double>& state) override;

 private:
  struct Column { std::vector<double> v, w; };
  double initial_;
  int reuse_, max_columns_;
  double filter_;
  std::deque<Column> current_;               // this macro step's, newest first
  std::deque<std::deque<Column>> past_;      // earlier macro steps', newest first
  std::vector<double> r_prev_, x_prev_;
  int used_ = 0;
  // What the last end_step changed in past_ (for forget_step).
  bool pushed_ = false;
  std::deque<std::deque<Column>> dropped_;
};

std::unique_ptr<Acceleration> make_acceleration(const AccelerationSpec& spec);

}  // namespace master
