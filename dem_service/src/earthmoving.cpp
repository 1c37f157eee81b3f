#include "dem/earthmoving.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace dem {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void check_angles(double alpha, double phi, double delta) {
  auto fail = [](const char* name, double v, const char* range) {
    std::ostringstream m;
    m << name << " = " << v * 180 / M_PI << " deg is outside " << range;
    throw std::invalid_argument(m.str());
  };
  if (!std::isfinite(alpha) || !(alpha > 0) || alpha > M_PI / 2 + 1e-12)
    fail("rake angle alpha", alpha, "(0, 90] deg");
  if (!std::isfinite(phi) || !(phi > 0) || !(phi < M_PI / 2))
    fail("friction angle phi", phi, "(0, 90) deg");
  if (!std::isfinite(delta) || !(delta >= 0) || delta > phi + 1e-12)
    fail("soil-blade friction angle delta", delta, "[0, phi] deg");
}

}  // namespace

double wedge_force(double alpha, double phi, double delta, double beta) {
  // Unit width, gamma = 1, depth 1. Blade tip at the origin, travel along +x, soil surface at
  // z = 1. The blade runs from the tip back and up, direction b = (-cos a, sin a); the failure
  // plane from the tip forward and up, f = (cos beta, sin beta). The wedge is the triangle tip,
  // blade top (-cot a, 1), surface exit (cot beta, 1): weight (cot a + cot beta) / 2.
  const double W = 0.5 * (std::cos(alpha) / std::sin(alpha) + std::cos(beta) / std::sin(beta));
  // Blade on soil: along the blade's normal into the soil n_b = (sin a, cos a), turned by delta
  // against the soil's motion up the blade (along b): p = n_b cos delta - b sin delta.
  const double px = std::sin(alpha) * std::cos(delta) + std::cos(alpha) * std::sin(delta);
  const double pz = std::cos(alpha) * std::cos(delta) - std::sin(alpha) * std::sin(delta);
  // Soil below on the wedge: along the plane's normal into the wedge n_f = (-sin beta, cos beta),
  // turned by phi against the wedge's motion up the plane (along f): r = n_f cos phi - f sin phi.
  const double rx = -std::sin(beta) * std::cos(phi) - std::cos(beta) * std::sin(phi);
  const double rz = std::cos(beta) * std::cos(phi) - std::sin(beta) * std::sin(phi);
  // P p + R r + (0, -W) = 0.
  const double det = px * rz - pz * rx;
  if (!(std::abs(det) > 1e-15)) return kInf;
  const double P = (0 * rz - W * rx) / det;  // Cramer: [px rx; pz rz] [P; R] = [0; W]
  const double R = (px * W - pz * 0) / det;
  if (!(P > 0) || !(R > 0)) return kInf;
  return P;
}

double wedge_force_closed_form(double alpha, double phi, double delta, double beta) {
  const double cot_a = std::cos(alpha) / std::sin(alpha), cot_b = std::cos(beta) / std::sin(beta);
  const double cot_bp = std::cos(beta + phi) / std::sin(beta + phi);
  return (cot_a + cot_b) / (2 * (std::cos(alpha + delta) + std::sin(alpha + delta) * cot_bp));
}

WedgeResult passive_wedge(double alpha, double phi, double delta) {
  check_angles(alpha, phi, delta);
  // Scan, then golden section around the best sample (the force is unimodal in beta where the
  // reactions are positive).
  constexpr int kScan = 2000;
  double best = kInf, best_beta = 0;
  for (int k = 1; k < kScan; ++k) {
    const double b = (M_PI / 2) * k / kScan;
    const double f = wedge_force(alpha, phi, delta, b);
    if (f < best) {
      best = f;
      best_beta = b;
    }
  }
  if (!std::isfinite(best))
    throw std::invalid_argument("passive wedge: no failure plane in equilibrium (alpha, phi, delta)");
  double lo = std::max(1e-9, best_beta - M_PI / 2 / kScan), hi = std::min(M_PI / 2, best_beta + M_PI / 2 / kScan);
  const double g = (std::sqrt(5.0) - 1) / 2;
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = wedge_force(alpha, phi, delta, x1), f2 = wedge_force(alpha, phi, delta, x2);
  while (hi - lo > 1e-12) {
    if (f1 < f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - g * (hi - lo);
      f1 = wedge_force(alpha, phi, delta, x1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + g * (hi - lo);
      f2 = wedge_force(alpha, phi, delta, x2);
    }
  }
  WedgeResult r;
  r.beta = 0.5 * (lo + hi);
  r.n_gamma = std::min(best, wedge_force(alpha, phi, delta, r.beta));
  r.horizontal = r.n_gamma * std::sin(alpha + delta);
  r.vertical = r.n_gamma * std::cos(alpha + delta);
  return r;
}

double rankine_kp(double phi) {
  const double t = std::tan(M_PI / 4 + phi / 2);
  return t * t;
}

double coulomb_kp(double phi, double delta, double theta) {
  const double c = std::cos(phi + theta);
  const double q = std::sin(phi + delta) * std::sin(phi) / (std::cos(theta - delta) * std::cos(theta));
  const double s = 1 - std::sqrt(q);
  return c * c / (std::cos(theta) * std::cos(theta) * std::cos(theta - delta) * s * s);
}

double reece_draft(double gamma, double depth, double width, double alpha, double phi, double delta) {
  if (!(gamma > 0) || !(depth > 0) || !(width > 0) || !std::isfinite(gamma * depth * width))
    throw std::invalid_argument("reece_draft: unit weight, depth and width must be > 0");
  return gamma * depth * depth * width * passive_wedge(alpha, phi, delta).horizontal;
}

}  // namespace dem
