#pragma once
/// \file contact.hpp
/// What a contact set (the stops active at once) implies, derived on first use and cached.
///
/// For a set S with normals W = [w_j]_{j∈S} (n × m) and Delassus matrix G = Wᵀ M⁻¹ W:
///
/// * Restitution (generalised Newton law). Impulses Λ ≥ 0 act along -W:
///       v⁺ = v⁻ - M⁻¹ W Λ,     g'⁺ = g'⁻ - G Λ,
///   with the complementarity 0 ≤ Λ ⊥ G Λ - (I + R) g'⁻ ≥ 0, R = diag(r_j). When every stop of S
///   takes an impulse this is g'⁺ = -R g'⁻ and, for fixed stops,
///       v⁺ = R_S v⁻,   R_S = I - M⁻¹ W G⁻¹ (I + R) Wᵀ,
///   which for the paper's system is Wagg (2004) eq. (8): R1, R2, R3; in modal coordinates
///   Ψ⁻¹ R_S Ψ (eq. 10). Where contacts couple (stops between masses, a full M) some Λ_j of the
///   combined law can be negative; the LCP then decides which stops take an impulse.
///
/// * Sticking subsystem. Stuck stops hold Wᵀ x = s(t). Split the coordinates into m dependent
///   ones D (chosen by column-pivoted QR of Wᵀ, so that A = Wᵀ_D is well conditioned) and free
///   ones F: x_D = A⁻¹ (s(t) - Wᵀ_F x_F). Hence
///       x = N y + P s(t),   y = x_F,   N = [I; -A⁻¹ Wᵀ_F] (rows F; D),   P = [0; A⁻¹],
///   and y obeys  NᵀMN y'' + NᵀCN y' + NᵀKN y = Nᵀ (f - M P s'' - C P s' - K P s),
///   again of the form F0 + Fc cos Ωt + Fs sin Ωt, so it has an exact LinearFlow. For stops on
///   single masses the reduced coordinates are the free masses themselves: with mass 1 stuck
///   this is Wagg's eq. (11), with mass 2 stuck eq. (14) (whose static solution is x1 = +s2/2,
///   not the -s2/2 printed in eq. (16)).
///
/// * Contact forces, from Wᵀ x'' = s'':   λ = G⁻¹ (Wᵀ M⁻¹ (f - C v - K x) - s''),
///   λ_j ≥ 0 while stop j holds. For the paper: with mass 1 stuck (lower stop, s1 < 0) λ = -F2 of
///   eq. (12); with mass 2 stuck (upper stop, s2 > 0) λ = +F1 of eq. (15) (plus A2 cos Ωt when
///   A2 ≠ 0): the paper's F carries the sign of s_i, F_i s_i > 0 while the stop holds.
///   Which stops stay active after an event is the solution of the acceleration LCP
///       0 ≤ λ ⊥ G λ - q ≥ 0,   q = Wᵀ M⁻¹ (f - C v - K x) - s''   (free gap acceleration).
///
/// * Engaged compliant stops (stops.hpp, Stop::Law::compliant). A set may also name compliant
///   stops; they are engaged (penetrated, g > 0) rather than held. Each engaged stop j adds
///   k_j w_j w_jᵀ to K, c_j w_j w_jᵀ to C and w_j (k_j s_j(t) + c_j s_j'(t) − F_p,j) to f, i.e.
///       constant += w (k s0 − F_p),  cosine += w (k sc + c Ω ss),  sine += w (k ss − c Ω sc),
///   before the held rigid stops reduce the system as above (so a rigid stop can be held while
///   a compliant one is engaged: a two-stage stop). The restitution data and the contact forces
///   are those of the held rigid stops only (active()); engaged() lists the compliant ones.
///
/// Each ContactMode builds its restitution data on construction (cheap: m×m) and its reduced
/// flow only when first asked for, so sets that are only impacted never pay for a sticking flow.
#include "vibro/flow.hpp"
#include "vibro/stops.hpp"

#include <atomic>
#include <map>
#include <memory>
#include <vector>

namespace vibro {

/// Sorted indices of the stops in a set. As a mode's key (ContactModes::get) it names the held
/// rigid stops and the engaged compliant stops together.
using ContactSet = std::vector<int>;

/// Solves 0 ≤ λ ⊥ G λ - q ≥ 0 for symmetric positive definite G (Murty's least-index principal
/// pivoting, finite for P-matrices; K. G. Murty, "Note on a Bard-type scheme for solving the
/// complementarity problem", Opsearch 11, 1974). Throws std::runtime_error after 2^m·m pivots.
Eigen::VectorXd solve_lcp(const Eigen::MatrixXd& G, const Eigen::VectorXd& q);

/// Storage for solve_lcp on up to m stops; after reserve(m) the solve allocates nothing.
struct LcpWorkspace {
  Eigen::MatrixXd sub, factor;
  Eigen::VectorXd q_sub, lambda_sub, slack;
  std::vector<Eigen::Index> basis;
  std::vector<char> basic;
  void reserve(Eigen::Index m);
};

/// The same LCP (same pivoting, same tolerances) into `lambda` (size q.size()), without
/// allocating once `work` is reserved for q.size() stops (the event loops' form).
void solve_lcp(const Eigen::Ref<const Eigen::MatrixXd>& G, const Eigen::Ref<const Eigen::VectorXd>& q,
               Eigen::Ref<Eigen::VectorXd> lambda, LcpWorkspace& work);

class ContactMode {
 public:
  /// `active`: the mode's key, held rigid stops and engaged compliant stops (sorted).
  /// `interrupt` (SimulatorOptions::interrupt, may be null): the flow of a large subsystem is
  /// built under run_bounded (bounded_wait.hpp), so that raising it interrupts the build.
  ContactMode(const ImpactSystem& scene, ContactSet active, FlowOptions flow_options,
              const std::atomic<bool>* interrupt = nullptr);

  /// The held rigid stops (the constraints; size(), the restitution data and the contact forces
  /// refer to them).
  const ContactSet& active() const { return active_; }
  /// The engaged compliant stops (their springs and dashpots are in the mode's K, C, f).
  const ContactSet& engaged() const { return engaged_; }
  Eigen::Index size() const { return static_cast<Eigen::Index>(active_.size()); }

  // --- restitution ---
  /// G = Wᵀ M⁻¹ W (m × m).
  const Eigen::MatrixXd& delassus() const { return delassus_; }
  /// M⁻¹ W (n × m).
  const Eigen::MatrixXd& mass_inverse_normals() const { return minv_w_; }
  /// R_S of the combined Newton law (n × n), for fixed stops all taking an impulse.
  const Eigen::MatrixXd& restitution_matrix() const { return restitution_; }

  // --- sticking subsystem (built on first call) ---
  struct Reduced {
    std::vector<Eigen::Index> free;       ///< F, full indices of the reduced coordinates y
    std::vector<Eigen::Index> dependent;  ///< D
    Eigen::MatrixXd mass, damping, stiffness;  ///< NᵀMN, NᵀCN, NᵀKN
    HarmonicForcing forcing;                   ///< reduced right-hand side
    Eigen::MatrixXd to_full;   ///< T: full augmented state = T · reduced augmented state
    std::unique_ptr<LinearFlow> flow;
    /// Rows (reduced augmented space): gap g_j of each stop neither held nor engaged, then -λ_j
    /// of each held rigid stop of S, then -g_j of each engaged compliant stop, in the order of
    /// `watched`. An event is a crossing of a row from ≤ 0 to > 0.
    std::unique_ptr<Functionals> watch;
    std::vector<int> watched;  ///< stop index of each watch row
    Eigen::Index gap_rows = 0;  ///< the first gap_rows rows are gaps, the next size() are -λ
    Eigen::Index engaged_rows_from = 0;  ///< rows from here on are -g of the engaged stops
    Eigen::MatrixXd force_rows;  ///< λ of the stops in S as rows in the full augmented space
  };
  const Reduced& reduced() const;
  bool reduced_built() const { return reduced_ != nullptr; }

  /// Reduced augmented state [x_F; v_F; cos; sin; 1] from a full state (the dependent
  /// coordinates are implied, so rounding drift off the constraint is projected away).
  Eigen::VectorXd reduce(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                         const Eigen::Ref<const Eigen::VectorXd>& v) const;
  /// The same into `out` (size reduced().flow->size()), without allocating.
  void reduce(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
              const Eigen::Ref<const Eigen::VectorXd>& v, Eigen::Ref<Eigen::VectorXd> out) const;
  /// The full augmented state T·z_r from a reduced one (the empty set's T is the identity),
  /// without allocating; `full` has size 2n + 3 and may not alias `reduced_state`.
  void expand(const Eigen::Ref<const Eigen::VectorXd>& reduced_state, Eigen::Ref<Eigen::VectorXd> full) const;
  /// The full system's positions and velocities [x; v] as functionals of the reduced augmented
  /// state (the first 2n rows of T), for states asked for at many times (DenseSegmentView::state,
  /// through Segment::evaluate: T and the flow's basis folded into one table). Built on first
  /// call, so a mode whose states no observer asks for never pays for it.
  const Functionals& state_rows() const;

 private:
  void build_reduced() const;

  const ImpactSystem* scene_;
  ContactSet active_;
  ContactSet engaged_;
  FlowOptions flow_options_;
  const std::atomic<bool>* interrupt_ = nullptr;
  Eigen::MatrixXd normals_;  // W (n × m)
  Eigen::MatrixXd delassus_, minv_w_, restitution_;
  mutable std::unique_ptr<Reduced> reduced_;
  mutable std::unique_ptr<Functionals> state_rows_;  // after reduced_: it points into its flow
};

/// The lazily built modes of one scene, keyed by contact set. Not thread-safe: each simulation
/// (each sweep point's thread) owns its own cache.
class ContactModes {
 public:
  ContactModes(const ImpactSystem& scene, FlowOptions flow_options = {}, const std::atomic<bool>* interrupt = nullptr)
      : scene_(&scene), flow_options_(flow_options), interrupt_(interrupt) {}
  const ContactMode& get(const ContactSet& set);
  std::size_t built() const { return modes_.size(); }
  /// Number of modes whose sticking subsystem has been built.
  std::size_t reduced_built() const;
  const ImpactSystem& scene() const { return *scene_; }

 private:
  const ImpactSystem* scene_;
  FlowOptions flow_options_;
  const std::atomic<bool>* interrupt_ = nullptr;
  std::map<ContactSet, std::unique_ptr<ContactMode>> modes_;
};

}  // namespace vibro
