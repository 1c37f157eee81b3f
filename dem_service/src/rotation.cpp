#include "dem/rotation.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "cosim/yaml_config.hpp"
#include "dem/pair_kernel.hpp"
#include "dem/stability.hpp"

namespace dem {
namespace cfg = cosim::config;
using cfg::ConfigError;

namespace {

// The checks shared by the config and programmatic scenes; `fail` throws the caller's type.
template <class Fail>
void check_rotation(const Scene& sc, Fail&& fail) {
  const RotationOptions& o = sc.rotation;
  const RollingResistance& r = o.rolling;
  if (!o.rotating()) {
    if (r.kind != RollingResistance::Kind::none)
      fail("particles.rolling_resistance: needs particles.model: rotating (spheres that do not "
           "rotate cannot roll); set particles.model: rotating or remove rolling_resistance");
    return;
  }
  if (r.kind == RollingResistance::Kind::none) return;
  std::ostringstream m;
  if (!(r.friction > 0) || !std::isfinite(r.friction)) {
    m << "particles.rolling_resistance.friction: must be a coefficient > 0 (mu_r, e.g. 0.1: the "
         "rolling torque is capped at mu_r R F_n), got "
      << r.friction << "; for no rolling resistance set rolling_resistance.model: none";
    fail(m.str());
  }
  if (r.friction > 1) {
    m << "particles.rolling_resistance.friction: " << r.friction
      << " is above 1 (a lever longer than the rolling radius); soils use 0.05 to 0.5";
    fail(m.str());
  }
  if (!(r.stiffness_factor > 0) || !std::isfinite(r.stiffness_factor)) {
    m << "particles.rolling_resistance.stiffness_factor: must be > 0 (k_r = factor k_N mu_r^2 "
         "R_r^2; Ai et al. 2011 use 2.25), got "
      << r.stiffness_factor;
    fail(m.str());
  }
  if (!(r.damping >= 0 && r.damping <= 1)) {
    m << "particles.rolling_resistance.damping: must be a fraction of the critical rolling "
         "damping in [0, 1] (e.g. 0.3; 0 = none), got "
      << r.damping;
    fail(m.str());
  }
}

}  // namespace

void parse_rotation(const YAML::Node& parts, Scene& sc) {
  RotationOptions o;
  if (parts && parts.IsMap()) {
    const std::string model = cfg::get_choice(parts, "particles", "model",
                                              {"translating", "rotating"}, "translating");
    o.model = model == "rotating" ? ParticleModel::rotating : ParticleModel::translating;
    if (const YAML::Node rr = parts["rolling_resistance"]) {
      const std::string p = "particles.rolling_resistance";
      if (!rr.IsMap())
        throw ConfigError(p + ": expected a map {model: epsd, friction: 0.1, damping: 0.3}");
      cfg::check_keys(rr, p, {"model", "friction", "stiffness_factor", "damping"});
      const std::string kind = cfg::get_choice(rr, p, "model", {"none", "epsd"}, "epsd");
      o.rolling.kind =
          kind == "epsd" ? RollingResistance::Kind::epsd : RollingResistance::Kind::none;
      o.rolling.friction = cfg::get_double_or(rr, p, "friction", o.rolling.friction);
      o.rolling.stiffness_factor =
          cfg::get_double_or(rr, p, "stiffness_factor", o.rolling.stiffness_factor);
      o.rolling.damping = cfg::get_double_or(rr, p, "damping", o.rolling.damping);
      if (o.rolling.kind == RollingResistance::Kind::none && o.model == ParticleModel::translating)
        o.rolling = RollingResistance{};  // "none" asks for nothing
    }
  }
  sc.rotation = o;
  check_rotation(sc, [](const std::string& m) { throw ConfigError(m); });
}

void validate_rotation(const Scene& sc) {
  check_rotation(sc, [](const std::string& m) { throw std::invalid_argument(m); });
}

double rotating_contact_period(const Scene& sc, std::string* which) {
  double best = INFINITY;
  if (!sc.rotation.rotating()) return best;
  const std::vector<SizeProbe> probes = size_probes(sc);
  auto consider = [&](double t, const std::string& what) {
    if (t < best) {
      best = t;
      if (which) *which = what;
    }
  };
  // Tangential oscillation with free spins: the contact point's mass is
  // 1 / (1/m_i + r_i^2/I_i + 1/m_j + r_j^2/I_j) = 2/7 of m* for solid spheres.
  auto both = [&](const ContactLaw& law, double len, double mt, double rr, double ir,
                  const std::string& what) {
    const ContactCoefficients c = coefficients(law, len, mt);
    if (c.kt > 0) consider(M_PI / std::sqrt(c.kt / mt), what + " (tangential, rotating)");
    const RollingCoefficients k = rolling_coefficients(sc.rotation.rolling, c.k, rr, ir);
    if (k.kr > 0) consider(M_PI / std::sqrt(k.kr / ir), what + " (rolling spring)");
  };
  for (const SizeProbe& a : probes) {
    const double ia = moment_of_inertia(a.m, a.r);
    for (const SizeProbe& b : probes) {
      const double ib = moment_of_inertia(b.m, b.r);
      const double len = a.r * b.r / (a.r + b.r);
      const double mt = 1 / (1 / a.m + a.r * a.r / ia + 1 / b.m + b.r * b.r / ib);
      const double ir = 1 / (1 / (ia + a.m * a.r * a.r) + 1 / (ib + b.m * b.r * b.r));
      std::ostringstream w;
      w << "sphere-sphere " << a.name << " r=" << a.r << " / " << b.name << " r=" << b.r;
      both(sc.particle_particle, len, mt, len, ir, w.str());
    }
    if (!sc.walls.empty() || !sc.tools.empty()) {
      const double mt = 1 / (1 / a.m + a.r * a.r / ia), ir = ia + a.m * a.r * a.r;
      std::ostringstream w;
      w << "sphere-wall " << a.name << " r=" << a.r;
      both(sc.particle_wall, a.r, mt, a.r, ir, w.str());
      for (const ContactLaw& law : sc.boundary_laws) both(law, a.r, mt, a.r, ir, w.str());
    }
  }
  return best;
}

void Rotation::size_arrays(State& s) {
  const std::size_t n = s.size();
  if (s.w.size() != n) s.w.resize(n, Vec3{});
  if (s.wu.size() != n) s.wu.resize(n, Vec3{});
}

void Rotation::pair_forces(const Scene& sc, State& s, std::vector<Vec3>& force,
                           ContactStats& stats, const detail::PairSleep* sleep) {
  const std::size_t n = s.size();
  size_arrays(s);
  if (s.pair_roll.size() != s.pair_j.size()) s.pair_roll.assign(s.pair_j.size(), Vec3{});
  force.resize(n);
  torque_.assign(n, Vec3{});
  const Vec3 g = sc.gravity;
  const double dt = sc.dt;
  const ContactLaw& law = sc.particle_particle;
  const RollingResistance& rr = sc.rotation.rolling;
  const Vec3* const X = s.x.data();
  const Vec3* const U = s.u.data();
  const Vec3* const WU = s.wu.data();
  const double* const R = s.radius.data();
  const double* const M = s.mass.data();
  Vec3* const F = force.data();
  Vec3* const T = torque_.data();
  // Sleeping (scene.sleep): the translating model's rules (detail::pair_rows_sleep), one thread.
  const std::int32_t* const REST = sleep ? sleep->rest : nullptr;
  const std::int32_t S = sleep ? sleep->steps : 0;
  auto wake = [&](std::size_t p) {
    if (!sleep->wake[p] && sleep->woken) sleep->woken->push_back(static_cast<std::int32_t>(p));
    sleep->wake[p] = 1;
  };
  for (std::size_t i = 0; i < n; ++i) F[i] = M[i] * g;
  stats.particle_contacts = 0;
  stats.max_overlap = 0;
  stats.max_overlap_ratio = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double ri = R[i], mi = M[i];
    const double ii = moment_of_inertia(mi, ri);
    const bool si = REST && REST[i] >= S;
    for (std::int32_t k = s.pair_offset[i]; k < s.pair_offset[i + 1]; ++k) {
      const std::size_t j = static_cast<std::size_t>(s.pair_j[k]);
      const bool sj = REST && REST[j] >= S;
      if (si && sj) continue;  // two sleepers: no force, both springs stay as they were
      Vec3& spring = s.pair_spring[k];
      Vec3& roll = s.pair_roll[k];
      const Vec3 d = X[i] - X[j];
      const double rj = R[j], rsum = ri + rj;
      const double d2 = norm2(d);
      const Vec3 urel = U[i] - U[j];
      // Spins do not change the normal speed at the contact ((w x n) . n = 0): the translating
      // screen holds.
      if (surely_apart(d2, rsum, norm2(urel), dt)) {
        // A sleeper whose contact with an awake particle ends may have lost its support.
        if ((si || sj) && (nonzero(spring) || nonzero(roll))) wake(si ? i : j);
        spring = Vec3{};
        roll = Vec3{};
        continue;
      }
      const double dist = std::sqrt(d2);
      const Vec3 nrm = (1.0 / dist) * d;
      const double overlap = rsum - dist;
      const double ai = ri - 0.5 * overlap, aj = rj - 0.5 * overlap;
      const Vec3 uc = urel - cross(ai * WU[i] + aj * WU[j], nrm);
      const double mj = M[j];
      const ContactCoefficients c = coefficients(law, ri * rj / rsum, mi * mj / (mi + mj));
      Vec3 f;
      if (!contact_force(law, c, overlap, nrm, uc, spring, dt, f)) {
        spring = Vec3{};
        roll = Vec3{};
        continue;
      }
      ++stats.particle_contacts;
      stats.max_overlap = std::max(stats.max_overlap, overlap);
      stats.max_overlap_ratio = std::max(stats.max_overlap_ratio, overlap / std::min(ri, rj));
      // Awake against asleep: the force and torques act on the awake particle only (the
      // sleeper, v = w = 0, is a fixed body for it); a partner whose centre or contact point
      // moves faster than scene.sleep.wake_speed relative to the sleeper wakes it.
      if ((si || sj) && (norm2(urel) > sleep->wake_speed2 || norm2(uc) > sleep->wake_speed2))
        wake(si ? i : j);
      if (!si) F[i] += f;
      if (!sj) F[j] -= f;
      // (c - x_i) x f with c - x_i = -a_i n; (c - x_j) x (-f) with c - x_j = a_j n.
      const Vec3 nf = cross(nrm, f);
      if (!si) T[i] -= ai * nf;
      if (!sj) T[j] -= aj * nf;
      if (rr.kind != RollingResistance::Kind::none) {
        const double ij = moment_of_inertia(mj, rj);
        const double ir = 1 / (1 / (ii + mi * ri * ri) + 1 / (ij + mj * rj * rj));
        const RollingCoefficients rc = rolling_coefficients(rr, c.k, ri * rj / rsum, ir);
        const Vec3 m = rolling_torque(rc, nrm, WU[i] - WU[j], dot(f, nrm), roll, dt);
        if (!si) T[i] += m;
        if (!sj) T[j] -= m;
      }
    }
  }
}

void Rotation::integrate(const Scene& sc, State& s) {
  const std::size_t n = s.size();
  const double dt = sc.dt;
  // With scene.sleep: the particles awake at the start of the step (rest_steps not yet updated).
  const std::int32_t* const REST =
      sc.sleep.enabled && s.rest_steps.size() == n ? s.rest_steps.data() : nullptr;
  const std::int32_t S = sc.sleep.steps;
  std::size_t bad = n;
  for (std::size_t i = 0; i < n; ++i) {
    if (REST && REST[i] >= S) continue;  // asleep: w = wu = 0 kept
    const double c = dt / moment_of_inertia(s.mass[i], s.radius[i]);
    const Vec3 dw = c * torque_[i];
    s.w[i] += dw;
    s.wu[i] = s.w[i] + 0.5 * dw;
    if (bad == n && !std::isfinite(norm2(s.w[i]))) bad = i;
  }
  if (bad < n) {
    // s.step + 1: the step this integration ends in (the translating one counts it after).
    std::ostringstream msg;
    msg << "blow-up at step " << s.step + 1 << " (t = " << (s.step + 1) * dt
        << " s): particle id " << s.id[bad]
        << " has a non-finite angular velocity (rotating model); lower scene.dt or soften the "
           "contact or rolling stiffness (particles.rolling_resistance.stiffness_factor)";
    throw SimulationError(msg.str());
  }
}

double rotational_energy(const State& s) {
  double e = 0;
  for (std::size_t i = 0; i < s.w.size() && i < s.size(); ++i)
    e += 0.5 * moment_of_inertia(s.mass[i], s.radius[i]) * norm2(s.w[i]);
  return e;
}

}  // namespace dem
