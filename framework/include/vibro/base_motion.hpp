#pragma once
/// \file base_motion.hpp
/// Base (support) excitation: the rig the masses hang from moves by a prescribed displacement
///
///     x_b(t) = Σ_k ( a_k cos(k Ω t) + b_k sin(k Ω t) ),   k ≥ 1 whole, distinct,
///
/// (Ω the forcing frequency, so T = 2π/Ω stays the period) and drives the masses through the
/// springs and dashpots that tie them to it. Its reach is the influence vector ι: the
/// displacement of the coordinates when the whole rig, base included, moves rigidly by one unit
/// (ι = 1 for a chain between walls: every mass moves with the walls). Such a rigid motion
/// strains no spring, so the force that the base's springs and dashpots exert is K ι x_b + C ι x_b'
/// and the equations of motion in absolute coordinates x read
///
///     M x'' + C x' + K x = f(t) + K ι x_b(t) + C ι x_b'(t).                      (absolute)
///
/// With the relative coordinates y = x − ι x_b (the motion seen from the rig) the same equations
/// become
///
///     M y'' + C y' + K y = f(t) − M ι x_b''(t)                                  (relative)
///
/// (the base's inertial force; the influence-vector form of support excitation in A. K. Chopra,
/// Dynamics of Structures, chapter on multi-degree-of-freedom systems under ground motion).
/// Both right-hand sides are again finite sums of harmonics of Ω, so the flows stay exact: for
/// the harmonic k with a_k, b_k and ω = k Ω,
///
///     absolute: cosine += K ι a_k + C ι b_k ω,   sine += K ι b_k − C ι a_k ω,
///     relative: cosine += M ι ω² a_k,            sine += M ι ω² b_k.
///
/// Stops. A stop is fixed in the laboratory unless it is attached to the base, when its
/// position moves by c_j x_b(t), c_j = (the stop's coordinate combination)ᵀ ι: ι_i for a stop on
/// mass i (upper or lower), ι_i − ι_k for a stop between masses i and k, nᵀι along a normal n.
/// In the relative frame the roles swap: a stop attached to the base stands still and a stop fixed
/// in the laboratory moves by −c_j x_b(t). A stop that moves so takes x_b's first harmonic as its
/// amplitude and phase and its orders ≥ 2 as its higher harmonics (stops.hpp). Gaps, impact
/// velocities and Newton's law are the same in both frames (g = wᵀx − s(t) = wᵀy − (s(t) −
/// c x_b(t))), so the two formulations give the same motion, x(t) = y(t) + ι x_b(t),
/// v_x(t) = v_y(t) + ι x_b'(t).
///
/// Usage:
///     vibro::BaseExcitation b{.displacement = {{1, 0.05, 0.0}, {2, 0.01, 0.0}},
///                             .influence = ι, .stiffness = K * ι, .damping = C * ι,
///                             .inertia = M * ι, .frame = vibro::BaseFrame::absolute};
///     vibro::add_base_forcing(f, b);          // f: the HarmonicForcing of the system
///     vibro::move_stops_with_base(stops, attached, b);
#include "vibro/stops.hpp"
#include "vibro/system.hpp"

#include <vector>

namespace vibro {

/// One harmonic a cos(k Ω t) + b sin(k Ω t) of the base displacement, k ≥ 1.
struct BaseHarmonic {
  int order = 1;
  double cosine = 0.0;
  double sine = 0.0;
};

/// The frame the equations are written in: absolute x, or relative y = x − ι x_b.
enum class BaseFrame { absolute, relative };

struct BaseExcitation {
  std::vector<BaseHarmonic> displacement;  ///< x_b(t), distinct orders ≥ 1
  Eigen::VectorXd influence;               ///< ι (length n)
  Eigen::VectorXd stiffness;               ///< K ι: the springs to the base
  Eigen::VectorXd damping;                 ///< C ι: the dashpots to the base
  Eigen::VectorXd inertia;                 ///< M ι
  BaseFrame frame = BaseFrame::absolute;

  /// x_b(t), x_b'(t), x_b''(t) at forcing frequency Ω.
  double position(double frequency, double t) const;
  double velocity(double frequency, double t) const;
  double acceleration(double frequency, double t) const;
  /// Whether x_b has a nonzero harmonic of order ≥ 2.
  bool has_higher_harmonics() const;
  /// a_1, b_1 (zero when order 1 is not given).
  double first_cosine() const;
  double first_sine() const;

  /// Throws InvalidInput when an order is < 1 or repeated, a value is not finite or a vector does
  /// not have n entries.
  void validate(Eigen::Index n) const;
};

/// Adds the base's drive to f (absolute: K ι x_b + C ι x_b'; relative: −M ι x_b''), harmonic by
/// harmonic (orders ≥ 2 join f.harmonics of the same order or are appended, even when zero, so
/// the shape of f does not depend on the amplitudes). f.frequency is Ω.
void add_base_forcing(HarmonicForcing& f, const BaseExcitation& base);

/// d/dΩ of the part add_base_forcing adds, at Ω = f.frequency, in the same layout as f after
/// add_base_forcing (constant zero; harmonics of f's orders, zero where the base has none).
HarmonicForcing base_forcing_rate(const HarmonicForcing& f, const BaseExcitation& base);

/// c_j: how far the stop's position moves per unit base displacement when attached to the base.
double base_coefficient(const Stop& stop, const Eigen::VectorXd& influence);

/// Makes the stops move as the frame requires (absolute: those attached move by c_j x_b;
/// relative: those not attached move by −c_j x_b; x_b's orders ≥ 2 join the stop's harmonics,
/// even when zero). attached has one entry per stop. Throws InvalidInput "stops[j] (name): …"
/// when such a stop already moves on its own (amplitude > 0).
void move_stops_with_base(std::vector<Stop>& stops, const std::vector<bool>& attached, const BaseExcitation& base);

}  // namespace vibro
