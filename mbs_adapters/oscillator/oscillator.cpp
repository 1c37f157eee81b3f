#include "oscillator.hpp"

#include <unsupported/Eigen/MatrixFunctions>

namespace oscillator {
namespace {
constexpr int kMaxCoefficients = 4;

Eigen::Matrix2d own_matrix(Side side, const Parameters& p) {
  Eigen::Matrix2d A;
  if (side == Side::Mass1)
    A << 0, 1, -p.c1 / p.m1, -p.d1 / p.m1;
  else
    A << 0, 1, -(p.c2 + p.cc) / p.m2, -(p.d2 + p.dc) / p.m2;
  return A;
}

Eigen::MatrixXd input_matrix(Side side, const Parameters& p) {
  if (side == Side::Mass1) {
    Eigen::MatrixXd B(2, 1);
    B << 0, 1 / p.m1;
    return B;
  }
  Eigen::MatrixXd B(2, 2);
  B << 0, 0, p.cc / p.m2, p.dc / p.m2;
  return B;
}
}  // namespace

Half::Half(Side side, const Parameters& p, double inner_step) : side_(side), p_(p), h_(inner_step) {
  x_ = side == Side::Mass1 ? Eigen::Vector2d(p.x1, p.v1) : Eigen::Vector2d(p.x2, p.v2);
  // Augmented state z = [x; w_0..w_3] with u(tau + sigma h) = sum_j w_j sigma^j: the Taylor
  // coefficients in units of h shift as w_j' = (j + 1) w_{j+1} / h, so one constant matrix
  // propagates state and input together, exactly.
  const int m = input_size();
  const int n = 2 + kMaxCoefficients * m;
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n);
  M.block<2, 2>(0, 0) = own_matrix(side, p);
  M.block(0, 2, 2, m) = input_matrix(side, p);
  for (int j = 0; j + 1 < kMaxCoefficients; ++j)
    M.block(2 + j * m, 2 + (j + 1) * m, m, m) =
        Eigen::MatrixXd::Identity(m, m) * (static_cast<double>(j + 1) / h_);
  step_ = (M * h_).exp();
  // Integrator states I' = z appended: exp([[M, 0], [1, 0]] h) has the integral of exp(M tau)
  // over [0, h] in its lower left block, which takes z at an inner step's start to z's integral
  // over that inner step.
  Eigen::MatrixXd Mi = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  Mi.topLeftCorner(n, n) = M;
  Mi.bottomLeftCorner(n, n) = Eigen::MatrixXd::Identity(n, n);
  mean_step_ = (Mi * h_).exp().bottomLeftCorner(n, n);
}

namespace {
// The augmented state at a step's start: a_j multiplies s^j with s = tau / H = sigma / n_inner,
// so w_j = a_j / n_inner^j.
Eigen::VectorXd augmented(const Eigen::Vector2d& x, const std::vector<Eigen::VectorXd>& a, int m,
                          int n_inner) {
  Eigen::VectorXd z = Eigen::VectorXd::Zero(2 + kMaxCoefficients * m);
  z.head<2>() = x;
  double scale = 1.0;
  for (std::size_t j = 0; j < a.size(); ++j, scale /= n_inner) z.segment(2 + j * m, m) = a[j] * scale;
  return z;
}
}  // namespace

void Half::advance(const std::vector<Eigen::VectorXd>& a, int n_inner) {
  Eigen::VectorXd z = augmented(x_, a, input_size(), n_inner);
  for (int k = 0; k < n_inner; ++k) z = step_ * z;
  x_ = z.head<2>();
}

Eigen::VectorXd Half::advance_with_average(const std::vector<Eigen::VectorXd>& a, int n_inner) {
  const int m = input_size();
  Eigen::VectorXd z = augmented(x_, a, m, n_inner);
  Eigen::VectorXd integral = Eigen::VectorXd::Zero(z.size());
  for (int k = 0; k < n_inner; ++k) {
    integral += mean_step_ * z;
    z = step_ * z;
  }
  x_ = z.head<2>();
  const Eigen::VectorXd mean = integral / (n_inner * h_);  // w_0 is the input's current value
  return output_of(mean.head<2>(), mean.segment(2, m));
}

Eigen::VectorXd Half::output_of(const Eigen::Vector2d& x, const Eigen::VectorXd& u) const {
  if (side_ == Side::Mass1) return x;
  Eigen::VectorXd f(1);
  f(0) = -(p_.cc * (u(0) - x(0)) + p_.dc * (u(1) - x(1)));
  return f;
}

Eigen::Matrix4d monolithic_matrix(const Parameters& p) {
  Eigen::Matrix4d A;
  A << 0, 1, 0, 0,
      -(p.c1 + p.cc) / p.m1, -(p.d1 + p.dc) / p.m1, p.cc / p.m1, p.dc / p.m1,
      0, 0, 0, 1,
      p.cc / p.m2, p.dc / p.m2, -(p.c2 + p.cc) / p.m2, -(p.d2 + p.dc) / p.m2;
  return A;
}

Eigen::Vector4d monolithic_solution(const Parameters& p, double t) {
  const Eigen::Matrix4d E = (monolithic_matrix(p) * t).exp();
  return E * Eigen::Vector4d(p.x1, p.v1, p.x2, p.v2);
}

}  // namespace oscillator
