#include "dem/lab/triaxial.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "cosim/yaml_config.hpp"
#include "dem/stability.hpp"

namespace dem::lab {
namespace cfg = cosim::config;

namespace {

constexpr double kDeg = 180.0 / M_PI;

double positive(const YAML::Node& n, const std::string& path, const std::string& key,
                double fallback, const std::string& unit) {
  if (!n || !n[key]) return fallback;
  const double v = cfg::get_double(n, path, key);
  if (!(v > 0) || !std::isfinite(v)) {
    std::ostringstream msg;
    msg << path << "." << key << ": must be > 0 " << unit << ", got " << n[key].Scalar();
    throw cfg::ConfigError(msg.str());
  }
  return v;
}

// The rate that gives inertial number I at pressure p: I = rate d sqrt(rho / p).
double rate_for(const Grains& g, double inertial, double p) {
  return inertial / (2 * g.mean_radius() * std::sqrt(g.density / p));
}

struct Servo {
  BoxRig& rig;
  Engine& engine;
  State& s;
  double dt, gain;
  std::array<double, 6> sum{};
  std::array<double, 6> integral{};
  long n = 0;
  // Share of the proportional speed added to the integral speed each step: the integral part
  // takes about 1 / kIntegral steps to learn a steady speed.
  static constexpr double kIntegral = 0.03;

  // One step; faces with servo[f] follow target[f] at up to vmax[f], the others move inward at
  // fixed[f] m/s.
  void step(const std::array<double, 6>& target, const std::array<bool, 6>& servo,
            const std::array<double, 6>& speed) {
    rig.before_step(engine, s);
    engine.step(s);
    for (int f = 0; f < 6; ++f) {
      const double sig = rig.stress(engine, f);
      sum[static_cast<std::size_t>(f)] += sig;
      double v = speed[static_cast<std::size_t>(f)];
      if (servo[static_cast<std::size_t>(f)]) {
        const double k0 = rig.contact_stiffness(s, f);
        const Species& sp = engine.scene().species[0];
        const double kmin = engine.scene().particle_wall.stiffness_per_length
                                ? engine.scene().particle_wall.normal_stiffness * sp.radius.min
                                : engine.scene().particle_wall.normal_stiffness;
        // Proportional part from the contact stiffness (stable below gain 1), plus an integral
        // part that learns the speed the face needs (a proportional servo alone lags the
        // dilating sample by an error proportional to that speed).
        const double vmax = speed[static_cast<std::size_t>(f)];
        const double vp = servo_speed(gain, rig.area(f), target[static_cast<std::size_t>(f)] - sig,
                                      std::max(k0, kmin), dt, vmax);
        double& vi = integral[static_cast<std::size_t>(f)];
        vi = std::clamp(vi + kIntegral * vp, -vmax, vmax);
        v = std::clamp(vp + vi, -vmax, vmax);
      }
      rig.move(f, v * dt);
    }
    ++n;
  }
  std::array<double, 6> mean_and_reset() {
    std::array<double, 6> m{};
    for (int f = 0; f < 6; ++f) m[static_cast<std::size_t>(f)] = n ? sum[static_cast<std::size_t>(f)] / n : 0;
    sum.fill(0);
    n = 0;
    return m;
  }
};

// All six faces servoed to p until the window means of two windows in a row are within tol.
// Returns the simulated time.
double consolidate(BoxRig& rig, Engine& engine, State& s, double p, double gain, double vmax,
                   double tol, long max_steps, const std::string& what, const std::string& section,
                   const Progress& progress) {
  const double dt = engine.scene().dt;
  Servo servo{rig, engine, s, dt, gain};
  std::array<double, 6> target, speed;
  target.fill(p);
  speed.fill(vmax);
  const std::array<bool, 6> all{true, true, true, true, true, true};
  const long window = 500;
  int good = 0;
  long steps = 0;
  while (true) {
    for (long k = 0; k < window; ++k) servo.step(target, all, speed);
    steps += window;
    const auto m = servo.mean_and_reset();
    double worst = 0;
    for (double v : m) worst = std::max(worst, std::abs(v - p) / p);
    good = worst < tol ? good + 1 : 0;
    if (progress && steps % (window * 20) == 0) {
      std::ostringstream line;
      line << what << ": t = " << steps * dt << " s, packing "
           << packing_fraction(s, rig.lo(), rig.hi()) << ", worst face off by " << 100 * worst
           << " %";
      progress(line.str());
    }
    if (good >= 2) return steps * dt;
    if (steps >= max_steps) {
      std::ostringstream msg;
      msg << what << ": the walls did not hold " << p << " Pa within " << 100 * tol << " % after "
          << steps << " steps (worst face off by " << 100 * worst
          << " %); raise " << section << ".max_consolidation_steps or " << section
          << ".tolerance, or lower " << section << ".servo_gain if the walls oscillate";
      throw std::runtime_error(msg.str());
    }
  }
}

}  // namespace

namespace {

// The triaxial and the biaxial test read the same keys, under `section`.
TriaxialOptions parse_test(const YAML::Node& root, const std::string& section) {
  cfg::check_keys(root, "", {"grains", "sample", section, "run"});
  TriaxialOptions o;
  o.section = section;
  const std::string& S = section;
  o.grains = parse_grains(root["grains"], "grains");
  const YAML::Node sm = root["sample"];
  if (sm) {
    cfg::check_keys(sm, "sample",
                    {"count", "seed", "initial_fraction", "preparation_friction", "aspect",
                     "thickness"});
    if (sm["aspect"]) {
      o.aspect = cfg::get_double(sm, "sample", "aspect");
      if (!(o.aspect >= 0.5 && o.aspect <= 4))
        throw cfg::ConfigError("sample.aspect: " + sm["aspect"].Scalar() +
                               " is outside 0.5 .. 4 (the sample's height over its width; 1 a "
                               "cube, 2 a biaxial sample whose shear band can leave through the "
                               "sides)");
    }
    if (sm["thickness"]) {
      o.thickness = cfg::get_double(sm, "sample", "thickness");
      if (!(o.thickness >= 0.1 && o.thickness <= 1))
        throw cfg::ConfigError("sample.thickness: " + sm["thickness"].Scalar() +
                               " is outside 0.1 .. 1 (the sample's extent along y over its width "
                               "along x; below 1 a slab, as thin as a plane-strain bin)");
    }
    if (sm["count"]) {
      o.count = cfg::get_int(sm, "sample", "count");
      if (o.count < 50 || o.count > 2000000)
        throw cfg::ConfigError("sample.count: " + std::to_string(o.count) +
                               " grains is outside 50 .. 2000000; a triaxial sample needs at "
                               "least a few hundred grains");
    }
    if (sm["seed"]) {
      const long long seed = cfg::get_int(sm, "sample", "seed");
      if (seed < 0) throw cfg::ConfigError("sample.seed: must be an integer >= 0");
      o.seed = static_cast<std::uint64_t>(seed);
    }
    o.initial_fraction = positive(sm, "sample", "initial_fraction", o.initial_fraction, "");
    if (o.initial_fraction > 0.35)
      throw cfg::ConfigError("sample.initial_fraction: " + std::to_string(o.initial_fraction) +
                             " is above 0.35, where random insertion stalls; the walls compact "
                             "the sample, start looser");
    if (sm["preparation_friction"]) {
      o.preparation_friction = cfg::get_double(sm, "sample", "preparation_friction");
      if (!(o.preparation_friction >= 0) || !std::isfinite(o.preparation_friction))
        throw cfg::ConfigError("sample.preparation_friction: must be >= 0 (0: frictionless, the "
                               "densest sample), got " + sm["preparation_friction"].Scalar());
    }
  }
  const YAML::Node t = root[S];
  if (!t) throw cfg::ConfigError(S + ": missing (expected at least confining_pressures)");
  cfg::check_keys(t, S,
                  {"confining_pressures", "inertial_number", "strain_rate", "max_axial_strain",
                   "record_every", "servo_gain", "tolerance", "max_consolidation_steps", "peak"});
  o.first_peak = section == "biaxial";
  if (t["peak"]) {
    const std::string v = t["peak"].IsScalar() ? t["peak"].Scalar() : std::string("(not a word)");
    if (v != "first" && v != "max")
      throw cfg::ConfigError(S + ".peak: '" + v + "' is not allowed (allowed: first, the largest "
                             "angle before the first softening; max, the largest over the test)");
    o.first_peak = v == "first";
  }
  const YAML::Node cp = t["confining_pressures"];
  if (!cp || !cp.IsSequence() || cp.size() == 0)
    throw cfg::ConfigError(S + ".confining_pressures: missing or empty (expected a list of "
                           "pressures in Pa, e.g. [10.0e3, 20.0e3, 40.0e3])");
  for (std::size_t i = 0; i < cp.size(); ++i) {
    const std::string p = S + ".confining_pressures." + std::to_string(i);
    double v;
    try {
      v = cp[i].as<double>();
    } catch (const YAML::Exception&) {
      throw cfg::ConfigError(p + ": expected a pressure in Pa, got '" + cp[i].Scalar() + "'");
    }
    if (!(v > 0) || !std::isfinite(v))
      throw cfg::ConfigError(p + ": a confining pressure must be > 0 Pa, got " + cp[i].Scalar());
    o.confining.push_back(v);
  }
  std::sort(o.confining.begin(), o.confining.end());
  for (std::size_t i = 1; i < o.confining.size(); ++i)
    if (o.confining[i] == o.confining[i - 1])
      throw cfg::ConfigError(S + ".confining_pressures: " + std::to_string(o.confining[i]) +
                             " Pa is given twice; give distinct pressures");
  o.inertial_number = positive(t, S, "inertial_number", o.inertial_number, "");
  if (o.inertial_number > 0.1)
    throw cfg::ConfigError(S + ".inertial_number: " + std::to_string(o.inertial_number) +
                           " is far from quasi-static (I < 1e-3 is, 1e-2 is the most a test may use)");
  if (t["strain_rate"]) o.strain_rate = positive(t, S, "strain_rate", 0, "1/s");
  o.max_axial_strain = positive(t, S, "max_axial_strain", o.max_axial_strain, "");
  if (o.max_axial_strain > 0.5)
    throw cfg::ConfigError(S + ".max_axial_strain: " + std::to_string(o.max_axial_strain) +
                           " is more than half the sample's height; give at most 0.5");
  o.record_every = positive(t, S, "record_every", o.record_every, "");
  if (o.record_every > o.max_axial_strain / 5)
    throw cfg::ConfigError(S + ".record_every: " + std::to_string(o.record_every) +
                           " leaves fewer than 5 records up to max_axial_strain; lower it");
  o.servo_gain = positive(t, S, "servo_gain", o.servo_gain, "");
  if (o.servo_gain >= 1)
    throw cfg::ConfigError(S + ".servo_gain: " + std::to_string(o.servo_gain) +
                           " is not below 1, where the wall overshoots every step; 0.05-0.3 works");
  o.tolerance = positive(t, S, "tolerance", o.tolerance, "");
  if (o.tolerance >= 0.5) throw cfg::ConfigError(S + ".tolerance: must be below 0.5 (a fraction)");
  if (t["max_consolidation_steps"]) {
    o.max_consolidation_steps = cfg::get_int(t, S, "max_consolidation_steps");
    if (o.max_consolidation_steps < 1000)
      throw cfg::ConfigError(S + ".max_consolidation_steps: must be at least 1000");
  }
  const YAML::Node r = root["run"];
  if (r) {
    cfg::check_keys(r, "run", {"threads"});
    if (r["threads"]) {
      o.threads = static_cast<int>(cfg::get_int(r, "run", "threads"));
      if (o.threads < 1 || o.threads > 256)
        throw cfg::ConfigError("run.threads: must be 1 .. 256");
    }
  }
  return o;
}

}  // namespace

TriaxialOptions parse_triaxial(const YAML::Node& root) { return parse_test(root, "triaxial"); }

TriaxialOptions parse_biaxial(const YAML::Node& root) {
  TriaxialOptions o = parse_test(root, "biaxial");
  o.plane_strain = true;
  return o;
}

MohrCoulombFit fit_mohr_coulomb(const std::vector<double>& s1, const std::vector<double>& s3) {
  MohrCoulombFit f;
  const std::size_t n = std::min(s1.size(), s3.size());
  if (n == 0) return f;
  double sst = 0, sss = 0, ss = 0, st = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double s = 0.5 * (s1[i] + s3[i]), t = 0.5 * (s1[i] - s3[i]);
    sst += s * t;
    sss += s * s;
    ss += s;
    st += t;
  }
  f.phi_origin = std::asin(std::clamp(sst / sss, -1.0, 1.0)) * kDeg;
  if (n >= 2) {
    const double N = static_cast<double>(n);
    const double den = N * sss - ss * ss;
    const double b = den != 0 ? (N * sst - ss * st) / den : 0;
    const double a = (st - b * ss) / N;
    f.phi = std::asin(std::clamp(b, -1.0, 1.0)) * kDeg;
    f.cohesion = a / std::cos(f.phi / kDeg);
    if (n >= 3 && den != 0) {
      double rss = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const double s = 0.5 * (s1[i] + s3[i]), t = 0.5 * (s1[i] - s3[i]);
        rss += (t - a - b * s) * (t - a - b * s);
      }
      const double se_b = std::sqrt(rss / (N - 2) * N / den);
      // d phi / d b = 1 / cos(phi)
      f.phi_stderr = se_b / std::cos(f.phi / kDeg) * kDeg;
    }
  } else {
    f.phi = f.phi_origin;
  }
  return f;
}

Sample prepare_sample(const TriaxialOptions& o, double pressure, const Progress& progress) {
  Scene scene = make_scene(o.grains, {0, 0, 0}, o.threads);
  scene.particle_particle.friction = o.preparation_friction;
  // A box L x thickness L x aspect L holding the grains at the initial fraction.
  const double L = std::cbrt(static_cast<double>(o.count) * o.grains.mean_volume() /
                             (o.initial_fraction * o.aspect * o.thickness));
  const Vec3 lo{0, 0, 0}, hi{L, o.thickness * L, o.aspect * L};
  if (o.thickness * L < 2.5 * 2 * o.grains.radius_max)
    throw cfg::ConfigError("sample.thickness: the sample would be " +
                           std::to_string(o.thickness * L) + " m thick, less than 2.5 grains " +
                           "after compaction; raise sample.count or sample.thickness");
  Sample out;
  const double r = o.grains.radius_max;
  insert_random(scene, out.state, lo + Vec3{r, r, r}, hi - Vec3{r, r, r}, o.count, o.seed,
                "sample.count");
  BoxRig rig(scene, lo, hi);
  validate_state(scene, out.state);
  Engine engine(scene);
  // Compaction: the walls close at most at the rate of inertial number 1e-2 at the target
  // pressure (ten times the test's default), slower when the servo says so.
  const double vmax = rate_for(o.grains, 1e-2, pressure) * L / 2;
  consolidate(rig, engine, out.state, pressure, o.servo_gain, vmax, o.tolerance,
              o.max_consolidation_steps, "preparation", o.section, progress);
  out.lo = rig.lo();
  out.hi = rig.hi();
  out.dt = scene.dt;
  return out;
}

TriaxialTest run_triaxial(const TriaxialOptions& o, const Sample& sample, double confining,
                          const Progress& progress) {
  Scene scene = make_scene(o.grains, {0, 0, 0}, o.threads);
  State s = sample.state;
  s.lists_valid = false;
  BoxRig rig(scene, sample.lo, sample.hi);
  Engine engine(scene);
  const double dt = scene.dt;
  TriaxialTest t;
  t.confining = confining;
  t.dt = dt;
  t.grains = static_cast<long>(s.size());
  t.strain_rate = o.strain_rate > 0 ? o.strain_rate : rate_for(o.grains, o.inertial_number, confining);
  t.inertial_number = t.strain_rate * 2 * o.grains.mean_radius() * std::sqrt(o.grains.density / confining);
  const double L0 = rig.size().z;
  // Consolidation with the test's friction: walls at most at the shearing rate x 5.
  const double vcons = 5 * t.strain_rate * L0 / 2;
  t.consolidation_time = consolidate(rig, engine, s, confining, o.servo_gain, vcons, o.tolerance,
                                     o.max_consolidation_steps, "consolidation", o.section,
                                     progress);
  t.packing = packing_fraction(s, rig.lo(), rig.hi());
  {
    const double m = 2 * o.grains.radius_max;
    t.packing_inner = packing_fraction(s, rig.lo() + Vec3{m, m, m}, rig.hi() - Vec3{m, m, m});
  }
  t.coordination = coordination(engine, s);

  // Shearing: z walls at constant speed, lateral walls servoed; in plane strain the y walls
  // stay where they are (speed 0, not servoed).
  const double H0 = rig.size().z, V0 = rig.volume();
  const double X0 = rig.size().x, Y0 = rig.size().y;
  const double va = t.strain_rate * H0 / 2;
  const bool ps = o.plane_strain;
  std::array<double, 6> target{}, speed{};
  std::array<bool, 6> servo{true, true, !ps, !ps, false, false};
  for (int f = 0; f < 4; ++f) {
    target[static_cast<std::size_t>(f)] = confining;
    speed[static_cast<std::size_t>(f)] = servo[static_cast<std::size_t>(f)] ? 10 * va : 0.0;
  }
  speed[4] = speed[5] = va;
  Servo sv{rig, engine, s, dt, o.servo_gain};
  double strain = 0, next = o.record_every, time = 0;
  TriaxialRecord start;
  t.curve.push_back(start);
  t.curve.back().packing = t.packing;
  t.curve.back().sigma1 = t.curve.back().sigma2 = t.curve.back().sigma3 = confining;
  while (strain < o.max_axial_strain - 1e-12) {
    sv.step(target, servo, speed);
    time += dt;
    strain = (H0 - rig.size().z) / H0;
    if (strain >= next - 1e-12) {
      const auto m = sv.mean_and_reset();
      TriaxialRecord r;
      r.axial_strain = strain;
      r.volumetric_strain = (V0 - rig.volume()) / V0;
      r.sigma1 = 0.5 * (m[4] + m[5]);
      r.sigma2 = 0.5 * (m[2] + m[3]);
      r.sigma3 = ps ? 0.5 * (m[0] + m[1]) : 0.25 * (m[0] + m[1] + m[2] + m[3]);
      for (int f = 0; f < 4; ++f)
        if (servo[static_cast<std::size_t>(f)] &&
            std::abs(m[static_cast<std::size_t>(f)] - confining) > std::abs(r.sigma3_worst))
          r.sigma3_worst = m[static_cast<std::size_t>(f)] - confining;
      r.strain2 = (Y0 - rig.size().y) / Y0;
      r.strain3 = (X0 - rig.size().x) / X0;
      r.packing = packing_fraction(s, rig.lo(), rig.hi());
      r.time = time;
      t.curve.push_back(r);
      next += o.record_every;
      if (progress && t.curve.size() % 10 == 0) {
        std::ostringstream line;
        line << "shear " << confining / 1e3 << " kPa: axial strain " << strain << ", q "
             << r.q() / 1e3 << " kPa, volumetric strain " << r.volumetric_strain << ", phi "
             << std::asin(r.sin_phi()) * kDeg << " deg";
        progress(line.str());
      }
    }
  }
  // Peak, end, servo. The largest mobilised angle over the test, and the first peak: the
  // largest before the angle first falls more than kFirstPeakDrop below its running maximum
  // (after a softening, a small sample between rigid walls can harden again as its shear band
  // runs into them: the biaxial rig's; docs/soil_lab.md).
  constexpr double kFirstPeakDrop = 3.0;  // deg
  double best = -1, first = -1;
  std::size_t imax = 0, ifirst = 0;
  bool softened = false;
  for (std::size_t i = 1; i < t.curve.size(); ++i) {
    const TriaxialRecord& r = t.curve[i];
    if (r.sin_phi() > best) {
      best = r.sin_phi();
      imax = i;
    }
    if (!softened) {
      if (r.sin_phi() > first) {
        first = r.sin_phi();
        ifirst = i;
      } else if (std::asin(std::clamp(r.sin_phi(), -1.0, 1.0)) * kDeg <
                 std::asin(std::clamp(first, -1.0, 1.0)) * kDeg - kFirstPeakDrop) {
        softened = true;
      }
    }
    // The first records hold the jump from the isotropic state; the servo is judged after 0.5 %.
    if (r.axial_strain > 0.005)
      t.servo_worst = std::max(t.servo_worst, std::abs(r.sigma3_worst) / confining);
  }
  t.phi_max = std::asin(std::clamp(best, -1.0, 1.0)) * kDeg;
  t.phi_first_peak = std::asin(std::clamp(first, -1.0, 1.0)) * kDeg;
  t.peak = o.first_peak ? ifirst : imax;
  t.phi_peak = o.first_peak ? t.phi_first_peak : t.phi_max;
  {
    const TriaxialRecord& pk = t.curve[t.peak];
    t.sigma2_peak = pk.sigma2;
    t.b_peak = pk.sigma1 > pk.sigma3 ? (pk.sigma2 - pk.sigma3) / (pk.sigma1 - pk.sigma3) : 0;
  }
  // Peak dilatancy up to the peak: centred differences over 4 records (0.8 % of axial strain by
  // default), so that one record's jump as a band forms does not set the maximum.
  const std::size_t n = t.curve.size();
  for (std::size_t i = 2; i + 2 < n && i <= t.peak; ++i) {
    const TriaxialRecord &a = t.curve[i - 2], &b = t.curve[i + 2];
    const double de1 = b.axial_strain - a.axial_strain;
    const double dev = b.volumetric_strain - a.volumetric_strain;
    const double de3 = b.strain3 - a.strain3;
    if (!(de1 > 0)) continue;
    t.dilatancy_max = std::max(t.dilatancy_max, -dev / de1);
    if (de1 - de3 > 0)
      t.psi_max = std::max(t.psi_max, std::asin(std::clamp(-dev / (de1 - de3), -1.0, 1.0)) * kDeg);
  }
  const std::size_t from = std::max<std::size_t>(1, n - std::max<std::size_t>(2, (n - 1) / 4));
  double sp = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = from; i < n; ++i) {
    const double x = t.curve[i].axial_strain, y = t.curve[i].volumetric_strain;
    sp += t.curve[i].sin_phi();
    t.sigma1_end += t.curve[i].sigma1;
    t.sigma3_end += t.curve[i].sigma3;
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  const double m = static_cast<double>(n - from);
  t.sigma1_end /= m;
  t.sigma3_end /= m;
  t.phi_end = std::asin(std::clamp(sp / m, -1.0, 1.0)) * kDeg;
  const double den = m * sxx - sx * sx;
  t.dilatancy_end = den != 0 ? (m * sxy - sx * sy) / den : 0;
  t.critical = o.max_axial_strain >= 0.1 && std::abs(t.dilatancy_end) < 0.05;
  return t;
}

}  // namespace dem::lab
