// The dual-mass oscillator with force-displacement coupling, split in two halves (the
// analytic test bed for co-simulation schemes). The model knows nothing of the bus.
//   mass1: m1 x1'' = -c1 x1 - d1 x1' + F           input F, outputs x1, v1
//   mass2: m2 x2'' = -c2 x2 - d2 x2' + Fc          inputs x1, v1, output F = -Fc
//          Fc = cc (x1 - x2) + dc (v1 - v2)        (coupling spring-damper inside mass2)
// Each half is integrated exactly for a polynomial input (augmented matrix exponential), so
// every error measured against the monolithic solution is the coupling's.
#pragma once

#include <Eigen/Dense>
#include <vector>

namespace oscillator {

struct Parameters {
  double m1 = 1, c1 = 10, d1 = 0.2;
  double m2 = 1, c2 = 10, d2 = 0.2;
  double cc = 1000, dc = 2;
  double x1 = 0.1, v1 = 0, x2 = 0, v2 = 0;  // initial state
};

enum class Side { Mass1, Mass2 };

// One half: state (x, v); inputs u (mass1: [F], mass2: [x1, v1]) given per step as a
// polynomial u(s) = sum_j a_j s^j in s = (t - t_start)/H, up to degree 3.
class Half {
 public:
  Half(Side side, const Parameters& p, double inner_step);
  int input_size() const { return side_ == Side::Mass1 ? 1 : 2; }
  // Advances n inner steps across one macro step H = n * inner_step. coefficients[j] is a_j.
  void advance(const std::vector<Eigen::VectorXd>& coefficients, int n_inner);
  // Like advance, also returning the exact mean of the output over the step: output() is linear
  // in the state and the input, so its mean is output_of(mean state, mean input), and those
  // means are the integral of the augmented state (exact, see mean_step_).
  Eigen::VectorXd advance_with_average(const std::vector<Eigen::VectorXd>& coefficients,
                                       int n_inner);
  // mass1: [x1, v1]; mass2: [F] for the input value u_end at the end of the step.
  Eigen::VectorXd output(const Eigen::VectorXd& u_end) const { return output_of(x_, u_end); }
  const Eigen::Vector2d& state() const { return x_; }
  void set_state(const Eigen::Vector2d& x) { x_ = x; }

 private:
  Eigen::VectorXd output_of(const Eigen::Vector2d& x, const Eigen::VectorXd& u) const;

  Side side_;
  Parameters p_;
  double h_;
  Eigen::Vector2d x_;
  Eigen::MatrixXd step_;       // exp(M h) of the augmented system
  Eigen::MatrixXd mean_step_;  // integral of exp(M tau) over [0, h]: z's integral over an inner step
};

// The monolithic system matrix for (x1, v1, x2, v2) and its exact solution at time t.
Eigen::Matrix4d monolithic_matrix(const Parameters& p);
Eigen::Vector4d monolithic_solution(const Parameters& p, double t);

}  // namespace oscillator
