// Predictor polynomials: exact for polynomials up to their degree, least squares, and
// orientation on the rotation group.
#include <cosim/polynomial_wire.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace cosim;

namespace {
double poly(const std::vector<double>& c, double t) {
  double v = 0;
  for (std::size_t j = c.size(); j-- > 0;) v = v * t + c[j];
  return v;
}
}  // namespace

TEST(Polynomial, ExtrapolationReproducesPolynomialsUpToItsOrder) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> coef(-3, 3);
  for (int order = 0; order <= kMaxPolynomialOrder; ++order) {
    for (int degree = 0; degree <= order; ++degree) {
      std::vector<double> c(degree + 1);
      for (auto& x : c) x = coef(gen);
      // samples at s = 0, -1, -2, ... (the past macro times), as the master uses them
      std::vector<double> s;
      std::vector<Value> v;
      for (int i = order; i >= 0; --i) {
        s.push_back(-i);
        v.push_back({poly(c, -i)});
      }
      const auto p = fit_polynomial(SignalKind::Scalar, s, v, order, s.size() - 1);
      for (double t : {0.0, 0.25, 0.5, 1.0})
        EXPECT_NEAR(p.evaluate(t)[0], poly(c, t), 1e-12 * (1 + std::abs(poly(c, t))))
            << "order " << order << " degree " << degree << " s " << t;
    }
    // and a polynomial of degree order+1 is NOT reproduced: the check can fail
    std::vector<double> c(order + 2, 0.0);
    c.back() = 1.0;
    std::vector<double> s;
    std::vector<Value> v;
    for (int i = order; i >= 0; --i) s.push_back(-i), v.push_back({poly(c, -i)});
    const auto p = fit_polynomial(SignalKind::Scalar, s, v, order, s.size() - 1);
    EXPECT_GT(std::abs(p.evaluate(1.0)[0] - poly(c, 1.0)), 0.5);
  }
}

TEST(Polynomial, LeastSquaresIsExactForLowDegreeAndAveragesNoise) {
  // 6 samples of a line fitted with order 1: exact
  std::vector<double> s;
  std::vector<Value> v;
  for (int i = 5; i >= 0; --i) s.push_back(-i), v.push_back({2.0 - 0.5 * (-i)});
  auto p = fit_polynomial(SignalKind::Scalar, s, v, 1, s.size() - 1);
  EXPECT_NEAR(p.evaluate(1.0)[0], 1.5, 1e-13);
  // alternating noise +-1 on a constant: order 0 over 6 samples gives the mean
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = {10.0 + (i % 2 ? 1.0 : -1.0)};
  p = fit_polynomial(SignalKind::Scalar, s, v, 0, s.size() - 1);
  EXPECT_NEAR(p.evaluate(0.5)[0], 10.0, 1e-13);
}

TEST(Polynomial, OrientationIsPredictedOnTheRotationGroup) {
  // Constant angular velocity about a tilted axis: q(t) = q0 exp(w t). A linear polynomial in
  // the rotation vector relative to the latest sample reproduces it exactly; component-wise
  // linear extrapolation of the quaternion would not stay on the unit sphere.
  const Quat q0 = quat_normalized({0.9, 0.1, -0.3, 0.2});
  const Vec3 w{0.8, -1.1, 0.4};  // rad per macro step, large on purpose
  auto at = [&](double t) { return quat_multiply(q0, quat_exp({w[0] * t, w[1] * t, w[2] * t})); };
  std::vector<double> s{-1, 0};
  std::vector<Value> v;
  for (double t : s) {
    const Quat q = at(t);
    v.push_back(Kinematics{{1, 2, 3}, q, {0, 0, 0}, w}.to_value());
  }
  const auto p = fit_polynomial(SignalKind::Kinematics, s, v, 1, 1);
  for (double t : {0.3, 1.0}) {
    const Quat got = Kinematics::from_value(p.evaluate(t)).orientation;
    const Quat want = at(t);
    const double dot = got[0] * want[0] + got[1] * want[1] + got[2] * want[2] + got[3] * want[3];
    EXPECT_NEAR(std::abs(dot), 1.0, 1e-12) << "t = " << t;
    EXPECT_NEAR(quat_norm(got), 1.0, 1e-14);
  }
}

TEST(Polynomial, WireRoundTripAndValidation) {
  Polynomials in;
  const Wrench f{{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
  const Kinematics k{{1, 2, 3}, {1, 0, 0, 0}, {}, {}};
  in["f"] = InputPolynomial::constant(SignalKind::Wrench, f.to_value());
  in["k"] = InputPolynomial::constant(SignalKind::Kinematics, k.to_value());
  in["s"] = InputPolynomial::constant(SignalKind::Scalar, {4.5});
  auto msg = to_message(in);
  auto out = from_message(msg, "test");
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out["f"].evaluate(0.3), in["f"].evaluate(0.3));
  EXPECT_EQ(out["s"].evaluate(1.0)[0], 4.5);
  msg.kinematics[0].orientation_reference[0] = 2.0;
  EXPECT_THROW(from_message(msg, "test"), ProtocolError);
  msg = to_message(in);
  msg.scalars[0].coefficients[0] = std::nan("");
  EXPECT_THROW(from_message(msg, "test"), ProtocolError);
  msg = to_message(in);
  msg.wrenches[0].n_coefficients = 7;
  EXPECT_THROW(from_message(msg, "test"), ProtocolError);
}

// Histopolation (use: average): the means over the intervals [-1, 0], [-2, -1], ... of a
// polynomial up to the order are reproduced exactly, so is the polynomial itself; the mean over
// [0, 1] of the fit is InputPolynomial::mean.
namespace {
// Exact mean of the polynomial c over [a, b].
double mean_of(const std::vector<double>& c, double a, double b) {
  double m = 0;
  for (std::size_t j = 0; j < c.size(); ++j)
    m += c[j] * (std::pow(b, j + 1.0) - std::pow(a, j + 1.0)) / ((j + 1.0) * (b - a));
  return m;
}
}  // namespace

TEST(Polynomial, HistopolationReproducesPolynomialsUpToItsOrder) {
  std::mt19937 gen(9);
  std::uniform_real_distribution<double> coef(-3, 3);
  for (int order = 0; order <= kMaxPolynomialOrder; ++order) {
    for (int degree = 0; degree <= order; ++degree) {
      std::vector<double> c(degree + 1);
      for (auto& x : c) x = coef(gen);
      for (int extra : {0, 3}) {  // exact, and least squares over more intervals
        std::vector<std::pair<double, double>> iv;
        std::vector<Value> v;
        for (int i = order + extra; i >= 0; --i) {
          iv.push_back({-i - 1.0, -i * 1.0});
          v.push_back({mean_of(c, -i - 1.0, -i)});
        }
        const auto p = fit_polynomial_to_means(SignalKind::Scalar, iv, v, order);
        for (double t : {0.0, 0.25, 0.5, 1.0})
          EXPECT_NEAR(p.evaluate(t)[0], poly(c, t), 1e-11 * (1 + std::abs(poly(c, t))))
              << "order " << order << " degree " << degree << " extra " << extra;
        EXPECT_NEAR(p.mean()[0], mean_of(c, 0.0, 1.0), 1e-11 * (1 + std::abs(poly(c, 1.0))));
      }
    }
    // the end-sample fit of the same means is a different polynomial (the check can fail)
    std::vector<double> c(order + 1, 0.0);
    c.back() = 1.0;
    std::vector<std::pair<double, double>> iv;
    std::vector<Value> v;
    for (int i = order; i >= 0; --i) iv.push_back({-i - 1.0, -i * 1.0}), v.push_back({mean_of(c, -i - 1.0, -i)});
    if (order > 0) {
      std::vector<double> s;
      for (int i = order; i >= 0; --i) s.push_back(-i);
      const auto q = fit_polynomial(SignalKind::Scalar, s, v, order, s.size() - 1);
      EXPECT_GT(std::abs(q.evaluate(1.0)[0] - poly(c, 1.0)), 0.1) << order;
    }
  }
  // one interval, the current step (an iterated step): the constant with that mean
  const auto p = fit_polynomial_to_means(SignalKind::Wrench, {{0.0, 1.0}},
                                         {{1, 2, 3, 4, 5, 6, 0, 0, 0}}, 0);
  EXPECT_EQ(p.mean(), (Value{1, 2, 3, 4, 5, 6, 0, 0, 0}));
  EXPECT_EQ(p.evaluate(0.3), p.mean());
}

TEST(Polynomial, HistopolationRefusesKinematicsAndBadIntervals) {
  const Value pose{0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  EXPECT_THROW(fit_polynomial_to_means(SignalKind::Kinematics, {{-1.0, 0.0}}, {pose}, 0),
               std::invalid_argument);
  EXPECT_THROW(fit_polynomial_to_means(SignalKind::Scalar, {{-1.0, 0.0}}, {{1.0}}, 1),
               std::invalid_argument);
  EXPECT_THROW(fit_polynomial_to_means(SignalKind::Scalar, {{0.0, 0.0}}, {{1.0}}, 0),
               std::invalid_argument);
  EXPECT_THROW(fit_polynomial_to_means(SignalKind::Scalar, {{-1.0, 0.0}, {-1.0, 0.0}}, {{1.0}, {2.0}}, 1),
               std::invalid_argument);
  EXPECT_THROW(InputPolynomial::constant(SignalKind::Kinematics, pose).mean(), std::invalid_argument);
}
