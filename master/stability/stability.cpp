#include "stability.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <unsupported/Eigen/MatrixFunctions>

namespace cosim::stability {

namespace {

// The largest predictor order the protocol carries (cosim::kMaxPolynomialOrder); kept as a copy
// so this library does not depend on the protocol target.
constexpr int kMaxOrder = 3;
// A least-squares predictor with more samples than this is not a sensible configuration.
constexpr int kMaxSamples = 16;

// Exact propagation of one half  y' = A y + B u(t)  over a macro step H, where every input is a
// polynomial u_i(t_n + sigma H) = sum_j w_ij sigma^j on sigma in [0, 1]:
//   y(t_n + H) = E y(t_n) + G w,   w = (w_0j for input 0, then input 1, ...).
// The coefficients of the polynomial re-expanded about the current time are states with
// d/dsigma w_j = (j + 1) w_{j+1}, and u = w_0, so one matrix exponential of the augmented system
// (in sigma, i.e. time scaled by H) gives E and G exactly. E - I is taken from phi1(HA), where
// exp(X) - I = X phi1(X) and exp([[X, I], [0, 0]]) = [[exp(X), phi1(X)], [0, I]]: no cancellation
// against the identity even when H A is tiny.
struct HalfPropagator {
  Eigen::Matrix2d e_minus_identity;
  Eigen::MatrixXd g;  // 2 x (inputs * (k + 1))
};

HalfPropagator propagate(const Eigen::Matrix2d& A, const Eigen::MatrixXd& B, int k, double H) {
  const int inputs = static_cast<int>(B.cols());
  const int nc = k + 1;
  const int n = 2 + inputs * nc;
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n);
  M.topLeftCorner<2, 2>() = H * A;
  for (int i = 0; i < inputs; ++i) {
    const int c = 2 + i * nc;
    M.block(0, c, 2, 1) = H * B.col(i);
    for (int j = 0; j < k; ++j) M(c + j, c + j + 1) = j + 1;
  }
  const Eigen::MatrixXd expM = M.exp();

  Eigen::Matrix4d X = Eigen::Matrix4d::Zero();
  X.topLeftCorner<2, 2>() = H * A;
  X.topRightCorner<2, 2>() = Eigen::Matrix2d::Identity();
  const Eigen::Matrix4d expX = X.exp();

  HalfPropagator out;
  out.e_minus_identity = (H * A) * expX.topRightCorner<2, 2>();
  out.g = expM.topRightCorner(2, n - 2);
  return out;
}

// The means over one macro step of a half's state, for the same inputs:
//   mean of y over [t_n, t_n + H] = Em y(t_n) + Gm w.
// Two integrator states I' = y (in sigma, so I(1) is the mean) appended to the augmented system
// of propagate(); one matrix exponential gives Em and Gm exactly. Only the ForceUse::Average map
// needs them (mass2's interval-mean coupling force).
struct HalfMean {
  Eigen::Matrix2d e;
  Eigen::MatrixXd g;  // 2 x (inputs * (k + 1))
};

HalfMean interval_mean(const Eigen::Matrix2d& A, const Eigen::MatrixXd& B, int k, double H) {
  const int inputs = static_cast<int>(B.cols());
  const int nc = k + 1;
  const int n = 2 + inputs * nc;
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + 2, n + 2);
  M.topLeftCorner<2, 2>() = H * A;
  for (int i = 0; i < inputs; ++i) {
    const int c = 2 + i * nc;
    M.block(0, c, 2, 1) = H * B.col(i);
    for (int j = 0; j < k; ++j) M(c + j, c + j + 1) = j + 1;
  }
  M.block<2, 2>(n, 0) = Eigen::Matrix2d::Identity();  // d/dsigma (integral of y) = y
  const Eigen::MatrixXd expM = M.exp();
  HalfMean out;
  out.e = expM.block<2, 2>(n, 0);
  out.g = expM.block(n, 2, 2, n - 2);
  return out;
}

// The (k+1) x m matrix P taking m sample values at abscissae s (in units of H from t_n) to the
// polynomial coefficients: exact interpolation for m = k + 1, least squares for m > k + 1 —
// the same fit as cosim::fit_polynomial, which the master's predictor calls.
Eigen::MatrixXd fit_matrix(const std::vector<double>& s, int k) {
  const int m = static_cast<int>(s.size());
  Eigen::MatrixXd V(m, k + 1);
  for (int i = 0; i < m; ++i) {
    double power = 1.0;
    for (int j = 0; j <= k; ++j, power *= s[i]) V(i, j) = power;
  }
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(m, m);
  if (m == k + 1) return Eigen::FullPivLU<Eigen::MatrixXd>(V).solve(I);
  return Eigen::ColPivHouseholderQR<Eigen::MatrixXd>(V).solve(I);
}

// The (k+1) x m histopolation matrix: from the means of p over m intervals [a_i, b_i] (in units
// of H from t_n) to the coefficients of p, the polynomial of order k whose interval means equal
// the given ones (exactly for m = k + 1, least squares for more) — the same fit as
// cosim::fit_polynomial_to_means, which the master's predictor calls for `use: average`.
Eigen::MatrixXd histopolation_matrix(const std::vector<std::pair<double, double>>& intervals, int k) {
  const int m = static_cast<int>(intervals.size());
  Eigen::MatrixXd V(m, k + 1);
  for (int i = 0; i < m; ++i) {
    const auto [a, b] = intervals[static_cast<std::size_t>(i)];
    double pa = a, pb = b;  // a^(j+1), b^(j+1)
    for (int j = 0; j <= k; ++j, pa *= a, pb *= b) V(i, j) = (pb - pa) / ((j + 1) * (b - a));
  }
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(m, m);
  if (m == k + 1) return Eigen::FullPivLU<Eigen::MatrixXd>(V).solve(I);
  return Eigen::ColPivHouseholderQR<Eigen::MatrixXd>(V).solve(I);
}

// The m latest macro-step intervals, newest first, the newest ending at `newest_end` (0: the
// step [t_{n-1}, t_n]).
std::vector<std::pair<double, double>> intervals(int m, double newest_end) {
  std::vector<std::pair<double, double>> out;
  for (int i = 0; i < m; ++i) out.emplace_back(newest_end - i - 1, newest_end - i);
  return out;
}

// Abscissae of the m latest samples, newest first, starting at `newest` (0: t_n, 1: t_{n+1}).
std::vector<double> abscissae(int m, double newest) {
  std::vector<double> s(static_cast<std::size_t>(m));
  for (int i = 0; i < m; ++i) s[static_cast<std::size_t>(i)] = newest - i;
  return s;
}

std::string number(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

void check_step(double H) {
  if (!(H > 0.0) || !std::isfinite(H))
    throw std::invalid_argument("macro step H must be a finite number > 0, got " + number(H));
}

// |lambda| - 1 for lambda = 1 + mu, written so that a tiny mu keeps its digits.
double modulus_minus_one(std::complex<double> mu) {
  const double a = std::abs(1.0 + mu);
  return (2.0 * mu.real() + std::norm(mu)) / (a + 1.0);
}

// Diagonal similarity D^-1 M D with powers of two (exact in floating point) that evens out row
// and column norms. The force history is in newtons (entries of order cc) while the kinematics are
// in metres; balancing first keeps the eigenvalue error near eps * (balanced norm) instead of
// eps * cc. Classic Parlett-Reinsch iteration.
void balance(Eigen::MatrixXd& M) {
  const Eigen::Index n = M.rows();
  for (bool converged = false; !converged;) {
    converged = true;
    for (Eigen::Index i = 0; i < n; ++i) {
      double c = M.col(i).cwiseAbs().sum() - std::abs(M(i, i));
      double r = M.row(i).cwiseAbs().sum() - std::abs(M(i, i));
      if (c == 0.0 || r == 0.0) continue;
      const double before = c + r;
      double f = 1.0;
      while (c < r / 2.0) {
        c *= 2.0;
        r /= 2.0;
        f *= 2.0;
      }
      while (c >= r * 2.0) {
        c /= 2.0;
        r *= 2.0;
        f /= 2.0;
      }
      if (c + r < 0.95 * before) {
        converged = false;
        M.col(i) *= f;
        M.row(i) /= f;
      }
    }
  }
}

}  // namespace

void set_param(OscParams& p, std::string_view key, double value) {
  if (key == "m1")
    p.m1 = value;
  else if (key == "c1")
    p.c1 = value;
  else if (key == "d1")
    p.d1 = value;
  else if (key == "m2")
    p.m2 = value;
  else if (key == "c2")
    p.c2 = value;
  else if (key == "d2")
    p.d2 = value;
  else if (key == "cc")
    p.cc = value;
  else if (key == "dc")
    p.dc = value;
  else
    throw std::invalid_argument("unknown oscillator parameter '" + std::string(key) +
                                "'; allowed: m1, c1, d1, m2, c2, d2, cc, dc");
}

void validate(const OscParams& p) {
  const std::pair<const char*, double> all[] = {{"m1", p.m1}, {"c1", p.c1}, {"d1", p.d1},
                                                {"m2", p.m2}, {"c2", p.c2}, {"d2", p.d2},
                                                {"cc", p.cc}, {"dc", p.dc}};
  for (const auto& [name, v] : all) {
    if (!std::isfinite(v))
      throw std::invalid_argument(std::string("oscillator parameter ") + name + " is not finite");
    if (v < 0.0)
      throw std::invalid_argument(std::string("oscillator parameter ") + name +
                                  " must be >= 0, got " + number(v));
  }
  if (p.m1 <= 0.0 || p.m2 <= 0.0)
    throw std::invalid_argument("oscillator masses m1 and m2 must be > 0");
}

std::string_view force_use_name(ForceUse u) { return u == ForceUse::End ? "end" : "average"; }

std::optional<ForceUse> parse_force_use(std::string_view name) {
  if (name == "end") return ForceUse::End;
  if (name == "average") return ForceUse::Average;
  return std::nullopt;
}

std::string_view scheme_name(Scheme s) { return s == Scheme::Jacobi ? "jacobi" : "gauss_seidel"; }

std::optional<Scheme> parse_scheme(std::string_view name) {
  if (name == "jacobi") return Scheme::Jacobi;
  if (name == "gauss_seidel") return Scheme::GaussSeidel;
  return std::nullopt;
}

void validate(const Predictors& pr) {
  if (pr.iterations < 0 || pr.iterations > 1000)
    throw std::invalid_argument("iterations: " + std::to_string(pr.iterations) +
                                " is not allowed (allowed: 0 = converged, 1 = explicit, 2 to 1000)");
  if (pr.iterations != 1 && pr.force == ForceUse::Average)
    throw std::invalid_argument("the implicit scheme (iterations != 1) is modelled for force end samples only (use-force end)");
  const auto order = [](const char* what, int k) {
    if (k < 0 || k > kMaxOrder)
      throw std::invalid_argument(std::string(what) + " must be 0.." + std::to_string(kMaxOrder) +
                                  ", got " + std::to_string(k));
  };
  order("kinematic predictor order kq", pr.kq);
  order("force predictor order kf", pr.kf);
  const auto samples = [](const char* what, int m, int k) {
    if (m < k + 1 || m > kMaxSamples)
      throw std::invalid_argument(std::string(what) + " must be " + std::to_string(k + 1) + ".." +
                                  std::to_string(kMaxSamples) + " (at least order + 1), got " +
                                  std::to_string(m));
  };
  samples("kinematic sample count mq", pr.samples_q(), pr.kq);
  samples("force sample count mf", pr.samples_f(), pr.kf);
}

Layout layout(Scheme scheme, const Predictors& pr) {
  Layout l;
  const int mq = pr.samples_q();
  // Jacobi's newest kinematic sample is the current state x1(t_n); Gauss-Seidel's is mass1's new
  // output x1(t_{n+1}), computed within the step, so it keeps one past sample fewer.
  l.hq = scheme == Scheme::Jacobi ? mq - 1 : std::max(mq - 2, 0);
  l.hf = pr.samples_f();
  return l;
}

StepMap step_map(const OscParams& p, Scheme scheme, const Predictors& pr, double H) {
  validate(p);
  validate(pr);
  check_step(H);
  const int kq = pr.kq, kf = pr.kf, mq = pr.samples_q(), mf = pr.samples_f();
  const Layout L = layout(scheme, pr);
  const int N = L.size();

  Eigen::Matrix2d A1, A2;
  A1 << 0.0, 1.0, -p.c1 / p.m1, -p.d1 / p.m1;
  A2 << 0.0, 1.0, -(p.c2 + p.cc) / p.m2, -(p.d2 + p.dc) / p.m2;
  Eigen::MatrixXd B1(2, 1), B2(2, 2);
  B1 << 0.0, 1.0 / p.m1;                     // input F
  B2 << 0.0, 0.0, p.cc / p.m2, p.dc / p.m2;  // inputs u_x, u_v
  const HalfPropagator h1 = propagate(A1, B1, kf, H);
  const HalfPropagator h2 = propagate(A2, B2, kq, H);

  const bool average = pr.force == ForceUse::Average;
  // Force end samples F_n, F_{n-1}, ... at s = 0, -1, ...; or interval means over [-1, 0],
  // [-2, -1], ... (histopolation). mass1 steps first in both schemes: always extrapolation.
  const Eigen::MatrixXd PF = average ? histopolation_matrix(intervals(mf, 0.0), kf)
                                     : fit_matrix(abscissae(mf, 0.0), kf);
  const HalfMean m2 = average ? interval_mean(A2, B2, kq, H) : HalfMean{};
  const Eigen::MatrixXd Pq = fit_matrix(abscissae(mq, scheme == Scheme::Jacobi ? 0.0 : 1.0), kq);

  // Implicit iterations: the inputs fitted through the previous iteration's end values.
  const bool implicit = pr.iterations != 1;
  const Eigen::MatrixXd PF_it = implicit ? fit_matrix(abscissae(mf, 1.0), kf) : Eigen::MatrixXd();
  const Eigen::MatrixXd Pq_it = implicit ? fit_matrix(abscissae(mq, 1.0), kq) : Eigen::MatrixXd();

  // One pass of both halves from z_n; `guess` (x1, v1, F at t_{n+1} from the previous iteration)
  // or null for the first pass (the explicit step). Linear in (z, guess).
  struct Pass {
    Eigen::Vector2d dy1, dy2;
    Eigen::Vector3d end;  // x1, v1, F at t_{n+1}
  };
  const auto pass = [&](const Eigen::VectorXd& z, const Eigen::Vector3d* guess) {
    Pass out;
    const Eigen::Vector2d y1 = z.segment<2>(0), y2 = z.segment<2>(2);

    // mass1 with the force extrapolated from F_n, F_{n-1}, ... (both schemes), or in an
    // iteration fitted through the guess at t_{n+1} and F_n, F_{n-1}, ...
    Eigen::VectorXd wF;
    if (!guess) {
      wF = PF * z.segment(L.f_hist(), mf);
    } else {
      Eigen::VectorXd fs(mf);
      fs(0) = (*guess)(2);
      for (int h = 1; h < mf; ++h) fs(h) = z(L.f_hist() + h - 1);
      wF = PF_it * fs;
    }
    const Eigen::Vector2d dy1 = h1.e_minus_identity * y1 + h1.g * wF;

    // mass2's kinematic samples, newest first.
    Eigen::VectorXd xs(mq), vs(mq);
    int i = 0;
    if (scheme == Scheme::GaussSeidel) {  // mass1's sample at t_{n+1}, just computed
      xs(i) = y1(0) + dy1(0);
      vs(i) = y1(1) + dy1(1);
      ++i;
    } else if (guess) {  // Jacobi iteration: the previous iteration's sample at t_{n+1}
      xs(i) = (*guess)(0);
      vs(i) = (*guess)(1);
      ++i;
    }
    if (i < mq) {  // the sample at t_n is the current state
      xs(i) = y1(0);
      vs(i) = y1(1);
      ++i;
    }
    for (int h = 0; i < mq; ++i, ++h) {
      xs(i) = z(L.x1_hist() + h);
      vs(i) = z(L.v1_hist() + h);
    }
    const Eigen::VectorXd wx = (guess && scheme == Scheme::Jacobi ? Pq_it : Pq) * xs;
    const Eigen::VectorXd wv = (guess && scheme == Scheme::Jacobi ? Pq_it : Pq) * vs;
    Eigen::VectorXd w2(2 * (kq + 1));
    w2 << wx, wv;
    const Eigen::Vector2d dy2 = h2.e_minus_identity * y2 + h2.g * w2;
    const Eigen::Vector2d y2_new = y2 + dy2;

    // mass2's output: the force on mass1 with the input polynomial's value at the step's end;
    // or its exact mean over the step, from the means of the input polynomial (sum w_j / (j+1))
    // and of mass2's state.
    double F_new = 0.0;
    if (!average) {
      F_new = -(p.cc * (wx.sum() - y2_new(0)) + p.dc * (wv.sum() - y2_new(1)));
    } else {
      double ux_mean = 0.0, uv_mean = 0.0;
      for (int j = 0; j <= kq; ++j) {
        ux_mean += wx(j) / (j + 1);
        uv_mean += wv(j) / (j + 1);
      }
      const Eigen::Vector2d y2_mean = m2.e * y2 + m2.g * w2;
      F_new = -(p.cc * (ux_mean - y2_mean(0)) + p.dc * (uv_mean - y2_mean(1)));
    }
    out.dy1 = dy1;
    out.dy2 = dy2;
    out.end << y1(0) + dy1(0), y1(1) + dy1(1), F_new;
    return out;
  };

  // The fixed point of the iteration (iterations = 0): the pass's end values are affine in the
  // guess, end = Cz z + Cg guess, so guess* = (I - Cg)^-1 Cz z.
  Eigen::Matrix3d I_minus_Cg = Eigen::Matrix3d::Identity();
  if (pr.iterations == 0) {
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(N);
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3d e = Eigen::Vector3d::Unit(c);
      I_minus_Cg.col(c) -= pass(zero, &e).end;
    }
  }
  const auto fixed_point = I_minus_Cg.fullPivLu();

  // z_{n+1} - z_n for one macro step from z_n. Linear in z, so applying it to the unit vectors
  // gives the columns of phi - I. Written as an increment so the physical rows carry
  // (E - I) y + G w, never I + small - I.
  const auto increment = [&](const Eigen::VectorXd& z) {
    Eigen::VectorXd dz(N);
    const Eigen::Vector2d y1 = z.segment<2>(0);
    Pass last = pass(z, nullptr);
    if (pr.iterations == 0) {
      const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
      const Eigen::Vector3d g = fixed_point.solve(pass(z, &zero).end);
      last = pass(z, &g);
    }
    for (int k = 1; k < pr.iterations; ++k) {
      const Eigen::Vector3d g = last.end;
      last = pass(z, &g);
    }
    const double F_new = last.end(2);
    dz.segment<2>(0) = last.dy1;
    dz.segment<2>(2) = last.dy2;
    // Histories shift by one: the newest past kinematic sample becomes x1(t_n), the newest force
    // sample becomes F_{n+1}.
    for (int h = 0; h < L.hq; ++h) {
      const double xn = h == 0 ? y1(0) : z(L.x1_hist() + h - 1);
      const double vn = h == 0 ? y1(1) : z(L.v1_hist() + h - 1);
      dz(L.x1_hist() + h) = xn - z(L.x1_hist() + h);
      dz(L.v1_hist() + h) = vn - z(L.v1_hist() + h);
    }
    for (int h = 0; h < L.hf; ++h) {
      const double fn = h == 0 ? F_new : z(L.f_hist() + h - 1);
      dz(L.f_hist() + h) = fn - z(L.f_hist() + h);
    }
    return dz;
  };

  StepMap out;
  out.layout = L;
  out.phi_minus_identity.resize(N, N);
  for (int c = 0; c < N; ++c)
    out.phi_minus_identity.col(c) = increment(Eigen::VectorXd::Unit(N, c));
  out.phi = out.phi_minus_identity + Eigen::MatrixXd::Identity(N, N);
  return out;
}

Eigen::VectorXd initial_extended_state(const OscParams& p, Scheme scheme, const Predictors& pr,
                                       const Eigen::Vector4d& x0) {
  validate(pr);
  const Layout L = layout(scheme, pr);
  Eigen::VectorXd z(L.size());
  z.head<4>() = x0;
  z.segment(L.x1_hist(), L.hq).setConstant(x0(0));
  z.segment(L.v1_hist(), L.hq).setConstant(x0(1));
  z.segment(L.f_hist(), L.hf).setConstant(-(p.cc * (x0(0) - x0(2)) + p.dc * (x0(1) - x0(3))));
  return z;
}

double spectral_radius_minus_one(const OscParams& p, Scheme scheme, int kq, int kf, int mq, int mf,
                                 double H) {
  return spectral_radius_minus_one(p, scheme, Predictors{kq, kf, mq, mf, ForceUse::End}, H);
}

double spectral_radius(const OscParams& p, Scheme scheme, const Predictors& pr, double H) {
  return 1.0 + spectral_radius_minus_one(p, scheme, pr, H);
}

double spectral_radius_minus_one(const OscParams& p, Scheme scheme, const Predictors& pr,
                                 double H) {
  const StepMap map = step_map(p, scheme, pr, H);
  // Eigenvalues of phi - I are mu = lambda - 1; for the physical modes they are O(H), so
  // |lambda| - 1 keeps its digits where max |eig(phi)| - 1 would round to a few ulps of 1.
  Eigen::MatrixXd D = map.phi_minus_identity;
  balance(D);
  const Eigen::EigenSolver<Eigen::MatrixXd> es(D, false);
  if (es.info() != Eigen::Success)
    throw std::runtime_error(
        "eigenvalue computation of the step map did not converge (H = " + number(H) + ")");
  double worst = -1.0;
  for (const auto& mu : es.eigenvalues()) worst = std::max(worst, modulus_minus_one(mu));
  return worst;
}

double spectral_radius(const OscParams& p, Scheme scheme, int kq, int kf, int mq, int mf,
                       double H) {
  return 1.0 + spectral_radius_minus_one(p, scheme, kq, kf, mq, mf, H);
}

Eigen::Matrix4d monolithic_matrix(const OscParams& p) {
  Eigen::Matrix4d A;
  A << 0.0, 1.0, 0.0, 0.0, -(p.c1 + p.cc) / p.m1, -(p.d1 + p.dc) / p.m1, p.cc / p.m1, p.dc / p.m1,
      0.0, 0.0, 0.0, 1.0, p.cc / p.m2, p.dc / p.m2, -(p.c2 + p.cc) / p.m2, -(p.d2 + p.dc) / p.m2;
  return A;
}

double slowest_decay_rate(const OscParams& p) {
  const Eigen::EigenSolver<Eigen::Matrix4d> es(monolithic_matrix(p), false);
  double max_re = -std::numeric_limits<double>::infinity();
  for (const auto& l : es.eigenvalues()) max_re = std::max(max_re, l.real());
  return -max_re;
}

std::optional<double> StabilityScan::critical() const {
  if (unstable_at_h_min) return std::nullopt;
  for (const auto& c : crossings)
    if (c.becomes_unstable) return c.H;
  return std::nullopt;
}

StabilityScan scan_stability(const OscParams& p, Scheme scheme, int kq, int kf, int mq, int mf,
                             const ScanOptions& opt) {
  return scan_stability(p, scheme, Predictors{kq, kf, mq, mf, ForceUse::End}, opt);
}

StabilityScan scan_stability(const OscParams& p, Scheme scheme, const Predictors& pr,
                             const ScanOptions& opt) {
  if (!(opt.h_min > 0.0) || !(opt.h_max > opt.h_min) || opt.points < 2 || !(opt.rel_tol > 0.0))
    throw std::invalid_argument("stability scan needs 0 < h_min < h_max, points >= 2, rel_tol > 0");
  const auto unstable = [&](double H) {
    return spectral_radius_minus_one(p, scheme, pr, H) >= 0.0;
  };
  const double log_min = std::log(opt.h_min), log_max = std::log(opt.h_max);
  const auto grid = [&](int i) {
    if (i == 0) return opt.h_min;
    if (i == opt.points - 1) return opt.h_max;
    return std::exp(log_min + (log_max - log_min) * i / (opt.points - 1));
  };

  StabilityScan scan;
  double h_prev = grid(0);
  bool prev = unstable(h_prev);
  scan.unstable_at_h_min = prev;
  for (int i = 1; i < opt.points; ++i) {
    const double h = grid(i);
    const bool now = unstable(h);
    if (now != prev) {
      // Bisect in log H: the bracket spans decades at the coarse end of the grid.
      double lo = h_prev, hi = h;
      while (hi - lo > opt.rel_tol * lo) {
        const double mid = std::sqrt(lo * hi);
        (unstable(mid) == prev ? lo : hi) = mid;
      }
      scan.crossings.push_back({0.5 * (lo + hi), now});
    }
    h_prev = h;
    prev = now;
  }
  return scan;
}

std::optional<double> critical_macro_step(const OscParams& p, Scheme scheme, int kq, int kf, int mq,
                                          int mf, const ScanOptions& opt) {
  return scan_stability(p, scheme, kq, kf, mq, mf, opt).critical();
}

std::optional<double> critical_macro_step(const OscParams& p, Scheme scheme, const Predictors& pr,
                                          const ScanOptions& opt) {
  return scan_stability(p, scheme, pr, opt).critical();
}

}  // namespace cosim::stability
