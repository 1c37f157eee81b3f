// Linear stability of a co-simulation scheme on the dual-mass oscillator: the one-macro-step map
// Phi(H) of the coupled scheme (both halves integrated exactly for their polynomial inputs), its
// spectral radius rho(H), and the critical macro step where rho first rises above 1.
//
// The definitions mirror the co-simulation master (master/src/predictor.cpp): inputs are
// polynomials in s = (t - t_n)/H fitted to the latest samples of the source output, Jacobi
// extrapolates from samples at t_n, t_{n-1}, ..., Gauss-Seidel (mass1 first) lets mass2
// interpolate through mass1's new sample at t_{n+1}. The force connection can carry end samples
// (`use: end`) or interval averages (`use: average`, fitted by histopolation). See
// docs/stability.md.
#pragma once

#include <Eigen/Dense>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cosim::stability {

// Our own copy of the benchmark's parameters (SI units), so this library stays independent of
// the oscillator adapter. Defaults are the benchmark's.
struct OscParams {
  double m1 = 1.0, c1 = 10.0, d1 = 0.2;  // mass1: mass, spring to ground, damper to ground
  double m2 = 1.0, c2 = 10.0, d2 = 0.2;  // mass2: same
  double cc = 1000.0, dc = 2.0;          // coupling spring and damper between the masses
};

// Sets one parameter by its name (m1, c1, d1, m2, c2, d2, cc, dc). Throws std::invalid_argument
// naming the allowed keys for an unknown key.
void set_param(OscParams& p, std::string_view key, double value);
// Throws std::invalid_argument when a mass is not > 0 or a stiffness/damping is negative or any
// value is not finite.
void validate(const OscParams& p);

enum class Scheme { Jacobi, GaussSeidel };
std::string_view scheme_name(Scheme s);  // "jacobi", "gauss_seidel"
std::optional<Scheme> parse_scheme(std::string_view name);

// What the force connection (mass2.force -> mass1.force) hands over, as the master's
// `connections[].use`: End = the force at each macro time point, fitted by inter/extrapolation;
// Average = the exact mean of mass2's coupling force over each macro step, fitted by
// histopolation (the polynomial whose means over the latest intervals equal the received means).
enum class ForceUse { End, Average };
std::string_view force_use_name(ForceUse u);  // "end", "average"
std::optional<ForceUse> parse_force_use(std::string_view name);

// Predictor orders and sample counts. mq/mf = 0 means "k + 1" (exact inter/extrapolation).
struct Predictors {
  int kq = 0, kf = 0;  // polynomial order of the kinematic inputs (x1, v1 -> mass2) and the force
  int mq = 0, mf = 0;  // number of samples fitted; more than k + 1 gives a least-squares fit
  ForceUse force = ForceUse::End;  // force samples: end values or interval averages
  // Iterations per macro step (the master's coupling.type: implicit without acceleration):
  // 1 = explicit; k > 1 = k iterations, each after the first fitting the inputs through the
  // previous iteration's end values (force: s = 1, 0, -1, ...; Jacobi's kinematics too);
  // 0 = iterated to convergence (the fixed point of the end values). ForceUse::End only.
  int iterations = 1;
  int samples_q() const { return mq > 0 ? mq : kq + 1; }
  int samples_f() const { return mf > 0 ? mf : kf + 1; }
};
// Orders 0..3 (the protocol's maximum) and at least k + 1 samples, at most 16.
void validate(const Predictors& pr);

// Where each quantity sits in the extended state z:
//   z = (x1, v1, x2, v2, x1 history, v1 history, F history)
// x1/v1 history: the past samples x1(t_{n-1}), x1(t_{n-2}), ... still needed by the predictor
// (Jacobi: m_q - 1 of them; Gauss-Seidel: m_q - 2, because its newest sample is t_{n+1}).
// F history: F_n, F_{n-1}, ... (m_f values). F_n is a state of its own: mass2 computed it from its
// *predicted* kinematics, so it is not a function of (x1, v1, x2, v2). With ForceUse::Average the
// entries are the interval means Fbar_n (over [t_{n-1}, t_n]), Fbar_{n-1}, ... instead.
struct Layout {
  int hq = 0;  // entries in each of the x1 and v1 histories
  int hf = 0;  // entries in the F history
  int x1_hist() const { return 4; }
  int v1_hist() const { return 4 + hq; }
  int f_hist() const { return 4 + 2 * hq; }
  int size() const { return 4 + 2 * hq + hf; }
};
Layout layout(Scheme scheme, const Predictors& pr);

// The one-macro-step map z_{n+1} = phi * z_n and, computed without cancellation, phi - I (the
// physical block of phi is I + O(H), so subtracting I from phi would lose digits at small H).
struct StepMap {
  Layout layout;
  Eigen::MatrixXd phi;
  Eigen::MatrixXd phi_minus_identity;
};
StepMap step_map(const OscParams& p, Scheme scheme, const Predictors& pr, double H);

// The extended state at t = 0 for a physical state x0 = (x1, v1, x2, v2) when every past sample
// equals the initial output (x1 and v1 histories = x1(0), v1(0); F history = the coupling force
// -(cc (x1 - x2) + dc (v1 - v2)) at t = 0; for ForceUse::Average the same value stands for every
// past interval mean, as the master's constant start).
Eigen::VectorXd initial_extended_state(const OscParams& p, Scheme scheme, const Predictors& pr,
                                       const Eigen::Vector4d& x0);

// rho(H) = max |eig(phi)| and rho(H) - 1. Computed from the eigenvalues mu = lambda - 1 of the
// balanced phi - I, so rho - 1 keeps its digits when it is tiny: against a long-double evaluation
// the absolute error is ~1e-17 for H <= 1e-2 (a plain eig(phi) is off by ~1e-13).
// mq/mf = 0 means k + 1 samples. Throws std::invalid_argument for invalid parameters/orders/H.
double spectral_radius(const OscParams& p, Scheme scheme, int kq, int kf, int mq, int mf, double H);
double spectral_radius_minus_one(const OscParams& p, Scheme scheme, int kq, int kf, int mq, int mf,
                                 double H);
// The same for any Predictors (force end samples or interval averages).
double spectral_radius(const OscParams& p, Scheme scheme, const Predictors& pr, double H);
double spectral_radius_minus_one(const OscParams& p, Scheme scheme, const Predictors& pr,
                                 double H);

// The monolithic 4x4 system x' = A x on x = (x1, v1, x2, v2), and the slowest decay rate
// alpha = -max Re eig(A) (the exact rho(H) -> exp(-alpha H) as H -> 0).
Eigen::Matrix4d monolithic_matrix(const OscParams& p);
double slowest_decay_rate(const OscParams& p);

// Where rho(H) - 1 changes sign on [h_min, h_max]: a log grid of `points` values, each sign change
// bisected (in log H) to a relative width `rel_tol`.
struct ScanOptions {
  double h_min = 1e-6, h_max = 1e-1;
  int points = 400;
  double rel_tol = 1e-6;
};
struct Crossing {
  double H;
  bool becomes_unstable;  // true: rho rises through 1 as H grows; false: falls back below 1
};
struct StabilityScan {
  bool unstable_at_h_min = false;   // rho >= 1 already at h_min (not expected: rho -> 1- as H -> 0)
  std::vector<Crossing> crossings;  // in increasing H
  // The first crossing from below (the critical macro step); empty when stable on the whole range
  // or already unstable at h_min.
  std::optional<double> critical() const;
};
StabilityScan scan_stability(const OscParams& p, Scheme scheme, int kq, int kf, int mq, int mf,
                             const ScanOptions& opt = {});
StabilityScan scan_stability(const OscParams& p, Scheme scheme, const Predictors& pr,
                             const ScanOptions& opt = {});
// Shortcut: scan_stability(...).critical(). Empty means "no crossing from below": stable on the
// whole range, or (check scan_stability's unstable_at_h_min) already unstable at h_min.
std::optional<double> critical_macro_step(const OscParams& p, Scheme scheme, int kq, int kf,
                                          int mq = 0, int mf = 0, const ScanOptions& opt = {});
std::optional<double> critical_macro_step(const OscParams& p, Scheme scheme, const Predictors& pr,
                                          const ScanOptions& opt = {});

}  // namespace cosim::stability
