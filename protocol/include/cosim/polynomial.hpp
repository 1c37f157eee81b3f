// Input polynomials over a macro step: how a predicted signal crosses the bus, and how the
// master builds it from past samples (extrapolation, interpolation or least squares).
// Coefficient j multiplies s^j, s = (t - t_start) / (t_end - t_start).
// Orientation lives on the rotation group: q(s) = q_ref * exp(r(s)) with r a polynomial in the
// body-fixed rotation vector relative to q_ref; the other components are polynomials as they are.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cosim/rotation.hpp"
#include "cosim/signal.hpp"

namespace cosim {

constexpr int kMaxPolynomialOrder = 3;

struct InputPolynomial {
  SignalKind kind = SignalKind::Scalar;
  int n_coefficients = 1;
  // n_coefficients rows of tangent_size(kind) numbers, row-major.
  std::vector<double> coefficients;
  Quat orientation_reference{1, 0, 0, 0};

  int order() const { return n_coefficients - 1; }
  Value evaluate(double s) const;
  // The mean over the step, s in [0, 1]: sum_j c_j / (j + 1) per component. Not for kinematics
  // (the mean of a pose is not a pose): raises std::invalid_argument.
  Value mean() const;
  // A constant polynomial that returns `value`.
  static InputPolynomial constant(SignalKind kind, const Value& value);
};
using Polynomials = std::map<std::string, InputPolynomial>;

// Maps a value to the tangent coordinates used by the polynomial (orientation as the rotation
// vector relative to reference), and back.
std::vector<double> to_tangent(SignalKind kind, const Value& value, const Quat& reference);
Value from_tangent(SignalKind kind, const std::vector<double>& tangent, const Quat& reference);

// Fits a polynomial of `order` through samples (s_i, values_i). With order + 1 samples it
// interpolates; with more it is the least-squares fit. The orientation reference is the
// orientation of `reference_sample`. Raises std::invalid_argument for too few samples or
// repeated s.
InputPolynomial fit_polynomial(SignalKind kind, const std::vector<double>& s,
                               const std::vector<Value>& values, int order,
                               std::size_t reference_sample);

// Histopolation: the polynomial of `order` whose means over the intervals [a_i, b_i] (in s) equal
// means_i. With order + 1 intervals it is exact; with more it is the least-squares fit of the
// means. Scalars and wrenches only (raises std::invalid_argument for kinematics, too few
// intervals, empty or repeated intervals).
InputPolynomial fit_polynomial_to_means(SignalKind kind,
                                        const std::vector<std::pair<double, double>>& intervals,
                                        const std::vector<Value>& means, int order);

}  // namespace cosim
