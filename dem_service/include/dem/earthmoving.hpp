// Reece's fundamental earthmoving equation for a wide blade in dry cohesionless soil without
// surcharge: F = gamma d^2 N_gamma w, the force on the blade per width w at depth d, inclined at
// the soil-blade friction angle delta to the blade's normal; its horizontal part (the draft) is
// F sin(alpha + delta). N_gamma from the Coulomb trial wedge (a plane failure surface from the
// blade tip to the free surface at angle beta), minimised over beta. Independent of the DEM.
// docs/soil.md: derivation, closed forms, citations.
#pragma once

namespace dem {

// Angles in radians. alpha: rake angle, between the blade and the horizontal (pi/2 = vertical
// blade; smaller = the blade leans back, the soil rides up it). phi: soil internal friction
// angle; delta: soil-blade friction angle.
struct WedgeResult {
  double n_gamma = 0;  // F / (gamma d^2 w)
  double beta = 0;     // failure-plane angle to the horizontal at the minimum, rad
  // Draft (horizontal) and vertical parts of the force on the blade per gamma d^2 w:
  // horizontal = n_gamma sin(alpha + delta), vertical = n_gamma cos(alpha + delta) (the soil
  // pushes the blade down when positive).
  double horizontal = 0, vertical = 0;
};

// The wedge's force per gamma d^2 w for a given failure-plane angle beta, from the equilibrium of
// the wedge's weight, the blade's reaction (at delta to its normal) and the soil's reaction on
// the failure plane (at phi to its normal), solved as a 2x2 linear system. Returns +inf where the
// wedge cannot be in equilibrium with positive reactions.
double wedge_force(double alpha, double phi, double delta, double beta);

// McKyes' closed form of the same equilibrium (McKyes 1985):
// N = (cot alpha + cot beta) / (2 [cos(alpha + delta) + sin(alpha + delta) cot(beta + phi)]).
double wedge_force_closed_form(double alpha, double phi, double delta, double beta);

// Minimises wedge_force over beta in (0, pi/2) (a scan, then golden-section refinement to
// 1e-12 rad). Throws std::invalid_argument naming the angle for alpha outside (0, pi/2],
// phi outside (0, pi/2), delta outside [0, phi] or a non-finite value.
WedgeResult passive_wedge(double alpha, double phi, double delta);

// Rankine's passive coefficient tan^2(pi/4 + phi/2): the smooth vertical wall gives
// N_gamma = K_p / 2.
double rankine_kp(double phi);

// Coulomb's passive coefficient for a wall inclined theta from the vertical and a level
// backfill (NAVFAC DM 7.02 form): cos^2(phi + theta) / (cos^2 theta cos(theta - delta)
// (1 - sqrt(sin(phi + delta) sin phi / (cos(theta - delta) cos theta)))^2).
double coulomb_kp(double phi, double delta, double theta);

// Reece's equation for dry cohesionless soil: horizontal draft force in N for unit weight
// gamma (N/m^3), depth d (m), width w (m).
double reece_draft(double gamma, double depth, double width, double alpha, double phi, double delta);

}  // namespace dem
