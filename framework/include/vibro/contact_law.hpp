#pragma once
/// \file contact_law.hpp
/// The contact-law seam: what a constraint's law contributes to the hybrid event loop
/// (simulator.hpp's procedure, written once for both engines in framework/src/event_loop.hpp).
///
/// A constraint j (a stop on the normal n_j with motion p_j(t), or a frictional contact) has, whatever
/// its law, four faces:
///
///  1. Guards. Scalars of the state and time whose sign says on which side of a switch the motion
///     is; an event is a guard rising above its trigger ε (events.hpp's certified search). Each
///     law says which guard watches it in each of its states:
///        rigid stop, open:      the gap       g_j = n_jᵀx − p_j(t)            (a row ℓᵀz of the flow)
///        rigid stop, held:      the pull      −λ_j (the contact force along the sticking flow)
///        compliant stop, open:  the gap g_j;  engaged: −g_j (it opens when the gap reopens)
///        Coulomb friction, slipping: ±(relative velocity) (it sticks when it reaches 0);
///                          stuck: |f_t| − μ_s N (it slips when the holding force reaches the limit)
///     Every guard is a linear functional of the mode's exact state (or of its modal state), so
///     the search's guarantee of events.hpp holds for it without change.
///  2. Resolution. What happens when a guard fires (GuardCrossing below): the rigid stop's
///     impact is Newton's law through the impulse LCP, v⁺ = v⁻ − M⁻¹W Λ with W the normals of the
///     impacting and held stops (contact.hpp), chatter ended by the chatter rule, then the
///     acceleration LCP says which stops hold (event_resolution.hpp, resolve_event, on the
///     engine's ContactAlgebra). A compliant stop's engagement has no impulse: the state is
///     continuous and only the mode changes. Friction sticks when the force needed to hold stays
///     within μ_s N and slips otherwise.
///  3. Mode contribution. Which pieces of M, C, K, f are in force between events. A held rigid
///     stop constrains n_jᵀx = p_j(t): the mode's flow is the reduced one on the constraint
///     manifold (ContactModes, flow.hpp; ModalContactMode, modal.hpp), and its force row −λ_j is a
///     functional of the reduced state. An engaged compliant stop adds k_s n nᵀ to K, c_s n nᵀ to
///     C and n (k_s p(t) + c_s p'(t) − F_p) to f (stops.hpp; contact.cpp): a linear flow again,
///     built like any other mode (engaged_system.hpp for the dense and the Taylor engine; the
///     modal engine's own modes when the dashpot keeps the damping proportional, modal.hpp). A
///     stuck frictional contact is a held constraint on the tangential velocity; a slipping one
///     adds the constant force −μ_k N sign(v_t) along its tangent.
///  4. Saltation. The jump of the linearised flow across the event, S = ∂(x⁺, v⁺)/∂(x⁻, v⁻)
///     + (f⁺ − S f⁻) ∂τ/∂(x⁻, v⁻) (di Bernardo et al. 2008, ch. 7): for the rigid impact
///     S = I − (1 + r) M⁻¹n nᵀ/(nᵀM⁻¹n) on v plus the time-shift term (the analysis layer,
///     linearisation.hpp); for a compliant stop's engagement or disengagement S = I + (f⁺ − f⁻)
///     wᵀ/ġ at g = 0 (the identity without dashpot or preload, where the vector field is
///     continuous), on every engine's tangent map.
///
/// The event loop does not know which law it handles: it asks the law of each fired guard what
/// its crossing means (transition), which stops touching at the start are impacts and which are
/// resting (initial_contact), and hands the sets to the engine, which resolves them (face 2) and
/// enters the next mode (face 3). The mode is the set of constraints in their non-default state
/// (held, engaged, stuck): the held rigid stops and the engaged compliant stops (ContactSet;
/// ContactMode splits it by law). A fired guard of a compliant stop asks for engage or
/// disengage; the frame hands those to the engine in its impact and release sets, and the
/// engine tells them from impacts and releases by the stop's law (Stop::is_compliant).
///
/// Where a new law plugs in: its guards and mode pieces where each engine builds a mode's flow
/// (flow.cpp's ContactModes for the dense engine, modal_modes.cpp for the modal engine,
/// taylor_simulator.cpp's step terms for the Taylor engine), its
/// resolution in event_resolution.cpp, its transitions here, its saltation in the analysis layer.
#include "vibro/contact.hpp"

namespace vibro {

/// Which face of its constraint a guard row watches (the rows of a mode are ordered: every
/// open constraint's guard first, then every held one's).
enum class GuardKind {
  opening,  ///< an open constraint's guard (a rigid stop's gap): it fires on closing
  holding,  ///< a held constraint's guard (a rigid stop's pull −λ): it fires on letting go
};

/// What a guard's crossing asks of the event resolution.
enum class Transition {
  impact,     ///< the constraint closes with a normal speed (Newton's law, then maybe held)
  release,    ///< the held constraint lets go (its force would turn into a pull)
  engage,     ///< a compliant stop's gap turns positive: its spring and dashpot join the flow
  disengage,  ///< an engaged compliant stop's gap returns to zero: they leave it
};

/// A stop touching (within the trigger) at the start of a run: not at all, approaching (an
/// impact at t0), or resting on it (a candidate for holding).
enum class InitialContact { none, impact, resting };

/// The rigid (Newton) stop: impacts with restitution r, held while its contact force pushes.
struct RigidStopLaw {
  /// The crossing of a guard of this kind (face 1 → face 2).
  static constexpr Transition transition(GuardKind kind) {
    return kind == GuardKind::opening ? Transition::impact : Transition::release;
  }
  /// A stop at gap g (≤ 0 open) with normal rate g' at the start: touching within `eps_gap`,
  /// it is an impact if approaching faster than `v_contact`, resting within ±v_contact.
  static constexpr InitialContact initial_contact(double gap, double rate, double eps_gap, double v_contact) {
    if (gap < -eps_gap) return InitialContact::none;
    if (rate > v_contact) return InitialContact::impact;
    if (rate >= -v_contact) return InitialContact::resting;
    return InitialContact::none;
  }
};

/// The compliant (Kelvin–Voigt) stop of stops.hpp: engaged while its gap g > 0, no impulse.
/// Its guards are g while open and −g while engaged, both located by the certified search; the
/// switch leaves the state as it is. Which compliant stops start engaged is decided from the
/// initial gap alone (engaged_at_start), never by the rigid stop's impact or resting test.
struct CompliantStopLaw {
  static constexpr Transition transition(GuardKind kind) {
    return kind == GuardKind::opening ? Transition::engage : Transition::disengage;
  }
  static constexpr bool engaged_at_start(double gap) { return gap > 0.0; }
};

}  // namespace vibro
