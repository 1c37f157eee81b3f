// The particle model a scene runs (docs/physics.md "Rotation", docs/soil_models.md): spheres
// that only translate (the paper's, the default) or spheres that also rotate, with a rolling
// resistance. Plain data, kept apart from dem/rotation.hpp so that Scene can hold it.
#pragma once

namespace dem {

enum class ParticleModel {
  translating,  // 3 DOF per particle: today's engine, bit for bit
  rotating,     // 6 DOF: angular velocity, torques from the tangential force and rolling resistance
};

// Rolling resistance of the rotating model, for every contact (particle-particle, wall, tool).
// epsd: the elastic-plastic spring-dashpot model ("model C" of Ai, Chen, Rotter and Ooi 2011,
// Powder Technology 206, 269-282): a rolling spring torque M_k with stiffness
// k_r = stiffness_factor * k_N * friction^2 * R_r^2, capped at friction * R_r * F_n (full
// mobilisation), plus a dashpot -C_r w_r with C_r = damping * 2 sqrt(I_r k_r) while the spring is
// below the cap (none at full mobilisation, their f = 0). none: no rolling resistance.
struct RollingResistance {
  enum class Kind { none, epsd } kind = Kind::none;
  double friction = 0;            // mu_r, dimensionless (rolling radius times it is the lever)
  double stiffness_factor = 2.25; // Ai et al.'s 3D value
  double damping = 0;             // eta_r, fraction of the critical rolling damping, in [0, 1]
};

struct RotationOptions {
  ParticleModel model = ParticleModel::translating;
  RollingResistance rolling;
  bool rotating() const { return model == ParticleModel::rotating; }
};

}  // namespace dem
