// Tests of cosim_stability_lib: the step map's spectral radius against a prototype of the same
// definitions, against a direct iteration of the map and an independent RK4 step, the critical
// macro steps, and the small-H limit exp(-alpha H).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "stability.hpp"

namespace {

using namespace cosim::stability;

struct Reference {
  Scheme scheme;
  int kq, kf;
  double H, rho;
};

// rho(H) printed to 6 decimals by an independent prototype of the same scheme definitions.
TEST(StabilitySpectralRadius, MatchesPrototypeNumbers) {
  const OscParams p;
  const Reference refs[] = {
      {Scheme::Jacobi, 0, 0, 1e-2, 1.035474},      {Scheme::Jacobi, 0, 0, 2e-3, 1.000300},
      {Scheme::Jacobi, 0, 0, 1e-3, 1.000025},      {Scheme::Jacobi, 0, 0, 5e-4, 0.999981},
      {Scheme::Jacobi, 1, 0, 1e-2, 1.013869},      {Scheme::Jacobi, 1, 0, 2e-3, 0.999800},
      {Scheme::GaussSeidel, 0, 0, 1e-3, 1.000025}, {Scheme::GaussSeidel, 0, 0, 5e-4, 0.999981},
      {Scheme::GaussSeidel, 1, 0, 1e-2, 1.003699}, {Scheme::Jacobi, 1, 1, 1e-2, 0.998985},
      {Scheme::Jacobi, 2, 2, 1e-2, 0.998985},
  };
  for (const auto& r : refs) {
    SCOPED_TRACE(std::string(scheme_name(r.scheme)) + " kq=" + std::to_string(r.kq) +
                 " kf=" + std::to_string(r.kf) + " H=" + std::to_string(r.H));
    EXPECT_NEAR(spectral_radius(p, r.scheme, r.kq, r.kf, 0, 0, r.H), r.rho, 2e-6);
  }
}

// The envelope (max over a window) of a sampled signal.
double envelope(const std::vector<double>& signal, std::size_t from, std::size_t to) {
  double m = 0.0;
  for (std::size_t i = from; i < to; ++i) m = std::max(m, std::abs(signal[i]));
  return m;
}

// Iterates z_{n+1} = phi z_n from x(0) = (0.1, 0, 0, 0) and measures the growth of x1. Only the
// second half is compared: the stiff out-of-phase mode (decay ~2.1 1/s) is gone by then, and what
// is left is the lightly damped in-phase mode (omega ~ 3.16 rad/s), which is also the mode the
// coupling error destabilises. At the start x1 = 0.1 is split between both modes, so comparing
// against the first window would mix them.
void check_iterated_growth(double H, bool expect_growth) {
  const OscParams p;
  const Predictors pr{0, 0, 0, 0};
  const StepMap map = step_map(p, Scheme::Jacobi, pr, H);
  Eigen::VectorXd z = initial_extended_state(p, Scheme::Jacobi, pr, Eigen::Vector4d(0.1, 0, 0, 0));
  const std::size_t steps = 20000;
  std::vector<double> x1{z(0)};
  for (std::size_t n = 0; n < steps; ++n) {
    z = map.phi * z;
    x1.push_back(z(0));
  }
  // Windows a little longer than one period of the in-phase mode (2 pi / 3.16 ~ 2 s).
  const auto window = static_cast<std::size_t>(std::ceil(2.2 / H));
  ASSERT_LT(window, steps / 2);
  const double mid = envelope(x1, steps / 2 - window, steps / 2 + 1);
  const double last = envelope(x1, steps - window, steps + 1);
  if (expect_growth)
    EXPECT_GT(last, mid) << "amplitude should grow at H = " << H;
  else
    EXPECT_LT(last, mid) << "amplitude should decay at H = " << H;

  const double observed = std::log(last / mid) / static_cast<double>(steps / 2);
  const double predicted = std::log(spectral_radius(p, Scheme::Jacobi, 0, 0, 0, 0, H));
  EXPECT_NEAR(observed, predicted, 0.1 * std::abs(predicted))
      << "growth per step over the last half at H = " << H;
}

TEST(StabilityIteratedMap, JacobiGrowsAbove1ms) { check_iterated_growth(1e-3, true); }
TEST(StabilityIteratedMap, JacobiDecaysAt500us) { check_iterated_growth(5e-4, false); }

TEST(StabilityCriticalStep, BracketsAndSignChange) {
  const OscParams p;
  struct Case {
    int kq, kf;
    double lo, hi;
  };
  for (const Case c : {Case{0, 0, 5e-4, 1e-3}, Case{1, 0, 2e-3, 1e-2}}) {
    SCOPED_TRACE("jacobi kq=" + std::to_string(c.kq) + " kf=" + std::to_string(c.kf));
    const auto hc = critical_macro_step(p, Scheme::Jacobi, c.kq, c.kf);
    ASSERT_TRUE(hc.has_value());
    EXPECT_GT(*hc, c.lo);
    EXPECT_LT(*hc, c.hi);
    EXPECT_LT(spectral_radius(p, Scheme::Jacobi, c.kq, c.kf, 0, 0, 0.98 * *hc), 1.0);
    EXPECT_GT(spectral_radius(p, Scheme::Jacobi, c.kq, c.kf, 0, 0, 1.02 * *hc), 1.0);
  }
}

// As H -> 0 the co-simulation error vanishes and rho tends to the exact decay exp(-alpha H).
TEST(StabilitySmallStep, TendsToMonolithicDecay) {
  const OscParams p;
  const double alpha = slowest_decay_rate(p);
  // The in-phase mode of the symmetric oscillator decays at d / (2 m) = 0.1 1/s.
  EXPECT_NEAR(alpha, 0.1, 1e-12);
  const double H = 1e-5;
  const double exact = std::exp(-alpha * H);
  for (Scheme s : {Scheme::Jacobi, Scheme::GaussSeidel})
    for (const auto& [kq, kf] : std::vector<std::pair<int, int>>{{0, 0}, {1, 0}, {1, 1}, {3, 3}}) {
      SCOPED_TRACE(std::string(scheme_name(s)) + " kq=" + std::to_string(kq) +
                   " kf=" + std::to_string(kf));
      EXPECT_NEAR(spectral_radius(p, s, kq, kf, 0, 0, H) / exact, 1.0, 1e-7);
    }
}

// Without coupling the halves are integrated exactly and rho(H) is exp(-alpha H) at any H.
TEST(StabilitySmallStep, UncoupledIsExact) {
  OscParams p;
  set_param(p, "cc", 0.0);
  set_param(p, "dc", 0.0);
  set_param(p, "d2", 0.6);  // mass2 decays faster, so alpha is mass1's 0.1 1/s
  for (double H : {1e-3, 1e-2, 1e-1})
    for (Scheme s : {Scheme::Jacobi, Scheme::GaussSeidel})
      EXPECT_NEAR(spectral_radius_minus_one(p, s, 2, 1, 0, 0, H), std::expm1(-0.1 * H), 1e-14)
          << scheme_name(s) << " H=" << H;
}

// ---- One macro step against an independent RK4 integration of both halves ----

// Coefficients of the degree-k polynomial through (least squares for more samples) (s_i, y_i).
Eigen::VectorXd fit(const std::vector<double>& s, const std::vector<double>& y, int k) {
  Eigen::MatrixXd V(s.size(), k + 1);
  Eigen::VectorXd Y(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    for (int j = 0; j <= k; ++j) V(i, j) = std::pow(s[i], j);
    Y(i) = y[i];
  }
  return V.householderQr().solve(Y);
}

double eval(const Eigen::VectorXd& w, double sigma) {
  double v = 0.0;
  for (int j = static_cast<int>(w.size()) - 1; j >= 0; --j) v = v * sigma + w(j);
  return v;
}

// RK4 on m x'' = -c x - d x' + f(sigma) over sigma in [0, 1] (t = sigma H).
template <class Force>
Eigen::Vector2d rk4(Eigen::Vector2d y, double m, double c, double d, double H, Force f) {
  const int n = 2000;
  const double h = H / n;
  const auto rhs = [&](const Eigen::Vector2d& q, double t) {
    return Eigen::Vector2d(q(1), (-c * q(0) - d * q(1) + f(t / H)) / m);
  };
  for (int i = 0; i < n; ++i) {
    const double t = i * h;
    const Eigen::Vector2d k1 = rhs(y, t), k2 = rhs(y + 0.5 * h * k1, t + 0.5 * h),
                          k3 = rhs(y + 0.5 * h * k2, t + 0.5 * h), k4 = rhs(y + h * k3, t + h);
    y += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
  return y;
}

// The scheme written out step by step from the definitions, on a random extended state.
Eigen::VectorXd direct_step(const OscParams& p, Scheme scheme, const Predictors& pr, double H,
                            const Eigen::VectorXd& z) {
  const Layout L = layout(scheme, pr);
  const int mq = pr.samples_q(), mf = pr.samples_f();
  std::vector<double> sf, F;
  for (int i = 0; i < mf; ++i) {
    sf.push_back(-i);
    F.push_back(z(L.f_hist() + i));
  }
  const Eigen::VectorXd wF = fit(sf, F, pr.kf);
  const Eigen::Vector2d y1 =
      rk4(z.segment<2>(0), p.m1, p.c1, p.d1, H, [&](double s) { return eval(wF, s); });
  std::vector<double> sq, xs, vs;
  const bool gs = scheme == Scheme::GaussSeidel;
  if (gs) {
    sq.push_back(1);
    xs.push_back(y1(0));
    vs.push_back(y1(1));
  }
  sq.push_back(0);
  xs.push_back(z(0));
  vs.push_back(z(1));
  for (int h = 0; static_cast<int>(sq.size()) < mq; ++h) {
    sq.push_back(-1 - h);
    xs.push_back(z(L.x1_hist() + h));
    vs.push_back(z(L.v1_hist() + h));
  }
  sq.resize(mq);
  xs.resize(mq);
  vs.resize(mq);
  const Eigen::VectorXd wx = fit(sq, xs, pr.kq), wv = fit(sq, vs, pr.kq);
  // Coupling spring/damper folded into mass2's own stiffness/damping; the input part is the force.
  const Eigen::Vector2d y2 = rk4(z.segment<2>(2), p.m2, p.c2 + p.cc, p.d2 + p.dc, H,
                                 [&](double s) { return p.cc * eval(wx, s) + p.dc * eval(wv, s); });
  const double F_new = -(p.cc * (eval(wx, 1) - y2(0)) + p.dc * (eval(wv, 1) - y2(1)));

  Eigen::VectorXd out(z.size());
  out << y1, y2, Eigen::VectorXd::Zero(z.size() - 4);
  for (int h = 0; h < L.hq; ++h) {
    out(L.x1_hist() + h) = h == 0 ? z(0) : z(L.x1_hist() + h - 1);
    out(L.v1_hist() + h) = h == 0 ? z(1) : z(L.v1_hist() + h - 1);
  }
  for (int h = 0; h < L.hf; ++h) out(L.f_hist() + h) = h == 0 ? F_new : z(L.f_hist() + h - 1);
  return out;
}

TEST(StabilityStepMap, MatchesDirectRk4Step) {
  const OscParams p;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Predictors cases[] = {{0, 0, 0, 0}, {1, 0, 0, 0}, {2, 1, 0, 0}, {3, 3, 0, 0},
                              {1, 1, 4, 3}, {2, 0, 5, 2}};  // the last two: least-squares fits
  for (Scheme s : {Scheme::Jacobi, Scheme::GaussSeidel})
    for (const auto& pr : cases) {
      SCOPED_TRACE(std::string(scheme_name(s)) + " kq=" + std::to_string(pr.kq) +
                   " kf=" + std::to_string(pr.kf) + " mq=" + std::to_string(pr.samples_q()) +
                   " mf=" + std::to_string(pr.samples_f()));
      const double H = 2e-3;
      const StepMap map = step_map(p, s, pr, H);
      Eigen::VectorXd z(map.layout.size());
      for (int i = 0; i < z.size(); ++i) z(i) = u(rng);
      z.tail(map.layout.hf) *= 100.0;  // forces in newtons are larger than positions in metres
      const Eigen::VectorXd expected = direct_step(p, s, pr, H, z);
      EXPECT_LT((map.phi * z - expected).cwiseAbs().maxCoeff(), 1e-9);
      EXPECT_LT((map.phi_minus_identity * z - (expected - z)).cwiseAbs().maxCoeff(), 1e-9);
    }
}

// ---- use: average, against an independent construction ----
//
// The averaged force connection written out from its definition with tools of its own: both
// halves by RK4 (mass2 with a third state, the integral of its coupling force, so the interval
// mean is integral / H); the histopolation through the cumulative integral (the polynomial whose
// means over [-m, -m+1], ..., [-1, 0] are the received means is the derivative of the degree-m
// polynomial through the running sums C(-m) = 0, C(-m+1) = Fbar_oldest, ..., C(0) = sum, a
// Lagrange interpolation); the kinematics by Lagrange interpolation. The step map is built
// column by column from it and its eigenvalues taken directly.

// Lagrange basis on nodes: value and derivative of sum_i y_i L_i at s.
double lagrange(const std::vector<double>& nodes, const std::vector<double>& y, double s) {
  double v = 0.0;
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    double l = 1.0;
    for (std::size_t j = 0; j < nodes.size(); ++j)
      if (j != i) l *= (s - nodes[j]) / (nodes[i] - nodes[j]);
    v += y[i] * l;
  }
  return v;
}
double lagrange_derivative(const std::vector<double>& nodes, const std::vector<double>& y, double s) {
  double v = 0.0;
  for (std::size_t i = 0; i < nodes.size(); ++i)
    for (std::size_t l = 0; l < nodes.size(); ++l) {
      if (l == i) continue;
      double term = 1.0 / (nodes[i] - nodes[l]);
      for (std::size_t j = 0; j < nodes.size(); ++j)
        if (j != i && j != l) term *= (s - nodes[j]) / (nodes[i] - nodes[j]);
      v += y[i] * term;
    }
  return v;
}

// Least-squares histopolation (mf > kf + 1) by the normal equations, the interval means of s^j
// by 3-point Gauss-Legendre quadrature (exact up to degree 5).
Eigen::VectorXd least_squares_means(const Eigen::VectorXd& means_newest_first, int k) {
  const int m = static_cast<int>(means_newest_first.size());
  const double g = std::sqrt(0.6), gx[] = {-g, 0.0, g}, gw[] = {5.0 / 18, 8.0 / 18, 5.0 / 18};
  Eigen::MatrixXd V(m, k + 1);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j <= k; ++j) {
      V(i, j) = 0.0;
      for (int q = 0; q < 3; ++q) V(i, j) += gw[q] * std::pow(-i - 0.5 + 0.5 * gx[q], j);
    }
  return (V.transpose() * V).ldlt().solve(V.transpose() * means_newest_first);
}

// One macro step of the averaged scheme (mq = kq + 1; mf >= kf + 1). State: x1 v1 x2 v2, then the
// x1 history, the v1 history and the mean-force history (newest first) as in Layout.
Eigen::VectorXd averaged_step_rk4(const OscParams& p, Scheme scheme, int kq, int kf, double H,
                                  const Eigen::VectorXd& z, int hq, int mf = 0) {
  if (mf == 0) mf = kf + 1;
  const int mq = kq + 1, f0 = 4 + 2 * hq;
  // Histopolation via the running sums of the means, oldest first.
  std::vector<double> nodes{static_cast<double>(-mf)}, sums{0.0};
  for (int i = mf - 1; i >= 0; --i) {
    nodes.push_back(-i);
    sums.push_back(sums.back() + z(f0 + i));
  }
  const Eigen::VectorXd ls = mf > kf + 1 ? least_squares_means(z.segment(f0, mf), kf) : Eigen::VectorXd();
  const auto force = [&](double s) {
    if (mf == kf + 1) return lagrange_derivative(nodes, sums, s);
    double v = 0.0;
    for (int j = kf; j >= 0; --j) v = v * s + ls(j);
    return v;
  };
  const int n = 1000;
  const double h = H / n;
  Eigen::Vector2d y1 = z.segment<2>(0);
  for (int i = 0; i < n; ++i) {
    const double t = i * h;
    const auto rhs = [&](const Eigen::Vector2d& q, double tt) {
      return Eigen::Vector2d(q(1), (-p.c1 * q(0) - p.d1 * q(1) + force(tt / H)) / p.m1);
    };
    const Eigen::Vector2d k1 = rhs(y1, t), k2 = rhs(y1 + 0.5 * h * k1, t + 0.5 * h),
                          k3 = rhs(y1 + 0.5 * h * k2, t + 0.5 * h), k4 = rhs(y1 + h * k3, t + h);
    y1 += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
  // Kinematic samples, newest first: Gauss-Seidel's x1(t_{n+1}) at s = 1, then t_n, history.
  std::vector<double> sq, xs, vs;
  if (scheme == Scheme::GaussSeidel) sq = {1.0}, xs = {y1(0)}, vs = {y1(1)};
  sq.push_back(0.0), xs.push_back(z(0)), vs.push_back(z(1));
  for (int j = 0; static_cast<int>(sq.size()) < mq; ++j)
    sq.push_back(-1.0 - j), xs.push_back(z(4 + j)), vs.push_back(z(4 + hq + j));
  sq.resize(mq), xs.resize(mq), vs.resize(mq);
  // mass2 with the integral of its coupling force on mass1 as a third state.
  const auto rhs2 = [&](const Eigen::Vector3d& q, double tt) {
    const double ux = lagrange(sq, xs, tt / H), uv = lagrange(sq, vs, tt / H);
    const double fc = p.cc * (ux - q(0)) + p.dc * (uv - q(1));
    return Eigen::Vector3d(q(1), (-p.c2 * q(0) - p.d2 * q(1) + fc) / p.m2, -fc);
  };
  Eigen::Vector3d y2(z(2), z(3), 0.0);
  for (int i = 0; i < n; ++i) {
    const double t = i * h;
    const Eigen::Vector3d k1 = rhs2(y2, t), k2 = rhs2(y2 + 0.5 * h * k1, t + 0.5 * h),
                          k3 = rhs2(y2 + 0.5 * h * k2, t + 0.5 * h), k4 = rhs2(y2 + h * k3, t + h);
    y2 += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
  Eigen::VectorXd out(z.size());
  out.head<4>() << y1, y2.head<2>();
  for (int j = 0; j < hq; ++j) {
    out(4 + j) = j == 0 ? z(0) : z(4 + j - 1);
    out(4 + hq + j) = j == 0 ? z(1) : z(4 + hq + j - 1);
  }
  for (int j = 0; j < mf; ++j) out(f0 + j) = j == 0 ? y2(2) / H : z(f0 + j - 1);
  return out;
}

double averaged_rho_rk4(const OscParams& p, Scheme scheme, int kq, int kf, double H) {
  const int hq = scheme == Scheme::Jacobi ? kq : std::max(kq - 1, 0);
  const int N = 4 + 2 * hq + kf + 1;
  Eigen::MatrixXd phi(N, N);
  for (int c = 0; c < N; ++c)
    phi.col(c) = averaged_step_rk4(p, scheme, kq, kf, H, Eigen::VectorXd::Unit(N, c), hq);
  const Eigen::EigenSolver<Eigen::MatrixXd> es(phi, false);
  double rho = 0.0;
  for (const auto& l : es.eigenvalues()) rho = std::max(rho, std::abs(l));
  return rho;
}

struct AveragedCase {
  Scheme scheme;
  int kq, kf;
};
const AveragedCase kAveraged[] = {{Scheme::Jacobi, 0, 0},      {Scheme::Jacobi, 1, 0},
                                  {Scheme::Jacobi, 1, 1},      {Scheme::Jacobi, 2, 2},
                                  {Scheme::GaussSeidel, 1, 0}, {Scheme::GaussSeidel, 1, 1}};

std::string describe(const AveragedCase& c) {
  return std::string(scheme_name(c.scheme)) + " (" + std::to_string(c.kq) + "," +
         std::to_string(c.kf) + ") use average";
}

TEST(StabilityAverage, StepMapMatchesAnIndependentRk4Construction) {
  const OscParams p;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const auto& c : kAveraged) {
    SCOPED_TRACE(describe(c));
    const Predictors pr{c.kq, c.kf, 0, 0, ForceUse::Average};
    const double H = 5e-3;
    const StepMap map = step_map(p, c.scheme, pr, H);
    Eigen::VectorXd z(map.layout.size());
    for (int i = 0; i < z.size(); ++i) z(i) = u(rng);
    z.tail(map.layout.hf) *= 100.0;
    const Eigen::VectorXd expected = averaged_step_rk4(p, c.scheme, c.kq, c.kf, H, z, map.layout.hq);
    EXPECT_LT((map.phi * z - expected).cwiseAbs().maxCoeff(), 1e-9);
    // and it is not the end-sample map
    const StepMap end = step_map(p, c.scheme, Predictors{c.kq, c.kf, 0, 0, ForceUse::End}, H);
    EXPECT_GT((end.phi * z - expected).cwiseAbs().maxCoeff(), 1e-3);
  }
  // least-squares histopolation: more means than order + 1
  for (const auto& [kf, mf] : std::vector<std::pair<int, int>>{{0, 3}, {1, 4}, {2, 6}}) {
    SCOPED_TRACE("jacobi (1," + std::to_string(kf) + ") mf=" + std::to_string(mf));
    const StepMap map = step_map(p, Scheme::Jacobi, Predictors{1, kf, 0, mf, ForceUse::Average}, 5e-3);
    Eigen::VectorXd z(map.layout.size());
    for (int i = 0; i < z.size(); ++i) z(i) = u(rng);
    z.tail(map.layout.hf) *= 100.0;
    const Eigen::VectorXd expected = averaged_step_rk4(p, Scheme::Jacobi, 1, kf, 5e-3, z, map.layout.hq, mf);
    EXPECT_LT((map.phi * z - expected).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(StabilityAverage, SpectralRadiusMatchesTheIndependentConstruction) {
  const OscParams p;
  for (const auto& c : kAveraged)
    for (double H : {1e-3, 5e-3, 2e-2}) {
      SCOPED_TRACE(describe(c) + " H=" + std::to_string(H));
      const double rho = spectral_radius(p, c.scheme, Predictors{c.kq, c.kf, 0, 0, ForceUse::Average}, H);
      EXPECT_NEAR(rho, averaged_rho_rk4(p, c.scheme, c.kq, c.kf, H), 1e-10);
    }
}

// The critical macro step of the library against a bisection of the independent rho(H) - 1,
// started from a bracket of +-10 % around it.
TEST(StabilityAverage, CriticalMacroStepMatchesTheIndependentConstruction) {
  const OscParams p;
  const AveragedCase cases[] = {{Scheme::Jacobi, 0, 0}, {Scheme::Jacobi, 1, 0},
                                {Scheme::Jacobi, 1, 1}, {Scheme::GaussSeidel, 1, 0}};
  for (const auto& c : cases) {
    SCOPED_TRACE(describe(c));
    const auto hc = critical_macro_step(p, c.scheme, Predictors{c.kq, c.kf, 0, 0, ForceUse::Average});
    ASSERT_TRUE(hc.has_value());
    double lo = 0.9 * *hc, hi = 1.1 * *hc;
    ASSERT_LT(averaged_rho_rk4(p, c.scheme, c.kq, c.kf, lo), 1.0);
    ASSERT_GT(averaged_rho_rk4(p, c.scheme, c.kq, c.kf, hi), 1.0);
    while (hi - lo > 1e-7 * lo) {
      const double mid = 0.5 * (lo + hi);
      (averaged_rho_rk4(p, c.scheme, c.kq, c.kf, mid) < 1.0 ? lo : hi) = mid;
    }
    std::printf("%s: H_crit %.6e, independent %.6e\n", describe(c).c_str(), *hc, 0.5 * (lo + hi));
    EXPECT_NEAR(0.5 * (lo + hi) / *hc, 1.0, 1e-5);
    // and it differs from the end-sample limit
    const auto he = critical_macro_step(p, c.scheme, c.kq, c.kf);
    ASSERT_TRUE(he.has_value());
    EXPECT_GT(std::abs(*he / *hc - 1.0), 0.05);
  }
}

// An exact equivalence: with Gauss-Seidel (mass1 first), constant kinematics and averaged
// force (0,0) is the same scheme as linear kinematics and end-sample force (1,0). Over a step,
// mass2's input is held at x1(t_{n+1}); the moving average over one macro step of that
// piecewise-constant input is the linear interpolation between x1(t_n) and x1(t_{n+1}), and
// the moving average of mass2's state solves mass2's equation for that input (linear, time-
// invariant), so the mean force of the one is the end force of the other.
TEST(StabilityAverage, GaussSeidel00AverageEqualsGaussSeidel10End) {
  const OscParams p;
  for (double H : {1e-3, 5e-3, 2e-2, 5e-2}) {
    const double a = spectral_radius_minus_one(p, Scheme::GaussSeidel, Predictors{0, 0, 0, 0, ForceUse::Average}, H);
    const double e = spectral_radius_minus_one(p, Scheme::GaussSeidel, Predictors{1, 0, 0, 0, ForceUse::End}, H);
    EXPECT_NEAR(a, e, 1e-12 + 1e-9 * std::abs(e)) << "H=" << H;
  }
}

// use: end through the Predictors overloads is the int-argument result, bit for bit.
TEST(StabilityAverage, EndThroughPredictorsIsUnchanged) {
  const OscParams p;
  for (Scheme s : {Scheme::Jacobi, Scheme::GaussSeidel})
    for (double H : {1e-3, 1e-2})
      EXPECT_EQ(spectral_radius_minus_one(p, s, Predictors{2, 1, 0, 0, ForceUse::End}, H),
                spectral_radius_minus_one(p, s, 2, 1, 0, 0, H));
}

TEST(StabilityArguments, RejectsWhatTheMasterCannotRun) {
  const OscParams p;
  EXPECT_THROW(spectral_radius(p, Scheme::Jacobi, 4, 0, 0, 0, 1e-3), std::invalid_argument);
  EXPECT_THROW(spectral_radius(p, Scheme::Jacobi, 2, 0, 2, 0, 1e-3), std::invalid_argument);
  EXPECT_THROW(spectral_radius(p, Scheme::Jacobi, 0, 0, 0, 0, 0.0), std::invalid_argument);
  OscParams bad;
  EXPECT_THROW(set_param(bad, "k1", 1.0), std::invalid_argument);
  set_param(bad, "m2", 0.0);
  EXPECT_THROW(spectral_radius(bad, Scheme::Jacobi, 0, 0, 0, 0, 1e-3), std::invalid_argument);
}

// ---- The implicit scheme (Predictors::iterations) ----

Predictors implicit_pr(int kq, int kf, int iterations) {
  Predictors pr{kq, kf, 0, 0, ForceUse::End};
  pr.iterations = iterations;
  return pr;
}

// Converged, Jacobi and Gauss-Seidel iterate to the same fixed point: the same map, the same
// spectral radius (their histories differ in length, so compare rho, not phi).
TEST(StabilityImplicit, ConvergedJacobiAndGaussSeidelAgree) {
  const OscParams p;
  for (double H : {1e-3, 2e-2, 9e-2})
    EXPECT_NEAR(spectral_radius(p, Scheme::Jacobi, implicit_pr(1, 0, 0), H),
                spectral_radius(p, Scheme::GaussSeidel, implicit_pr(1, 0, 0), H), 1e-12) << H;
}

// Where plain iteration converges (small H), k iterations approach the converged map; one
// iteration is the explicit scheme bit for bit.
TEST(StabilityImplicit, IterationsApproachTheConvergedSchemeAndOneIsExplicit) {
  const OscParams p;
  const double H = 5e-3;
  const double conv = spectral_radius_minus_one(p, Scheme::GaussSeidel, implicit_pr(1, 1, 0), H);
  double prev = std::abs(spectral_radius_minus_one(p, Scheme::GaussSeidel, implicit_pr(1, 1, 2), H) - conv);
  for (int k : {4, 8, 16}) {
    const double d = std::abs(spectral_radius_minus_one(p, Scheme::GaussSeidel, implicit_pr(1, 1, k), H) - conv);
    EXPECT_LT(d, prev) << k;
    prev = d;
  }
  EXPECT_LT(prev, 1e-9);
  for (Scheme s : {Scheme::Jacobi, Scheme::GaussSeidel})
    EXPECT_EQ(spectral_radius_minus_one(p, s, implicit_pr(1, 0, 1), 1e-2), spectral_radius_minus_one(p, s, 1, 0, 0, 0, 1e-2));
}

// The converged scheme's limits (docs/stability.md): 1.0317e-1 s for (1,0) against the explicit
// 8.454e-3 s (Gauss-Seidel) and 7.112e-3 s (Jacobi); with m1 = 0.01: 9.894e-2 s.
TEST(StabilityImplicit, ConvergedLimitsFarAboveTheExplicitOnes) {
  ScanOptions wide;
  wide.h_max = 10;
  wide.points = 500;
  OscParams p;
  EXPECT_NEAR(*critical_macro_step(p, Scheme::GaussSeidel, implicit_pr(1, 0, 0), wide), 1.0317e-1, 1e-4);
  set_param(p, "m1", 0.01);
  EXPECT_NEAR(*critical_macro_step(p, Scheme::GaussSeidel, implicit_pr(1, 0, 0), wide), 9.894e-2, 1e-4);
  EXPECT_THROW(spectral_radius(OscParams{}, Scheme::Jacobi, implicit_pr(1, 0, -1), 1e-3), std::invalid_argument);
  Predictors avg = implicit_pr(1, 0, 0);
  avg.force = ForceUse::Average;
  EXPECT_THROW(spectral_radius(OscParams{}, Scheme::Jacobi, avg, 1e-3), std::invalid_argument);
}

}  // namespace
