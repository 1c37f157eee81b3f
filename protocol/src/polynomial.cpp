#include "cosim/polynomial_wire.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <stdexcept>

namespace cosim {

std::vector<double> to_tangent(SignalKind kind, const Value& v, const Quat& reference) {
  if (kind != SignalKind::Kinematics) return v;
  return Kinematics::from_value(v).to_tangent(reference);
}

Value from_tangent(SignalKind kind, const std::vector<double>& t, const Quat& reference) {
  if (kind != SignalKind::Kinematics) return t;
  return Kinematics::from_tangent(t, reference).to_value();
}

Value InputPolynomial::evaluate(double s) const {
  const int n = tangent_size(kind);
  std::vector<double> t(n, 0.0);
  // Horner's rule per component.
  for (int j = n_coefficients - 1; j >= 0; --j)
    for (int c = 0; c < n; ++c) t[c] = t[c] * s + coefficients[j * n + c];
  return from_tangent(kind, t, orientation_reference);
}

Value InputPolynomial::mean() const {
  if (kind == SignalKind::Kinematics)
    throw std::invalid_argument("the mean of a kinematics polynomial is not defined");
  const int n = tangent_size(kind);
  Value m(static_cast<std::size_t>(n), 0.0);
  for (int j = 0; j < n_coefficients; ++j)
    for (int c = 0; c < n; ++c) m[c] += coefficients[j * n + c] / (j + 1);
  return m;
}

InputPolynomial InputPolynomial::constant(SignalKind kind, const Value& value) {
  InputPolynomial p;
  p.kind = kind;
  if (kind == SignalKind::Kinematics)
    p.orientation_reference = quat_normalized(Kinematics::from_value(value).orientation);
  p.coefficients = to_tangent(kind, value, p.orientation_reference);
  return p;
}

InputPolynomial fit_polynomial(SignalKind kind, const std::vector<double>& s,
                               const std::vector<Value>& values, int order,
                               std::size_t reference_sample) {
  const int m = static_cast<int>(s.size());
  if (order < 0 || order > kMaxPolynomialOrder)
    throw std::invalid_argument("polynomial order must be 0.." +
                                std::to_string(kMaxPolynomialOrder));
  if (m < order + 1 || values.size() != s.size() || reference_sample >= s.size())
    throw std::invalid_argument("fit_polynomial: need at least order + 1 samples");
  InputPolynomial p;
  p.kind = kind;
  p.n_coefficients = order + 1;
  if (kind == SignalKind::Kinematics) {
    p.orientation_reference =
        quat_normalized(Kinematics::from_value(values[reference_sample]).orientation);
  }
  const int n = tangent_size(kind);
  Eigen::MatrixXd V(m, order + 1);
  Eigen::MatrixXd Y(m, n);
  for (int i = 0; i < m; ++i) {
    double power = 1.0;
    for (int j = 0; j <= order; ++j, power *= s[i]) V(i, j) = power;
    const auto t = to_tangent(kind, values[i], p.orientation_reference);
    for (int c = 0; c < n; ++c) Y(i, c) = t[c];
  }
  Eigen::MatrixXd C;
  if (m == order + 1) {
    Eigen::FullPivLU<Eigen::MatrixXd> lu(V);
    if (!lu.isInvertible()) throw std::invalid_argument("fit_polynomial: repeated sample times");
    C = lu.solve(Y);
  } else {
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(V);
    if (qr.rank() < order + 1) throw std::invalid_argument("fit_polynomial: repeated sample times");
    C = qr.solve(Y);
  }
  p.coefficients.resize(static_cast<std::size_t>((order + 1) * n));
  for (int j = 0; j <= order; ++j)
    for (int c = 0; c < n; ++c) p.coefficients[j * n + c] = C(j, c);
  return p;
}

InputPolynomial fit_polynomial_to_means(SignalKind kind,
                                        const std::vector<std::pair<double, double>>& intervals,
                                        const std::vector<Value>& means, int order) {
  const int m = static_cast<int>(intervals.size());
  if (kind == SignalKind::Kinematics)
    throw std::invalid_argument("fit_polynomial_to_means: kinematics have no plain interval mean");
  if (order < 0 || order > kMaxPolynomialOrder)
    throw std::invalid_argument("polynomial order must be 0.." +
                                std::to_string(kMaxPolynomialOrder));
  if (m < order + 1 || means.size() != intervals.size())
    throw std::invalid_argument("fit_polynomial_to_means: need at least order + 1 intervals");
  const int n = tangent_size(kind);
  // Row i: the means of 1, s, s^2, ... over [a_i, b_i], (b^(j+1) - a^(j+1)) / ((j+1) (b - a)).
  Eigen::MatrixXd V(m, order + 1);
  Eigen::MatrixXd Y(m, n);
  for (int i = 0; i < m; ++i) {
    const auto [a, b] = intervals[static_cast<std::size_t>(i)];
    if (!(b > a)) throw std::invalid_argument("fit_polynomial_to_means: empty interval");
    double pa = a, pb = b;
    for (int j = 0; j <= order; ++j, pa *= a, pb *= b) V(i, j) = (pb - pa) / ((j + 1) * (b - a));
    if (static_cast<int>(means[static_cast<std::size_t>(i)].size()) != n)
      throw std::invalid_argument("fit_polynomial_to_means: a mean has the wrong size");
    for (int c = 0; c < n; ++c) Y(i, c) = means[static_cast<std::size_t>(i)][c];
  }
  Eigen::MatrixXd C;
  if (m == order + 1) {
    Eigen::FullPivLU<Eigen::MatrixXd> lu(V);
    if (!lu.isInvertible()) throw std::invalid_argument("fit_polynomial_to_means: repeated intervals");
    C = lu.solve(Y);
  } else {
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(V);
    if (qr.rank() < order + 1) throw std::invalid_argument("fit_polynomial_to_means: repeated intervals");
    C = qr.solve(Y);
  }
  InputPolynomial p;
  p.kind = kind;
  p.n_coefficients = order + 1;
  p.coefficients.resize(static_cast<std::size_t>((order + 1) * n));
  for (int j = 0; j <= order; ++j)
    for (int c = 0; c < n; ++c) p.coefficients[j * n + c] = C(j, c);
  return p;
}

namespace {

std::vector<std::vector<double>> rows(const InputPolynomial& p, int offset) {
  const int n = tangent_size(p.kind);
  std::vector<std::vector<double>> out(p.n_coefficients, std::vector<double>(3));
  for (int j = 0; j < p.n_coefficients; ++j)
    for (int c = 0; c < 3; ++c) out[j][c] = p.coefficients[j * n + offset + c];
  return out;
}

void put_rows(InputPolynomial& p, int offset, const std::vector<std::vector<double>>& r,
              const std::string& what) {
  const int n = tangent_size(p.kind);
  if (static_cast<int>(r.size()) != p.n_coefficients)
    throw ProtocolError(what + ": coefficient rows do not match n_coefficients");
  for (int j = 0; j < p.n_coefficients; ++j) {
    if (r[j].size() != 3) throw ProtocolError(what + ": coefficient row is not 3 numbers");
    for (int c = 0; c < 3; ++c) p.coefficients[j * n + offset + c] = r[j][c];
  }
}

// Every coefficient-row field of a wire polynomial with its offset in tangent coordinates: the
// one map that to_message and from_message both use. K is the message type, const or not.
template <class K, class F>
void kinematics_rows(K& k, F&& f) {
  f(Kinematics::kTangentPosition, k.position);
  f(Kinematics::kTangentRotation, k.rotation_vector);
  f(Kinematics::kTangentVelocity, k.linear_velocity);
  f(Kinematics::kTangentAngularVelocity, k.angular_velocity);
}
template <class W, class F>
void wrench_rows(W& w, F&& f) {
  f(Wrench::kForce, w.force);
  f(Wrench::kTorque, w.torque);
  f(Wrench::kPoint, w.reference_point);
}

void check_order(int32_t n, const std::string& what) {
  if (n < 1 || n > kMaxPolynomialOrder + 1)
    throw ProtocolError(what + ": n_coefficients is " + std::to_string(n) + ", allowed 1.." +
                        std::to_string(kMaxPolynomialOrder + 1));
}

void check_finite(const InputPolynomial& p, const std::string& what) {
  for (double c : p.coefficients)
    if (!std::isfinite(c)) throw ProtocolError(what + ": a coefficient is NaN or infinite");
}

}  // namespace

polynomial_set_t to_message(const Polynomials& polynomials) {
  polynomial_set_t m{};
  for (const auto& entry : polynomials) {
    const std::string& name = entry.first;
    const InputPolynomial& p = entry.second;  // a plain reference: lambdas below capture it
    switch (p.kind) {
      case SignalKind::Scalar:
        m.scalars.push_back({name, p.n_coefficients, p.coefficients});
        break;
      case SignalKind::Kinematics: {
        kinematics_polynomial_t k{};
        k.name = name;
        for (int i = 0; i < 4; ++i) k.orientation_reference[i] = p.orientation_reference[i];
        k.n_coefficients = p.n_coefficients;
        kinematics_rows(k, [&](int offset, auto& r) { r = rows(p, offset); });
        m.kinematics.push_back(k);
        break;
      }
      case SignalKind::Wrench: {
        wrench_polynomial_t w{};
        w.name = name;
        w.n_coefficients = p.n_coefficients;
        wrench_rows(w, [&](int offset, auto& r) { r = rows(p, offset); });
        m.wrenches.push_back(w);
        break;
      }
    }
  }
  set_counts(m);
  return m;
}

Polynomials from_message(const polynomial_set_t& m, const std::string& what) {
  Polynomials out;
  auto start = [&](const std::string& name, SignalKind kind, int32_t n) -> InputPolynomial& {
    const std::string where = what + " input '" + name + "'";
    require_valid_name(name, where);
    if (out.count(name)) throw ProtocolError(where + ": appears twice");
    check_order(n, where);
    InputPolynomial& p = out[name];
    p.kind = kind;
    p.n_coefficients = n;
    p.coefficients.assign(static_cast<std::size_t>(n * tangent_size(kind)), 0.0);
    return p;
  };
  for (const auto& s : m.scalars) {
    auto& p = start(s.name, SignalKind::Scalar, s.n_coefficients);
    p.coefficients = s.coefficients;
    check_finite(p, what + " input '" + s.name + "'");
  }
  for (const auto& k : m.kinematics) {
    const std::string where = what + " input '" + k.name + "'";
    auto& p = start(k.name, SignalKind::Kinematics, k.n_coefficients);
    kinematics_rows(k, [&](int offset, const auto& r) { put_rows(p, offset, r, where); });
    check_finite(p, where);
    const Quat q{k.orientation_reference[0], k.orientation_reference[1],
                 k.orientation_reference[2], k.orientation_reference[3]};
    const double n = quat_norm(q);
    if (!std::isfinite(n) || std::abs(n - 1.0) > 1e-6)
      throw ProtocolError(where + ": orientation_reference is not a unit quaternion (norm " +
                          std::to_string(n) + "); normalize it before sending");
    p.orientation_reference = q;
  }
  for (const auto& w : m.wrenches) {
    const std::string where = what + " input '" + w.name + "'";
    auto& p = start(w.name, SignalKind::Wrench, w.n_coefficients);
    wrench_rows(w, [&](int offset, const auto& r) { put_rows(p, offset, r, where); });
    check_finite(p, where);
  }
  return out;
}

}  // namespace cosim
