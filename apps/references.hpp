#pragma once
/// \file references.hpp
/// Closed-form and numerically exact references of `weft validate` (docs/validation.md).
namespace weft::app::reference {

/// Inextensible elastica of a cantilever of length L clamped horizontally at s = 0 and bent by
/// its own weight w per unit length (Euler's elastica; Frisch-Fay 1962, "Flexible Bars", ch. 3):
///   D theta''(s) = -w (L - s) cos theta(s),  theta(0) = 0,  theta'(L) = 0,
/// with theta the slope below the horizontal, solved by shooting on theta'(0) with RK4.
/// Depends on alpha = w L^3 / D alone; returns the tip's drop and horizontal reach per L.
struct Elastica {
  double drop;   ///< vertical deflection of the tip / L
  double reach;  ///< horizontal distance of the tip from the clamp / L
  double tip_slope;  ///< theta(L) [rad]
};
Elastica cantilever_elastica(double alpha);

/// The load alpha = w l^3 / D at which the chord from the clamp to the tip of a cantilever of
/// length l makes `chord_angle` with the horizontal (ASTM D1388's 41.5 degrees; Peirce 1930
/// gives alpha = 8 from an approximation of the same elastica, so that the bending length
/// c = (D / w)^(1/3) is half the overhang).
double elastica_alpha_at_chord_angle(double chord_angle);

/// Out-of-plane deflection of the free end of a circular-arc cantilever (radius R, opening
/// angle phi, clamped at one end) under a distributed load q per unit length normal to its
/// plane, small deflections: bending and torsion both work (curved beams loaded normal to
/// their plane, Roark's Formulas for Stress and Strain, ch. 9; by Castigliano's theorem with
/// a unit load at the tip; at the angle a from the free end the load beyond gives the bending
/// moment q R^2 (1 - cos a) and the torque q R^2 (a - sin a), the unit load R sin a and
/// R (1 - cos a)):
///   delta = q R^4 [ (1 - cos phi)^2 / (2 EI) + (phi - sin phi)^2 / (2 GJ) ].
double arc_cantilever_deflection(double phi, double R, double q, double bending, double torsion);

/// Isotropic St. Venant-Kirchhoff sheet in uniaxial stress along x (S_yy = 0): the Green
/// strains satisfy E_yy = -nu E_xx, so the lateral stretch is sqrt(1 - nu (lambda^2 - 1))
/// (docs/methods/shells.md §3.1; linear elasticity would give 1 - nu (lambda - 1)).
double stvk_uniaxial_lateral_stretch(double lambda, double nu);

/// A block sliding down an incline of angle `angle` with Coulomb friction mu: acceleration
/// g (sin angle - mu cos angle) when tan angle > mu, else 0 (it sticks).
double incline_acceleration(double g, double angle, double mu);

}  // namespace weft::app::reference
