// The modal chain engine's event loop: free flight, impacts, chatter and sticking in modal
// coordinates (modal.hpp). ChainModes and BandedChain are in modal.cpp.
#include "vibro/modal.hpp"

#include "vibro/contact.hpp"  // solve_lcp
#include "vibro/engine.hpp"   // modal_options

#include "event_rate.hpp"
#include "event_resolution.hpp"

#include <Eigen/QR>

#include <algorithm>
#include <chrono>
#include <functional>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <stdexcept>

namespace vibro {
namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// The nonzero entries of a stop's normal w: (mass, weight) pairs.
struct Normal {
  Eigen::Index i = 0, k = -1;
  double wi = 1.0, wk = 0.0;
};

Normal normal_of(const Stop& s) {
  switch (s.kind) {
    case Stop::Kind::upper: return {s.mass, -1, 1.0, 0.0};
    case Stop::Kind::lower: return {s.mass, -1, -1.0, 0.0};
    case Stop::Kind::between: return {s.mass, s.other, 1.0, -1.0};
  }
  return {};
}

/// w_aᵀ M⁻¹ w_b for diagonal M.
double delassus_entry(const Normal& a, const Normal& b, const Eigen::VectorXd& mass) {
  double sum = 0.0;
  auto add = [&](Eigen::Index ia, double wa) {
    if (ia < 0) return;
    if (ia == b.i) sum += wa * b.wi / mass(ia);
    if (b.k >= 0 && ia == b.k) sum += wa * b.wk / mass(ia);
  };
  add(a.i, a.wi);
  add(a.k, a.wk);
  return sum;
}

/// Upper bound of h over [a, b] from the end values and slopes and B ≥ |h''| (events.hpp).
double upper_bound(double ha, double da, double hb, double db, double B, double L) {
  const double chord = std::max(ha, hb) + B * L * L / 8.0;
  const double from_a = std::max(ha, ha + da * L + 0.5 * B * L * L);
  const double from_b = std::max(hb, hb - db * L + 0.5 * B * L * L);
  return std::min({chord, from_a, from_b});
}

/// c0 + cc cos Ωt + cs sin Ωt.
struct Harmonic {
  double c0 = 0.0, cc = 0.0, cs = 0.0;
  Harmonic derivative(double W) const { return {0.0, W * cs, -W * cc}; }
  Harmonic& operator+=(const Harmonic& o) {
    c0 += o.c0;
    cc += o.cc;
    cs += o.cs;
    return *this;
  }
  friend Harmonic operator*(double a, const Harmonic& h) { return {a * h.c0, a * h.cc, a * h.cs}; }
};

Harmonic stop_motion(const Stop& s) { return {s.s0(), s.s_cos(), s.s_sin()}; }

double value_at(const Harmonic& h, double W, double t) {
  return h.c0 + h.cc * std::cos(W * t) + h.cs * std::sin(W * t);
}

bool contains(const ContactSet& s, int j) { return std::binary_search(s.begin(), s.end(), j); }

std::string stop_text(const std::vector<Stop>& stops, int j) {
  return "stops[" + std::to_string(j) + "] (" + stops[static_cast<std::size_t>(j)].name + ")";
}

/// out = K x for the chain's tridiagonal K. O(n).
void stiffness_times(const BandedChain& ch, const Eigen::VectorXd& x, Eigen::VectorXd& out) {
  const Eigen::Index n = ch.dof();
  out = ch.stiffness_diagonal.cwiseProduct(x);
  for (Eigen::Index i = 0; i + 1 < n; ++i) {
    out(i) += ch.stiffness_off(i) * x(i + 1);
    out(i + 1) += ch.stiffness_off(i) * x(i);
  }
}

/// K_{l,l'} of the tridiagonal K (0 off the band).
double stiffness_entry(const BandedChain& ch, Eigen::Index l, Eigen::Index lp) {
  if (l == lp) return ch.stiffness_diagonal(l);
  if (std::abs(l - lp) == 1) return ch.stiffness_off(std::min(l, lp));
  return 0.0;
}

/// Chains of at least this many masses build their contact sets' modes by the secular equation
/// (ModalSimulatorOptions::contact_modes = automatic): at N = 1000 both routes take ~0.05 s,
/// beyond it the tridiagonal one grows as N² in time and memory, the secular one in time only.
constexpr Eigen::Index kSecularFromMasses = 1000;

/// Builds the modal form of contact set `set` (modal.hpp, ModalContactMode), or returns null and
/// says why in `why_not` when the set is one the modal engine cannot reduce.
std::unique_ptr<ModalContactMode> build_mode(const ChainModes& free, const std::vector<Stop>& stops,
                                             const ContactSet& set, std::string* why_not,
                                             TridiagonalSolver route = TridiagonalSolver::automatic) {
  const auto start = std::chrono::steady_clock::now();
  auto mode = std::make_unique<ModalContactMode>();
  mode->stuck = set;
  const BandedChain& ch = free.chain();
  const Eigen::Index n = free.dof();
  const double W = free.frequency();
  const double alpha = ch.rayleigh_mass, beta = ch.rayleigh_stiffness;
  mode->coordinate.assign(static_cast<std::size_t>(n), -1);
  mode->o0 = Eigen::VectorXd::Zero(n);
  mode->oc = Eigen::VectorXd::Zero(n);
  mode->os = Eigen::VectorXd::Zero(n);
  // Groups of masses joined by held stops between neighbours: (first, last, fixing stop or -1).
  struct Group {
    Eigen::Index lo, hi;
    int fixer;
  };
  std::vector<Group> groups;
  std::vector<int> tie(static_cast<std::size_t>(n), -1), fixer(static_cast<std::size_t>(n), -1);
  if (set.empty()) {
    mode->modes = &free;
    for (Eigen::Index l = 0; l < n; ++l) {
      mode->coordinate[static_cast<std::size_t>(l)] = l;
      mode->first.push_back(l);
      mode->last.push_back(l);
    }
  } else {
    for (int j : set) {
      const Stop& s = stops[static_cast<std::size_t>(j)];
      if (s.kind == Stop::Kind::between) {
        if (std::abs(s.mass - s.other) != 1) {
          *why_not = stop_text(stops, j) + " would hold masses " + std::to_string(s.mass) + " and " +
                     std::to_string(s.other) +
                     ", which are not neighbours: the modal engine reduces a chain only by fixing "
                     "masses or joining neighbours (use the dense engine)";
          return nullptr;
        }
        auto& slot = tie[static_cast<std::size_t>(std::min(s.mass, s.other))];
        if (slot >= 0) {
          *why_not = stop_text(stops, slot) + " and " + stop_text(stops, j) +
                     " would both hold the same two masses (redundant contact forces)";
          return nullptr;
        }
        slot = j;
      } else {
        auto& slot = fixer[static_cast<std::size_t>(s.mass)];
        if (slot >= 0) {
          *why_not = stop_text(stops, slot) + " and " + stop_text(stops, j) +
                     " would both hold mass " + std::to_string(s.mass);
          return nullptr;
        }
        slot = j;
      }
    }
    Eigen::Index lo = 0;
    for (Eigen::Index l = 0; l < n; ++l) {
      if (l + 1 < n && tie[static_cast<std::size_t>(l)] >= 0) continue;
      int fixing = -1;
      for (Eigen::Index i = lo; i <= l; ++i) {
        const int f = fixer[static_cast<std::size_t>(i)];
        if (f < 0) continue;
        if (fixing >= 0) {
          *why_not = stop_text(stops, fixing) + " and " + stop_text(stops, f) + " would both hold masses " +
                     std::to_string(lo) + "…" + std::to_string(l) +
                     ", joined by held stops between them (redundant contact forces)";
          return nullptr;
        }
        fixing = f;
      }
      groups.push_back({lo, l, fixing});
      lo = l + 1;
    }
    // Offsets: x_l = y_r + o_l(t) in a free group (o = 0 at its first mass), x_l = o_l(t) in a
    // fixed one (o = s(t)/w at the held mass), propagated along the held stops between neighbours.
    auto set_o = [&](Eigen::Index l, const Harmonic& h) {
      mode->o0(l) = h.c0;
      mode->oc(l) = h.cc;
      mode->os(l) = h.cs;
    };
    auto get_o = [&](Eigen::Index l) { return Harmonic{mode->o0(l), mode->oc(l), mode->os(l)}; };
    for (const Group& g : groups) {
      Eigen::Index anchor = g.lo;
      if (g.fixer >= 0) {
        const Stop& s = stops[static_cast<std::size_t>(g.fixer)];
        anchor = s.mass;
        set_o(anchor, (s.kind == Stop::Kind::upper ? 1.0 : -1.0) * stop_motion(s));
      }
      for (Eigen::Index l = anchor; l < g.hi; ++l) {  // x_mass - x_other = s
        const Stop& s = stops[static_cast<std::size_t>(tie[static_cast<std::size_t>(l)])];
        Harmonic next = get_o(l);
        next += (s.mass == l ? -1.0 : 1.0) * stop_motion(s);
        set_o(l + 1, next);
      }
      for (Eigen::Index l = anchor - 1; l >= g.lo; --l) {
        const Stop& s = stops[static_cast<std::size_t>(tie[static_cast<std::size_t>(l)])];
        Harmonic next = get_o(l + 1);
        next += (s.mass == l ? 1.0 : -1.0) * stop_motion(s);
        set_o(l, next);
      }
      if (g.fixer < 0) {
        const auto r = static_cast<Eigen::Index>(mode->first.size());
        mode->first.push_back(g.lo);
        mode->last.push_back(g.hi);
        for (Eigen::Index l = g.lo; l <= g.hi; ++l) mode->coordinate[static_cast<std::size_t>(l)] = r;
      }
    }
    const auto nr = static_cast<Eigen::Index>(mode->first.size());
    if (nr > 0) {
      // Reduced chain: x = T y + o(t) with T_{l,r} = 1 for l in group r, so TᵀMT, TᵀKT are the
      // group sums (tridiagonal again), TᵀCT = α TᵀMT + β TᵀKT (still proportional) and the
      // forcing is Tᵀ(f - M o'' - C o' - K o), harmonic.
      const HarmonicForcing& f = ch.forcing;
      Eigen::VectorXd Ko0, Koc, Kos;
      stiffness_times(ch, mode->o0, Ko0);
      stiffness_times(ch, mode->oc, Koc);
      stiffness_times(ch, mode->os, Kos);
      const Eigen::ArrayXd m = ch.mass.array();
      const Eigen::VectorXd F0 = f.constant - Ko0;
      const Eigen::VectorXd Fc = (f.cosine.array() + W * W * m * mode->oc.array() -
                                  W * (alpha * m * mode->os.array() + beta * Kos.array()) - Koc.array())
                                     .matrix();
      const Eigen::VectorXd Fs = (f.sine.array() + W * W * m * mode->os.array() +
                                  W * (alpha * m * mode->oc.array() + beta * Koc.array()) - Kos.array())
                                     .matrix();
      BandedChain red;
      red.mass = Eigen::VectorXd::Zero(nr);
      red.stiffness_diagonal = Eigen::VectorXd::Zero(nr);
      red.stiffness_off = Eigen::VectorXd::Zero(nr - 1);
      red.rayleigh_mass = alpha;
      red.rayleigh_stiffness = beta;
      red.forcing = HarmonicForcing::zero(nr, W);
      for (Eigen::Index r = 0; r < nr; ++r) {
        const Eigen::Index a = mode->first[static_cast<std::size_t>(r)], b = mode->last[static_cast<std::size_t>(r)];
        for (Eigen::Index l = a; l <= b; ++l) {
          red.mass(r) += ch.mass(l);
          red.stiffness_diagonal(r) += ch.stiffness_diagonal(l) + (l < b ? 2.0 * ch.stiffness_off(l) : 0.0);
          red.forcing.constant(r) += F0(l);
          red.forcing.cosine(r) += Fc(l);
          red.forcing.sine(r) += Fs(l);
        }
        if (r + 1 < nr && b + 1 == mode->first[static_cast<std::size_t>(r + 1)])
          red.stiffness_off(r) = ch.stiffness_off(b);
      }
      // The reduced chain's modes: its own tridiagonal eigenproblem (O(n_r²) time and memory),
      // or the free modes restricted by the held stops (secular equation, O(k n²) time, O(k n)
      // memory; modal.hpp), the default for long chains.
      const bool secular = route == TridiagonalSolver::secular ||
                           (route == TridiagonalSolver::automatic && n >= kSecularFromMasses);
      try {
        if (secular) {
          ChainReduction reduction{mode->first, mode->last, {}};
          for (int j : set) {
            const Normal w = normal_of(stops[static_cast<std::size_t>(j)]);
            reduction.normals.push_back({{w.i, w.wi}});
            if (w.k >= 0) reduction.normals.back().push_back({w.k, w.wk});
          }
          mode->owned = std::make_unique<ChainModes>(std::move(red), free, std::move(reduction));
        } else {
          mode->owned = std::make_unique<ChainModes>(
              std::move(red), route == TridiagonalSolver::automatic ? free.solver() : route);
        }
      } catch (const InvalidInput& e) {
        *why_not = "the subsystem with the held stops cannot be put in modal form: " + std::string(e.what());
        return nullptr;
      } catch (const std::runtime_error& e) {
        *why_not = "the held stops' constraints cannot be imposed on the modes: " + std::string(e.what());
        return nullptr;
      }
      mode->modes = mode->owned.get();
    }
  }

  // Per mass: its row φ_l (x_l = φ_l·q + o_l) and its harmonic part X_l = φ_l·p(t) + o_l(t),
  // formed only for the masses a guard needs.
  const ChainModes* md = mode->modes;
  const Eigen::Index nr = mode->size();
  std::map<Eigen::Index, std::pair<Eigen::VectorXd, Harmonic>> rows;
  auto mass_row = [&](Eigen::Index l) -> const std::pair<Eigen::VectorXd, Harmonic>& {
    auto it = rows.find(l);
    if (it != rows.end()) return it->second;
    std::pair<Eigen::VectorXd, Harmonic> entry{Eigen::VectorXd::Zero(nr),
                                               {mode->o0(l), mode->oc(l), mode->os(l)}};
    const Eigen::Index r = mode->coordinate[static_cast<std::size_t>(l)];
    if (r >= 0) {
      entry.first = md->phi_row(r);
      entry.second += Harmonic{entry.first.dot(md->particular_constant()),
                               entry.first.dot(md->particular_cosine()),
                               entry.first.dot(md->particular_sine())};
    }
    return rows.emplace(l, std::move(entry)).first->second;
  };
  if (md && md->solver() == TridiagonalSolver::secular) {
    // Every row the guards below read, in one pass over the implicit modes: the masses of the
    // free stops' normals, and of the held groups with their neighbours (contact forces).
    std::set<Eigen::Index> masses;
    for (int j = 0; j < static_cast<int>(stops.size()); ++j) {
      const Normal w = normal_of(stops[static_cast<std::size_t>(j)]);
      if (!contains(set, j)) {
        masses.insert(w.i);
        if (w.k >= 0) masses.insert(w.k);
      } else {
        for (Eigen::Index l : {w.i, w.k})
          for (Eigen::Index lp = l - 1; l >= 0 && lp <= l + 1; ++lp)
            if (lp >= 0 && lp < n) masses.insert(lp);
      }
    }
    std::vector<Eigen::Index> wanted, coordinates;
    for (Eigen::Index l : masses)
      if (mode->coordinate[static_cast<std::size_t>(l)] >= 0) {
        wanted.push_back(l);
        coordinates.push_back(mode->coordinate[static_cast<std::size_t>(l)]);
      }
    // Groups: every mass of a held group (the force rows sum over them).
    const Eigen::MatrixXd phi = md->phi_rows(coordinates);
    for (std::size_t c = 0; c < wanted.size(); ++c) {
      const Eigen::Index l = wanted[c];
      std::pair<Eigen::VectorXd, Harmonic> entry{phi.row(static_cast<Eigen::Index>(c)).transpose(),
                                                 {mode->o0(l), mode->oc(l), mode->os(l)}};
      entry.second += Harmonic{entry.first.dot(md->particular_constant()), entry.first.dot(md->particular_cosine()),
                               entry.first.dot(md->particular_sine())};
      rows.emplace(l, std::move(entry));
    }
  }

  const auto m = static_cast<Eigen::Index>(stops.size());
  const auto held = static_cast<Eigen::Index>(set.size());
  ModalGuards& g = mode->guards;
  g.P = Eigen::MatrixXd::Zero(m, nr);
  g.D = Eigen::MatrixXd::Zero(held, nr);
  g.h0 = Eigen::VectorXd::Zero(m);
  g.hc = Eigen::VectorXd::Zero(m);
  g.hs = Eigen::VectorXd::Zero(m);
  auto set_harmonic = [&](Eigen::Index row, const Harmonic& h) {
    g.h0(row) = h.c0;
    g.hc(row) = h.cc;
    g.hs(row) = h.cs;
  };
  // Gaps of the stops not held: g_j = w_jᵀ x - s_j(t).
  for (int j = 0; j < static_cast<int>(m); ++j) {
    if (contains(set, j)) continue;
    const auto row = static_cast<Eigen::Index>(mode->watched.size());
    mode->watched.push_back(j);
    const Stop& s = stops[static_cast<std::size_t>(j)];
    const Normal w = normal_of(s);
    Harmonic h = -1.0 * stop_motion(s);
    for (const auto& [l, weight] : {std::pair{w.i, w.wi}, std::pair{w.k, w.wk}}) {
      if (l < 0) continue;
      const auto& [phi, X] = mass_row(l);
      g.P.row(row) += weight * phi.transpose();
      h += weight * X;
    }
    set_harmonic(row, h);
  }
  mode->gap_rows = static_cast<Eigen::Index>(mode->watched.size());
  mode->watched.insert(mode->watched.end(), set.begin(), set.end());
  // Contact forces of the held stops, group by group. With the residual of mass l
  //     ρ_l = m_l x_l'' + (C x')_l + (K x)_l - f_l(t) = -Σ_j W_lj λ_j   (M x'' + C x' + K x = f - W λ),
  // the held stops S_G of group G satisfy W_G λ_G = -ρ_G, |G| equations for |S_G| unknowns, of
  // full column rank and consistent (a free group's rows sum to its reduced equation, 0), so the
  // guard -λ_G = W_G⁺ ρ_G. In the homogeneous modal state x_l = φ_l·u + X_l(t) and
  // u'' = -2σ∘u' - ω²∘u give ρ_l = P_l·u + D_l·u' + harmonic, with
  //     P_l = -m_l φ_l∘ω² + Σ_l' K_ll' φ_l',   D_l = m_l (α - 2σ)∘φ_l + β Σ_l' K_ll' φ_l' = β P_l
  // (2σ = α + βω²): a force guard's D row is β times its P row.
  if (held > 0) {
    const Eigen::VectorXd w2 = md ? md->omega_squared() : Eigen::VectorXd(0);
    for (const Group& grp : groups) {
      std::vector<int> members;
      if (grp.fixer >= 0) members.push_back(grp.fixer);
      for (Eigen::Index l = grp.lo; l < grp.hi; ++l) members.push_back(tie[static_cast<std::size_t>(l)]);
      if (members.empty()) continue;
      const Eigen::Index size = grp.hi - grp.lo + 1;
      Eigen::MatrixXd Wg = Eigen::MatrixXd::Zero(size, static_cast<Eigen::Index>(members.size()));
      for (std::size_t c = 0; c < members.size(); ++c) {
        const Normal w = normal_of(stops[static_cast<std::size_t>(members[c])]);
        Wg(w.i - grp.lo, static_cast<Eigen::Index>(c)) += w.wi;
        if (w.k >= 0) Wg(w.k - grp.lo, static_cast<Eigen::Index>(c)) += w.wk;
      }
      const Eigen::MatrixXd pinv = Wg.completeOrthogonalDecomposition().pseudoInverse();
      Eigen::MatrixXd Pg = Eigen::MatrixXd::Zero(size, nr);
      std::vector<Harmonic> hg(static_cast<std::size_t>(size));
      for (Eigen::Index l = grp.lo; l <= grp.hi; ++l) {
        const Eigen::Index a = l - grp.lo;
        const auto [phi, X] = mass_row(l);
        if (nr > 0) Pg.row(a) = -ch.mass(l) * phi.cwiseProduct(w2).transpose();
        Harmonic h = ch.mass(l) * X.derivative(W).derivative(W);
        h += (alpha * ch.mass(l)) * X.derivative(W);
        for (Eigen::Index lp = std::max<Eigen::Index>(l - 1, 0); lp <= std::min(l + 1, n - 1); ++lp) {
          const double k = stiffness_entry(ch, l, lp);
          const auto& [phi_p, X_p] = mass_row(lp);
          if (nr > 0) Pg.row(a) += k * phi_p.transpose();
          h += k * X_p;
          h += (beta * k) * X_p.derivative(W);
        }
        h += Harmonic{-ch.forcing.constant(l), -ch.forcing.cosine(l), -ch.forcing.sine(l)};
        hg[static_cast<std::size_t>(a)] = h;
      }
      for (std::size_t c = 0; c < members.size(); ++c) {
        const auto a_idx = std::lower_bound(set.begin(), set.end(), members[c]) - set.begin();
        const Eigen::Index row = mode->gap_rows + a_idx;
        Harmonic h;
        for (Eigen::Index a = 0; a < size; ++a) {
          const double p = pinv(static_cast<Eigen::Index>(c), a);
          if (p == 0.0) continue;
          if (nr > 0) g.P.row(row) += p * Pg.row(a);
          h += p * hg[static_cast<std::size_t>(a)];
        }
        set_harmonic(row, h);
        g.D.row(a_idx) = beta * g.P.row(row);
      }
    }
  }
  g.finish(W);
  mode->build_seconds = seconds_since(start);
  mode->bytes = (mode->owned ? mode->owned->bytes() : 0) +
                sizeof(double) * static_cast<std::size_t>(2 * (m + held) * nr + 4 * n);
  return mode;
}

/// Buffers of the free chain's size for the basis changes and guard values of an event, so that
/// no event allocates once they are warm (each use takes the head it needs).
struct Buffers {
  explicit Buffers(Eigen::Index n) : y(n), yd(n), u(n), ud(n), udd(n), fu(n), fud(n), z(n), kz(n) {}
  Eigen::VectorXd y, yd, u, ud, udd, fu, fud, z, kz;
  ChainModes::Workspace work;
};

/// Full physical state from a mode's homogeneous modal state at t. O(n·n_r).
void to_physical(const ModalContactMode& mode, double W, double t, const Eigen::Ref<const Eigen::VectorXd>& u,
                 const Eigen::Ref<const Eigen::VectorXd>& ud, Eigen::Ref<Eigen::VectorXd> x,
                 Eigen::Ref<Eigen::VectorXd> v, Buffers& b) {
  const Eigen::Index n = static_cast<Eigen::Index>(mode.coordinate.size());
  auto y = b.y.head(mode.size()), yd = b.yd.head(mode.size());
  if (mode.modes) mode.modes->to_physical(t, u, ud, y, yd, b.work);
  const double c = std::cos(W * t), s = std::sin(W * t);
  for (Eigen::Index l = 0; l < n; ++l) {
    const Eigen::Index r = mode.coordinate[static_cast<std::size_t>(l)];
    x(l) = mode.o0(l) + mode.oc(l) * c + mode.os(l) * s + (r >= 0 ? y(r) : 0.0);
    v(l) = W * (mode.os(l) * c - mode.oc(l) * s) + (r >= 0 ? yd(r) : 0.0);
  }
}

/// A mode's homogeneous modal state from the full state at t: each reduced coordinate is the
/// mass-weighted mean of its masses (less their offsets), the M-orthogonal projection onto the
/// constraints, so rounding drift off them is projected away. O(n·n_r).
/// `u`, `ud` have the mode's size.
void to_modal(const ModalContactMode& mode, const Eigen::VectorXd& mass, double W, double t,
              const Eigen::VectorXd& x, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> u,
              Eigen::Ref<Eigen::VectorXd> ud, Buffers& b) {
  const Eigen::Index nr = mode.size();
  if (nr == 0) return;
  const double c = std::cos(W * t), s = std::sin(W * t);
  auto y = b.y.head(nr), yd = b.yd.head(nr);
  for (Eigen::Index r = 0; r < nr; ++r) {
    double sy = 0.0, sv = 0.0, sm = 0.0;
    for (Eigen::Index l = mode.first[static_cast<std::size_t>(r)]; l <= mode.last[static_cast<std::size_t>(r)]; ++l) {
      sy += mass(l) * (x(l) - (mode.o0(l) + mode.oc(l) * c + mode.os(l) * s));
      sv += mass(l) * (v(l) - W * (mode.os(l) * c - mode.oc(l) * s));
      sm += mass(l);
    }
    y(r) = sy / sm;
    yd(r) = sv / sm;
  }
  mode.modes->to_modal(t, y, yd, u, ud, b.work);
}

/// Value and slope of guard `row` at t0 + τ from the homogeneous state (u0, ud0) at t0, and
/// its second derivative if `curvature` is given. O(n_r).
void guard_at(const ModalContactMode& mode, double W, double t0, const Eigen::Ref<const Eigen::VectorXd>& u0,
              const Eigen::Ref<const Eigen::VectorXd>& ud0, double tau, Eigen::Index row, double* value, double* slope,
              Buffers& b, double* curvature = nullptr) {
  const ModalGuards& g = mode.guards;
  const double t = t0 + tau, c = std::cos(W * t), s = std::sin(W * t);
  *value = g.h0(row) + g.hc(row) * c + g.hs(row) * s;
  *slope = W * (g.hs(row) * c - g.hc(row) * s);
  if (curvature) *curvature = -W * W * (g.hc(row) * c + g.hs(row) * s);
  if (!mode.modes) return;
  const Eigen::Index nr = mode.size();
  auto u = b.u.head(nr), ud = b.ud.head(nr), udd = b.udd.head(nr);
  mode.modes->advance(tau, u0, ud0, u, ud);
  *value += g.P.row(row).dot(u);
  *slope += g.P.row(row).dot(ud);
  const Eigen::Index first_d = g.rows() - g.D.rows();
  const bool rates = row >= first_d;
  // u'' = −(2 d ∘ u' + ω² ∘ u) (modal.hpp), and u''' from it the same way.
  if (rates || curvature)
    udd = -(2.0 * mode.modes->decay().cwiseProduct(ud) + mode.modes->omega_squared().cwiseProduct(u));
  if (curvature) *curvature += g.P.row(row).dot(udd);
  if (rates) {
    *value += g.D.row(row - first_d).dot(ud);
    *slope += g.D.row(row - first_d).dot(udd);
    if (curvature)
      *curvature -= g.D.row(row - first_d).dot(2.0 * mode.modes->decay().cwiseProduct(udd) +
                                               mode.modes->omega_squared().cwiseProduct(ud));
  }
}

/// The modal engine's side of event resolution (event_resolution.hpp), in physical coordinates:
/// sparse normals, diagonal M and tridiagonal K, so O(N) per event; contact sets through the
/// simulator's cache (`mode_of`, null with a reason when a set cannot be reduced).
class ChainAlgebra final : public detail::ContactAlgebra {
 public:
  using ModeOf = std::function<const ModalContactMode*(const ContactSet&, std::string*)>;
  ChainAlgebra(const BandedChain& chain, const std::vector<Stop>& stops, ModeOf mode_of, Buffers& buffers)
      : ch_(chain), stops_(stops), W_(chain.forcing.frequency), mode_of_(std::move(mode_of)), b_(buffers) {
    const auto m = static_cast<Eigen::Index>(stops.size());
    const Eigen::Index n = chain.dof();
    q_.resize(m);
    G_.resize(m, m);
    lcp_.reserve(m);
    G_diag_.resize(m);
    alpha_.resize(m);
    kx_.resize(n);
    kv_.resize(n);
    acc_.resize(n);
    for (Eigen::Index j = 0; j < m; ++j) {
      normal_.push_back(normal_of(stops[static_cast<std::size_t>(j)]));
      G_diag_(j) = delassus_entry(normal_.back(), normal_.back(), ch_.mass);
    }
    beta_.resize(m);
    for (Eigen::Index j = 0; j < m; ++j) {  // α_j, β_j (simulator.hpp, ChatterRule), C = αM + βK
      b_.z.setZero();
      add_minv_w(static_cast<int>(j), 1.0, b_.z);  // q = M⁻¹ w_j
      stiffness_times(ch_, b_.z, b_.kz);
      alpha_(j) = -(ch_.rayleigh_mass * G_diag_(j) + ch_.rayleigh_stiffness * b_.z.dot(b_.kz)) / G_diag_(j);
      // qᵀCq, qᵀ K q and qᵀ C M⁻¹ C q with M⁻¹ C q = α q + β M⁻¹ K q.
      const double G = G_diag_(j), qkq = b_.z.dot(b_.kz);
      const double qcq = ch_.rayleigh_mass * G + ch_.rayleigh_stiffness * qkq;
      kx_ = ch_.rayleigh_mass * b_.z + ch_.rayleigh_stiffness * b_.kz.cwiseQuotient(ch_.mass);  // d = M⁻¹ C q
      stiffness_times(ch_, kx_, kv_);
      const double qcd = ch_.rayleigh_mass * b_.z.dot(ch_.mass.cwiseProduct(kx_)) + ch_.rayleigh_stiffness * b_.z.dot(kv_);
      beta_(j) = (qcd - qkq) / G - (qcq / G) * (qcq / G);
    }
  }

  double gap(int j, double t, const Eigen::VectorXd& x) const override {
    return w_dot(j, x) - value_at(motion(j), W_, t);
  }
  double gap_rate(int j, double t, const Eigen::VectorXd& v) const {
    return w_dot(j, v) - value_at(motion(j).derivative(W_), W_, t);
  }
  void gap_rates(double t, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> out) const override {
    for (Eigen::Index j = 0; j < out.size(); ++j) out(j) = gap_rate(static_cast<int>(j), t, v);
  }
  void settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, const ContactSet& candidates,
              ContactSet& held, Eigen::Ref<Eigen::VectorXd> forces) override {
    held.clear();
    if (candidates.empty()) return;
    // Free acceleration M⁻¹(f - C v - K x), C = αM + βK: O(n).
    stiffness_times(ch_, x, kx_);
    stiffness_times(ch_, v, kv_);
    const HarmonicForcing& f = ch_.forcing;
    const double c = std::cos(W_ * t), s = std::sin(W_ * t);
    acc_ = f.constant + f.cosine * c + f.sine * s - kx_ - ch_.rayleigh_stiffness * kv_;
    acc_.array() /= ch_.mass.array();
    acc_ -= ch_.rayleigh_mass * v;
    const auto k = static_cast<Eigen::Index>(candidates.size());
    auto q = q_.head(k);
    for (Eigen::Index a = 0; a < k; ++a) {
      const int j = candidates[static_cast<std::size_t>(a)];
      q(a) = w_dot(j, acc_) - value_at(motion(j).derivative(W_).derivative(W_), W_, t);
    }
    auto G = G_.topLeftCorner(k, k);
    delassus(candidates, G);
    solve_lcp(G, q, forces, lcp_);
    for (Eigen::Index a = 0; a < k; ++a)
      if (forces(a) > 0.0) held.push_back(candidates[static_cast<std::size_t>(a)]);
  }
  void delassus(const ContactSet& set, Eigen::Ref<Eigen::MatrixXd> G) const override {
    const auto k = static_cast<Eigen::Index>(set.size());
    for (Eigen::Index a = 0; a < k; ++a)
      for (Eigen::Index b = 0; b < k; ++b)
        G(a, b) = delassus_entry(normal_[static_cast<std::size_t>(set[static_cast<std::size_t>(a)])],
                                 normal_[static_cast<std::size_t>(set[static_cast<std::size_t>(b)])], ch_.mass);
  }
  double delassus_diagonal(int j) const override { return G_diag_(j); }
  void apply_impulse(const ContactSet& set, const Eigen::Ref<const Eigen::VectorXd>& impulse,
                     Eigen::VectorXd& v) const override {
    for (std::size_t a = 0; a < set.size(); ++a) add_minv_w(set[a], -impulse(static_cast<Eigen::Index>(a)), v);
  }
  void shift(const ContactSet& set, Eigen::Index a, double s, Eigen::VectorXd& z) const override {
    add_minv_w(set[static_cast<std::size_t>(a)], -s, z);
  }
  bool accept(const ContactSet& held, std::string* why) override { return mode_of_(held, why) != nullptr; }
  double chatter_alpha(int j) const override { return alpha_(j); }
  void force_rates(const ContactSet& held, int j, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                   double* slope, double* curvature) override {
    std::string why;
    const ModalContactMode* mode = mode_of_(held, &why);
    if (!mode) throw std::logic_error("force_rates: the held set was not accepted: " + why);
    auto u = b_.fu.head(mode->size()), ud = b_.fud.head(mode->size());
    to_modal(*mode, ch_.mass, W_, t, x, v, u, ud, b_);
    const auto a_idx = std::lower_bound(held.begin(), held.end(), j) - held.begin();
    double value;
    guard_at(*mode, W_, t, u, ud, 0.0, mode->gap_rows + a_idx, &value, slope, b_, curvature);
    *slope = -*slope;  // the guard is -λ
    *curvature = -*curvature;
  }
  double chatter_beta(int j) const override { return beta_(j); }
  double normal_dot(int j, const Eigen::VectorXd& y) const override { return w_dot(j, y); }
  // C = αM + βK: M⁻¹ C y = α y + β M⁻¹ K y, O(n).
  void damped_normal(int j, Eigen::VectorXd& d) override {
    b_.z.setZero();
    add_minv_w(j, 1.0, b_.z);
    stiffness_times(ch_, b_.z, b_.kz);
    d = ch_.rayleigh_mass * b_.z + ch_.rayleigh_stiffness * b_.kz.cwiseQuotient(ch_.mass);
  }
  void damped_response(int j, const Eigen::VectorXd& d, Eigen::VectorXd& e) override {
    stiffness_times(ch_, d, kx_);  // M⁻¹ C d
    e = ch_.rayleigh_mass * d + ch_.rayleigh_stiffness * kx_.cwiseQuotient(ch_.mass);
    b_.z.setZero();  // − M⁻¹ K M⁻¹ w_j
    add_minv_w(j, 1.0, b_.z);
    stiffness_times(ch_, b_.z, b_.kz);
    e -= b_.kz.cwiseQuotient(ch_.mass);
  }

 private:
  double w_dot(int j, const Eigen::VectorXd& z) const {
    const Normal& w = normal_[static_cast<std::size_t>(j)];
    return w.wi * z(w.i) + (w.k >= 0 ? w.wk * z(w.k) : 0.0);
  }
  void add_minv_w(int j, double scale, Eigen::VectorXd& z) const {  // z += scale M⁻¹ w_j
    const Normal& w = normal_[static_cast<std::size_t>(j)];
    z(w.i) += scale * w.wi / ch_.mass(w.i);
    if (w.k >= 0) z(w.k) += scale * w.wk / ch_.mass(w.k);
  }
  Harmonic motion(int j) const { return stop_motion(stops_[static_cast<std::size_t>(j)]); }

  const BandedChain& ch_;
  const std::vector<Stop>& stops_;
  double W_;
  ModeOf mode_of_;
  Buffers& b_;
  std::vector<Normal> normal_;
  Eigen::VectorXd G_diag_, alpha_, beta_, kx_, kv_, acc_, q_;
  Eigen::MatrixXd G_;
  LcpWorkspace lcp_;
};

}  // namespace

void ModalGuards::finish(double frequency) {
  abs_P = P.cwiseAbs();
  abs_D = D.cwiseAbs();
  curvature = (frequency * frequency) * (hc.cwiseAbs2() + hs.cwiseAbs2()).cwiseSqrt();
}

// ---------------------------------------------------------------------------------------------
// The certified crossing search of events.hpp on modal guards.

class ModalChainSimulator::Search {
 public:
  struct Point {
    double tau = 0.0;
    Eigen::VectorXd h, d, bound;  // per row: value, slope, |h''| bound valid on [tau, ∞)
  };

  /// `capacity`: the largest mode count (the free chain's N), so that no reset allocates.
  Search(double frequency, long* evaluations, Eigen::Index capacity)
      : W_(frequency), evaluations_(evaluations), u_(capacity), ud_(capacity), udd_(capacity), b2_(capacity),
        b3_(capacity) {}

  /// Targets guards `g` of modes `md` (null: no free mass) from the homogeneous state (u0, ud0)
  /// at absolute time t0. The state's storage must outlive the search's use.
  void reset(const ChainModes* md, const ModalGuards& g, double t0, const Eigen::Ref<const Eigen::VectorXd>& u0,
             const Eigen::Ref<const Eigen::VectorXd>& ud0, double resolution) {
    md_ = md;
    g_ = &g;
    t0_ = t0;
    nr_ = md ? md->dof() : 0;
    u0_ = u0.data();
    ud0_ = ud0.data();
    resolution_ = resolution;
    const Eigen::Index rows = g.rows();
    if (u_.size() < nr_) {  // a capacity below the free chain's: grow (not in the event loop)
      for (Eigen::VectorXd* v : {&u_, &ud_, &udd_, &b2_, &b3_}) v->resize(nr_);
    }
    if (stack_.size() < 200) stack_.resize(200);
    for (Point& p : stack_) {
      p.h.resize(rows);
      p.d.resize(rows);
      p.bound.resize(rows);
    }
    trig_.resize(rows);
    last_below_.resize(rows);
    leaving_.assign(static_cast<std::size_t>(rows), false);
  }

  /// Evaluates the start and arms every row at base(i) (re-armed above a start inside the band
  /// while moving away, as in the dense engine).
  void start(const Eigen::VectorXd& base, double from = 0.0) {
    Point& P0 = stack_[0];
    from_ = from;
    evaluate(from, P0);
    for (Eigen::Index i = 0; i < g_->rows(); ++i) {
      trig_(i) = base(i);
      if (P0.h(i) > 0.0 && P0.d(i) <= 0.0) trig_(i) += P0.h(i);
      leaving_[static_cast<std::size_t>(i)] = P0.h(i) >= -base(i) && P0.d(i) < 0.0;
      last_below_(i) = -std::numeric_limits<double>::infinity();
    }
  }

  /// First crossing in [from, span] (from as given to start()), walking in steps of `step`;
  /// false if none.
  bool first(double span, double step, double* tau, int* row) {
    if (g_->rows() == 0) return false;
    for (double a = from_; a < span;) {
      const double b = std::min(a + step, span);
      evaluate(b, stack_[1]);
      if (search(0, 1, 2, tau, row)) return true;
      std::swap(stack_[0], stack_[1]);
      a = b;
    }
    return false;
  }

  /// Value, slope and bound of every row (only < 0) or one row at τ.
  void evaluate(double tau, Point& p, int only = -1) {
    ++*evaluations_;
    p.tau = tau;
    const ModalGuards& g = *g_;
    const Eigen::Index nd = g.D.rows(), rows = g.rows(), first_d = rows - nd;
    const bool full = only < 0;
    const double t = t0_ + tau, c = std::cos(W_ * t), s = std::sin(W_ * t);
    auto u_ = this->u_.head(nr_), ud_ = this->ud_.head(nr_), udd_ = this->udd_.head(nr_);
    auto b2_ = this->b2_.head(nr_), b3_ = this->b3_.head(nr_);
    if (md_) {
      md_->advance(tau, Eigen::Map<const Eigen::VectorXd>(u0_, nr_), Eigen::Map<const Eigen::VectorXd>(ud0_, nr_), u_,
                   ud_, full ? this->b2_.data() : nullptr);
      if (nd > 0) {
        const Eigen::VectorXd& sg = md_->decay();
        udd_ = -(2.0 * sg.cwiseProduct(ud_) + md_->omega_squared().cwiseProduct(u_));
        if (full) {
          const auto two_s = 2.0 * sg.array();
          const auto w = md_->omega().array();
          b3_ = (b2_.array() * (two_s * (two_s + w) + w * w) / (two_s + w)).matrix();
        }
      }
    }
    if (full) {
      if (md_) {
        p.h.noalias() = g.P * u_;
        p.d.noalias() = g.P * ud_;
        p.bound.noalias() = g.abs_P * b2_;
        if (nd > 0) {
          p.h.tail(nd).noalias() += g.D * ud_;
          p.d.tail(nd).noalias() += g.D * udd_;
          p.bound.tail(nd).noalias() += g.abs_D * b3_;
        }
      } else {
        p.h.setZero();
        p.d.setZero();
        p.bound.setZero();
      }
      p.bound += g.curvature;
      p.h += g.h0 + g.hc * c + g.hs * s;
      p.d += W_ * (g.hs * c - g.hc * s);
    } else {
      double h = g.h0(only) + g.hc(only) * c + g.hs(only) * s;
      double d = W_ * (g.hs(only) * c - g.hc(only) * s);
      if (md_) {
        h += g.P.row(only).dot(u_);
        d += g.P.row(only).dot(ud_);
        if (only >= first_d) {
          h += g.D.row(only - first_d).dot(ud_);
          d += g.D.row(only - first_d).dot(udd_);
        }
      }
      p.h(only) = h;
      p.d(only) = d;
    }
  }

  auto u() const { return u_.head(nr_); }
  auto ud() const { return ud_.head(nr_); }
  const Eigen::VectorXd& trig() const { return trig_; }
  Point& point(std::size_t i) { return stack_[i]; }

 private:
  bool certified(Eigen::Index i, const Point& a, const Point& b) const {
    return upper_bound(a.h(i), a.d(i), b.h(i), b.d(i), a.bound(i), b.tau - a.tau) <= trig_(i);
  }

  double refine_root(int i, double lo, double hi) {
    // Safeguarded Newton on h_i = 0 keeping a bracket h_i(lo) ≤ 0 < h_i(hi) (as the dense engine).
    Point& p = stack_.back();
    evaluate(lo, p, i);
    double h_lo = p.h(i);
    if (h_lo > 0.0) return lo;
    double h_hi = std::numeric_limits<double>::infinity();
    double x = 0.5 * (lo + hi);
    for (int it = 0; it < 200; ++it) {
      evaluate(x, p, i);
      const double h = p.h(i), d = p.d(i);
      if (h == 0.0) return x;
      if (h < 0.0) {
        lo = x;
        h_lo = h;
      } else {
        hi = x;
        h_hi = h;
      }
      const double t_abs = std::abs(t0_) + std::abs(hi);
      if (hi - lo <= 4.0 * std::numeric_limits<double>::epsilon() * t_abs)
        return std::abs(h_lo) <= std::abs(h_hi) ? lo : hi;
      double next = d != 0.0 ? x - h / d : 0.5 * (lo + hi);
      if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
      if (next == x) return x;
      x = next;
    }
    return x;
  }

  bool search(int ia, int ib, int free, double* tau_hit, int* row_hit) {
    if (free + 2 >= static_cast<int>(stack_.size()))
      throw std::runtime_error("modal crossing search: subdivision depth exceeded");
    const Point& A = stack_[static_cast<std::size_t>(ia)];
    const Point& B = stack_[static_cast<std::size_t>(ib)];
    const auto m = static_cast<int>(trig_.size());
    // A guard that starts on its surface and leaves it is within rounding of zero at τ = 0: that
    // point must not bracket a root (the root finder could return the surface just left).
    for (int j = 0; j < m; ++j)
      if (A.h(j) <= 0.0 && !(A.tau == from_ && leaving_[static_cast<std::size_t>(j)]))
        last_below_(j) = std::max(last_below_(j), A.tau);
    int uncertified = 0, above = -1;
    for (int j = 0; j < m; ++j)
      if (!certified(j, A, B)) {
        ++uncertified;
        if (B.h(j) > trig_(j) && above < 0) above = j;
      }
    if (uncertified == 0) return false;
    // The root before B, bracketed from the last point seen with h ≤ 0; a guard not ≤ 0 since
    // the segment began (re-armed above its start) is placed at B.
    auto root_of = [&](int j) {
      if (!std::isfinite(last_below_(j))) return B.tau;
      return refine_root(j, last_below_(j), B.tau);
    };
    if (B.tau - A.tau <= resolution_) {
      bool found = false;
      for (int j = 0; j < m; ++j)
        if (B.h(j) > trig_(j)) {
          const double r = root_of(j);
          if (!found || r < *tau_hit) {
            *tau_hit = r;
            *row_hit = j;
            found = true;
          }
        }
      return found;
    }
    if (uncertified == 1 && above >= 0 && std::isfinite(last_below_(above))) {
      // Shortcut: the one uncertified guard rises above ε at b; accept its root r if [a, r] is
      // certified for it (the others are certified on all of [a, b]).
      const double r = root_of(above);
      if (r <= A.tau) {
        *tau_hit = r;
        *row_hit = above;
        return true;
      }
      Point& R = stack_[static_cast<std::size_t>(free)];
      evaluate(r, R, above);
      if (upper_bound(A.h(above), A.d(above), R.h(above), R.d(above), A.bound(above), r - A.tau) <=
          trig_(above)) {
        *tau_hit = r;
        *row_hit = above;
        return true;
      }
    }
    evaluate(A.tau + 0.5 * (B.tau - A.tau), stack_[static_cast<std::size_t>(free)]);
    if (search(ia, free, free + 1, tau_hit, row_hit)) return true;
    return search(free, ib, free + 1, tau_hit, row_hit);
  }

  double W_;
  long* evaluations_;
  const ChainModes* md_ = nullptr;
  const ModalGuards* g_ = nullptr;
  double t0_ = 0.0, resolution_ = 0.0, from_ = 0.0;
  Eigen::Index nr_ = 0;
  const double *u0_ = nullptr, *ud0_ = nullptr;
  Eigen::VectorXd u_, ud_, udd_, b2_, b3_;  // capacity N, used through head(nr_)
  std::vector<Point> stack_;
  Eigen::VectorXd trig_, last_below_;
  std::vector<bool> leaving_;
};

// ---------------------------------------------------------------------------------------------
// Options, cache, construction

void ModalSimulatorOptions::validate() const {
  SimulatorOptions::validate();  // the shared fields, by the dense engine's rules
  if (!std::isfinite(mode_cache_bytes) || mode_cache_bytes < 0.0)
    throw InvalidInput("solver.mode_cache_bytes = " + number_text(mode_cache_bytes) + ": must be a finite number ≥ 0");
  if (stop_after_impacts < 0)
    throw InvalidInput("stop_after_impacts = " + std::to_string(stop_after_impacts) + ": must be ≥ 0");
}

ModalSimulatorOptions modal_options(const SimulatorOptions& options) {
  ModalSimulatorOptions m;
  static_cast<SimulatorOptions&>(m) = options;
  return m;
}

struct ModalChainSimulator::Cache {
  struct Entry {
    std::unique_ptr<ModalContactMode> mode;
    long last_use = 0;
  };
  std::map<ContactSet, Entry> modes;
  std::map<ContactSet, std::string> unsupported;
  std::set<ContactSet> ever_built;
  long clock = 0;
  std::size_t bytes = 0;
};

ModalChainSimulator::ModalChainSimulator(const ChainModes& modes, std::vector<Stop> stops,
                                         ModalSimulatorOptions options)
    : modes_(&modes), stops_(std::move(stops)), options_(options), cache_(std::make_unique<Cache>()) {
  options_.validate();
  const auto start = std::chrono::steady_clock::now();
  const Eigen::Index n = modes.dof();
  const double W = modes.frequency();
  for (std::size_t j = 0; j < stops_.size(); ++j) {
    Stop& s = stops_[j];
    const std::string label = "stops[" + std::to_string(j) + "]";
    if (s.mass < 0 || s.mass >= n)
      throw InvalidInput(label + ": mass " + std::to_string(s.mass) + " is not in [0, " +
                         std::to_string(n - 1) + "]");
    if (s.kind == Stop::Kind::between && (s.other < 0 || s.other >= n || s.other == s.mass))
      throw InvalidInput(label + ": other mass " + std::to_string(s.other) +
                         " must be in [0, " + std::to_string(n - 1) + "] and differ from mass");
    if (!std::isfinite(s.position) || !std::isfinite(s.amplitude) || !std::isfinite(s.phase) ||
        s.amplitude < 0.0)
      throw InvalidInput(label + ": position, amplitude and phase must be finite, amplitude ≥ 0");
    if (!(s.restitution >= 0.0 && s.restitution <= 1.0))
      throw InvalidInput(label + ": restitution = " + number_text(s.restitution) + ": must be in [0, 1]");
    if (s.amplitude > 0.0 && !(W > 0.0))
      throw InvalidInput(label + ": a moving stop needs forcing.frequency > 0");
    if (s.name.empty()) {
      s.name = s.kind == Stop::Kind::upper ? "upper" : (s.kind == Stop::Kind::lower ? "lower" : "between");
      s.name += " x" + std::to_string(s.mass);
      if (s.kind == Stop::Kind::between) s.name += "-x" + std::to_string(s.other);
    }
  }
  std::string why;
  cache_->modes[ContactSet{}].mode = build_mode(modes, stops_, {}, &why);
  stop_setup_seconds_ = seconds_since(start);
}

ModalChainSimulator::~ModalChainSimulator() = default;

std::size_t ModalChainSimulator::cached_modes() const { return cache_->modes.size() - 1; }

const ModalContactMode& ModalChainSimulator::contact_mode(const ContactSet& set) {
  for (std::size_t a = 0; a < set.size(); ++a)
    if (set[a] < 0 || set[a] >= static_cast<int>(stops_.size()) || (a > 0 && set[a] <= set[a - 1]))
      throw InvalidInput("contact set: stop indices must be sorted, distinct and in [0, " +
                         std::to_string(stops_.size()) + ")");
  ModalRunSummary scratch;
  std::string why;
  const ModalContactMode* mode = mode_for(set, &why, scratch);
  if (!mode) throw InvalidInput("contact set: " + why);
  return *mode;
}

const ModalContactMode* ModalChainSimulator::mode_for(const ContactSet& set, std::string* why_not,
                                                       ModalRunSummary& summary) {
  Cache& c = *cache_;
  ++c.clock;
  if (auto it = c.modes.find(set); it != c.modes.end()) {
    it->second.last_use = c.clock;
    return it->second.mode.get();
  }
  if (auto it = c.unsupported.find(set); it != c.unsupported.end()) {
    *why_not = it->second;
    return nullptr;
  }
  auto mode = build_mode(*modes_, stops_, set, why_not, options_.contact_modes);
  if (!mode) {
    c.unsupported[set] = *why_not;
    return nullptr;
  }
  summary.mode_build_seconds += mode->build_seconds;
  summary.mode_build_max_seconds = std::max(summary.mode_build_max_seconds, mode->build_seconds);
  if (!c.ever_built.insert(set).second) ++summary.modes_rebuilt;
  c.bytes += mode->bytes;
  const ModalContactMode* out = mode.get();
  c.modes[set] = {std::move(mode), c.clock};
  // Drop the least recently used subsystems beyond the budget (never the free set or this one).
  while (static_cast<double>(c.bytes) > options_.mode_cache_bytes) {
    auto victim = c.modes.end();
    for (auto it = c.modes.begin(); it != c.modes.end(); ++it)
      if (!it->first.empty() && it->first != set &&
          (victim == c.modes.end() || it->second.last_use < victim->second.last_use))
        victim = it;
    if (victim == c.modes.end()) break;
    c.bytes -= victim->second.mode->bytes;
    c.modes.erase(victim);
    ++modes_dropped_;
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// The run

ModalRunSummary ModalChainSimulator::run(double t0, const Eigen::VectorXd& x0,
                                         const Eigen::VectorXd& v0, double t_end,
                                         const std::vector<Observer*>& observers) {
  ++runs_started_;
  const ChainModes& md = *modes_;
  const BandedChain& ch = md.chain();
  const Eigen::Index n = md.dof();
  const int m = static_cast<int>(stops_.size());
  if (x0.size() != n || v0.size() != n)
    throw InvalidInput("initial state: x has " + std::to_string(x0.size()) + " and v has " +
                       std::to_string(v0.size()) + " entries, expected " + std::to_string(n));
  if (!x0.allFinite() || !v0.allFinite()) throw InvalidInput("initial state: not finite");
  if (!std::isfinite(t0) || !std::isfinite(t_end) || t_end < t0)
    throw InvalidInput("time span: [" + number_text(t0) + ", " + number_text(t_end) +
                       "] must be finite with t_end ≥ t0");

  // Scales and tolerances by the dense engine's rules (event_resolution.hpp).
  const double W = md.frequency();
  const double omega = W > 0.0 ? W : md.omega().maxCoeff();
  const double kmax =
      std::max(ch.stiffness_diagonal.cwiseAbs().maxCoeff(), n > 1 ? ch.stiffness_off.cwiseAbs().maxCoeff() : 0.0);
  const double fmax = ch.forcing.constant.cwiseAbs().maxCoeff() + ch.forcing.cosine.cwiseAbs().maxCoeff() +
                      ch.forcing.sine.cwiseAbs().maxCoeff();
  const detail::RunScales sc = detail::run_scales(options_, omega, kmax, ch.mass.maxCoeff(), fmax, stops_, x0, v0);
  SimulatorOptions automatic = options_;
  automatic.length_scale = 0.0;
  std::vector<std::string> warnings;
  detail::check_resolution(sc, detail::run_scales(automatic, omega, kmax, ch.mass.maxCoeff(), fmax, stops_, x0, v0),
                           options_, t0, t_end, warnings);
  const double L = sc.L, V = sc.V, F = sc.F, T = sc.T;
  const double eps_gap = sc.eps_gap, eps_force = sc.eps_force;
  const double v_chatter = sc.rules.v_chatter, h_chatter = sc.rules.h_chatter, v_contact = sc.rules.v_contact;
  const double dt_simultaneous = sc.dt_simultaneous, window = sc.window;
  const double resolution = 8.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t_end), T);
  force_tolerance_ = eps_force;
  gap_tolerance_ = eps_gap;

  ModalRunSummary summary;
  summary.warnings = std::move(warnings);
  summary.length_scale = L;
  summary.velocity_scale = V;
  summary.force_scale = F;
  summary.time_scale = T;
  // Events other than a lone free-flight impact are resolved in physical coordinates by the
  // rules shared with the dense engine (event_resolution.hpp).
  std::set<ContactSet> sets_seen;  // impact and contact sets visited (contact_sets_built)
  // Storage for the whole run, sized once for the free chain's N (modes have n_r ≤ N).
  Buffers buffers(n);
  u0_.resize(n);
  ud0_.resize(n);
  auto u0 = [&] { return u0_.head(nr_); };
  auto ud0 = [&] { return ud0_.head(nr_); };
  ChainAlgebra algebra(ch, stops_, [&](const ContactSet& set, std::string* why) {
    return set.empty() ? cache_->modes.at(ContactSet{}).mode.get() : mode_for(set, why, summary);
  }, buffers);
  const detail::EventRules& rules = sc.rules;
  for (int j = 0; j < m; ++j) {
    const double g = algebra.gap(j, t0, x0);
    if (g > eps_gap)
      throw InvalidInput("initial state violates " + stop_text(stops_, j) + " by " + number_text(g) +
                         " at t = " + number_text(t0));
  }
  long evaluations = 0;
  Search search(W, &evaluations, n);
  const RunContext context{n, stops_.size(), W};
  for (Observer* o : observers) o->begin(context, t0);

  double t = t0;
  Eigen::VectorXd x = x0, v = v0;
  ContactSet stuck;
  const ModalContactMode* mode = cache_->modes.at(ContactSet{}).mode.get();
  detail::EventRate rate(options_.max_events, window);
  std::string why_not;

  auto emit = [&](const Event& e) {
    for (Observer* o : observers) o->event(e);
  };
  // Ends the run; the state reached is the mode's, or (x, v) after an event that could not be
  // carried into a mode (physical = true).
  auto finish = [&](RunStatus status, std::string message, bool physical = false) {
    for (Observer* o : observers) o->end(t);
    summary.status = status;
    summary.message = std::move(message);
    summary.t = t;
    summary.x.resize(n);
    summary.v.resize(n);
    if (physical) {
      summary.x = x;
      summary.v = v;
    } else {
      to_physical(*mode, W, t, u0(), ud0(), summary.x, summary.v, buffers);
    }
    summary.stuck = stuck;
    summary.evaluations = evaluations;
    summary.contact_sets_built = sets_seen.size();
    summary.sticking_flows_built = cache_->ever_built.size();
    return summary;
  };
  // Enters the mode of `stuck` from the physical state (x, v) at t. False if unsupported.
  auto enter = [&]() {
    const ModalContactMode* next = mode_for(stuck, &why_not, summary);
    if (!next) return false;
    mode = next;
    sets_seen.insert(stuck);
    nr_ = mode->size();
    to_modal(*mode, ch.mass, W, t, x, v, u0(), ud0(), buffers);
    seg_t0_ = t;
    return true;
  };

  const std::function<void(const Event&)> emit_event = emit;
  const std::function<void(const ContactSet&)> visit = [&](const ContactSet& set) { sets_seen.insert(set); };
  detail::EventWorkspace work;
  work.reserve(m, n);
  auto handle = [&](const ContactSet& impacting, const ContactSet& releasing, const ContactSet& resting) {
    ++summary.general_events;
    return detail::resolve_event(algebra, stops_, rules, t, x, v, stuck, impacting, releasing, resting,
                                 emit_event, summary, &why_not, work, visit);
  };

  seg_t0_ = t0;
  nr_ = mode->size();
  to_modal(*mode, ch.mass, W, t, x, v, u0(), ud0(), buffers);
  ContactSet impacting, releasing;
  impacting.reserve(static_cast<std::size_t>(m));
  releasing.reserve(static_cast<std::size_t>(m));
  try {
    {  // Stops touched at t0 (within ε) that are approached or resting.
      ContactSet resting;
      for (int j = 0; j < m; ++j) {
        if (algebra.gap(j, t, x) < -eps_gap) continue;
        const double gd = algebra.gap_rate(j, t, v);
        if (gd > v_contact) impacting.push_back(j);
        else if (gd >= -v_contact) resting.push_back(j);
      }
      if (!impacting.empty() || !resting.empty()) {
        if (!handle(impacting, {}, resting) || !enter())
          return finish(RunStatus::unsupported, why_not, true);
      }
    }
    if (const double steps = T * std::max(W, mode->modes ? mode->modes->omega().maxCoeff() : 0.0);
        steps > detail::kStiffStepsPerPeriod)  // as in the dense engine: the search steps by 1/ω_max
      summary.warnings.push_back(detail::stiff_warning(steps, (t_end - t0) / T));
    Eigen::VectorXd base;
    while (true) {
      if (options_.interrupt && options_.interrupt->load(std::memory_order_relaxed)) {
        return finish(RunStatus::interrupted, "interrupted at t = " + number_text(t));
      }
      if (options_.reached) options_.reached->store(t, std::memory_order_relaxed);
      const ModalGuards& guards = mode->guards;
      const Eigen::Index rows = guards.rows();
      base.resize(rows);
      for (Eigen::Index i = 0; i < rows; ++i) base(i) = i < mode->gap_rows ? eps_gap : eps_force;
      search.reset(mode->modes, guards, t, u0(), ud0(), resolution);
      search.start(base);
      const double top = std::max(W, mode->modes ? mode->modes->omega().maxCoeff() : 0.0);
      const double span = t_end - t;
      const double step = top > 0.0 ? 1.0 / top : std::max(span, 1e-300);
      double tau_hit = span;
      int row_hit = -1;
      const bool hit = span > 0.0 && search.first(span, step, &tau_hit, &row_hit);
      const double tau = hit ? tau_hit : span;
      const double t_next = hit ? t + tau : t_end;
      ++summary.segments;
      if (!observers.empty()) {
        const ModalSegmentView view(*this, *mode, t, t_next);
        for (Observer* o : observers) o->segment(view);
      }
      Search::Point& P = search.point(0);
      search.evaluate(tau, P);
      u0() = search.u();
      ud0() = search.ud();
      t = t_next;
      seg_t0_ = t;
      if (!u0().allFinite() || !ud0().allFinite())
        return finish(RunStatus::numerical_failure, "non-finite modal state at t = " + number_text(t));
      if (!hit) break;
      impacting.clear();
      releasing.clear();
      for (Eigen::Index i = 0; i < rows; ++i) {
        const double trig = search.trig()(i);
        const bool fired = i == row_hit || (P.d(i) > 0.0 && P.h(i) >= -std::max(trig, P.d(i) * dt_simultaneous));
        if (!fired) continue;
        (i < mode->gap_rows ? impacting : releasing).push_back(mode->watched[static_cast<std::size_t>(i)]);
      }
      std::sort(impacting.begin(), impacting.end());
      std::sort(releasing.begin(), releasing.end());
      // Fast path, O(n): one impact in free flight that leaves the stop (no chatter, no rest):
      // the impulse is a rank-1 update of the modal velocities (modal.hpp).
      bool fast = false;
      if (stuck.empty() && releasing.empty() && impacting.size() == 1) {
        const int j = impacting.front();
        const auto row = static_cast<Eigen::Index>(std::find(mode->watched.begin(), mode->watched.end(), j) -
                                                   mode->watched.begin());
        const double r = stops_[static_cast<std::size_t>(j)].restitution;
        const double before = P.d(row);  // the gap's slope is its normal rate
        const double after = before > 0.0 ? -r * before : before;
        bool slow = false;
        if (r > 0.0 && r < 1.0) {
          // Free gap acceleration (the acceleration LCP of one stop holds iff it is > 0).
          auto udd = buffers.udd.head(nr_);
          udd = -(2.0 * md.decay().cwiseProduct(ud0()) + md.omega_squared().cwiseProduct(u0()));
          const double c = std::cos(W * t), s = std::sin(W * t);
          const double accel = guards.P.row(row).dot(udd) - W * W * (guards.hc(row) * c + guards.hs(row) * s);
          slow = accel > 0.0 && (before <= v_chatter || (r * before) * (r * before) / (2.0 * accel) <= h_chatter);
        }
        if (!slow && after < -v_contact) {
          fast = true;
          sets_seen.insert(impacting);
          const double impulse = before > 0.0 ? (1.0 + r) * before / algebra.delassus_diagonal(j) : 0.0;
          ud0() -= guards.P.row(row).transpose() * impulse;
          const double g = guards.P.row(row).dot(u0()) + value_at({guards.h0(row), guards.hc(row), guards.hs(row)}, W, t);
          if (g > 0.0) u0() -= guards.P.row(row).transpose() * (g / algebra.delassus_diagonal(j));
          const double c = std::cos(W * t), s = std::sin(W * t);
          const double after_rate = guards.P.row(row).dot(ud0()) + W * (guards.hs(row) * c - guards.hc(row) * s);
          emit({t, j, EventKind::impact, before, after_rate, 0.0});
          ++summary.impacts;
        }
      }
      if (!fast) {
        to_physical(*mode, W, t, u0(), ud0(), x, v, buffers);
        if (!handle(impacting, releasing, {}) || !enter()) return finish(RunStatus::unsupported, why_not, true);
      }
      if (options_.stop_after_impacts > 0 && summary.impacts >= options_.stop_after_impacts)
        return finish(RunStatus::completed,
                      "stopped after " + std::to_string(summary.impacts) + " impacts as asked (t_end not reached)");
      if (rate.exceeded(t)) {
        const int j = !impacting.empty() ? impacting.front() : releasing.front();
        return finish(RunStatus::event_cap,
                      "event cap: more than " + std::to_string(options_.max_events) + " events within " +
                          number_text(window) + " time units, at t = " + number_text(t) + ", " +
                          stop_text(stops_, j) +
                          " (Zeno behaviour the chatter rule did not resolve: raise "
                          "solver.chatter_velocity or solver.max_events)");
      }
    }
  } catch (const std::runtime_error& e) {
    return finish(RunStatus::numerical_failure, std::string(e.what()) + " (at t = " + number_text(t) + ")");
  }
  return finish(RunStatus::completed, "");
}

// ---------------------------------------------------------------------------------------------
// Observers

Eigen::Index ModalSegmentView::dof() const { return sim_->modes().dof(); }

void ModalSegmentView::state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const {
  const Eigen::Index nr = mode_->size();
  Eigen::VectorXd u(nr), ud(nr);
  if (mode_->modes) mode_->modes->advance(t - t_begin(), sim_->segment_u(), sim_->segment_ud(), u, ud);
  Buffers buffers(sim_->modes().dof());  // observers' own scratch (they may allocate)
  to_physical(*mode_, sim_->modes().frequency(), t, u, ud, x, v, buffers);
}

ModalSegmentState ModalSegmentView::keep() const {
  return {*sim_, *mode_, t_begin(), sim_->segment_u(), sim_->segment_ud()};
}

void ModalSegmentState::state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const {
  const Eigen::Index nr = mode_->size();
  Eigen::VectorXd u(nr), ud(nr);
  if (mode_->modes) mode_->modes->advance(t - t_begin_, u_, ud_, u, ud);
  Buffers buffers(sim_->modes().dof());
  to_physical(*mode_, sim_->modes().frequency(), t, u, ud, x, v, buffers);
}

void ModalSegmentState::rows(double t, const std::vector<Eigen::Index>& masses, Eigen::VectorXd& x,
                             Eigen::VectorXd& v) const {
  const ModalContactMode& md = *mode_;
  const double W = sim_->modes().frequency(), c = std::cos(W * t), s = std::sin(W * t);
  const auto k = static_cast<Eigen::Index>(masses.size());
  x.resize(k);
  v.resize(k);
  std::vector<Eigen::Index> coordinates;
  for (Eigen::Index l : masses) {
    const Eigen::Index r = md.coordinate[static_cast<std::size_t>(l)];
    if (r >= 0) coordinates.push_back(r);
  }
  Eigen::MatrixXd phi;
  Eigen::VectorXd q, qd;
  if (md.modes && !coordinates.empty()) {
    const ChainModes& m = *md.modes;
    const Eigen::Index nr = md.size();
    q.resize(nr);
    qd.resize(nr);
    m.advance(t - t_begin_, u_, ud_, q, qd);
    q += m.particular_constant() + m.particular_cosine() * c + m.particular_sine() * s;
    qd += W * (m.particular_sine() * c - m.particular_cosine() * s);
    phi = m.phi_rows(coordinates);
  }
  Eigen::Index next = 0;
  for (Eigen::Index i = 0; i < k; ++i) {
    const Eigen::Index l = masses[static_cast<std::size_t>(i)];
    x(i) = md.o0(l) + md.oc(l) * c + md.os(l) * s;
    v(i) = W * (md.os(l) * c - md.oc(l) * s);
    if (md.coordinate[static_cast<std::size_t>(l)] >= 0) {
      x(i) += phi.row(next).dot(q);
      v(i) += phi.row(next).dot(qd);
      ++next;
    }
  }
}

double ModalSegmentView::force(Eigen::Index a, double t) const {
  double value, slope;
  Buffers buffers(mode_->size());
  guard_at(*mode_, sim_->modes().frequency(), t_begin(), sim_->segment_u(), sim_->segment_ud(),
           t - t_begin(), mode_->gap_rows + a, &value, &slope, buffers);
  return -value;
}

namespace {

/// The interior local maxima of guard `row` of `mode` in (from, to) for the homogeneous state (u0, ud0)
/// at t0 (ModalSegmentState::guard_local_maxima). Guards −h' and h' (h = P u + D u' + harmonic; with
/// u'' = −2σu' − ω²u, h' = (−D∘ω²)·u + (P − 2D∘σ)·u' + harmonic'; gaps have D = 0). A maximum is −h'
/// crossing 0 upwards, a minimum h' crossing upwards; the search alternates between them, one armed
/// at a time (the other's trigger is +∞), as DenseSegmentView::force_local_minima.
std::vector<Minimum> guard_maxima(const ModalChainSimulator& sim, const ModalContactMode& mode, double t0,
                                  const Eigen::Ref<const Eigen::VectorXd>& u0,
                                  const Eigen::Ref<const Eigen::VectorXd>& ud0, Eigen::Index row, double from,
                                  double to, double tolerance) {
  const ModalGuards& g = mode.guards;
  const Eigen::Index nr = mode.size(), first_d = g.rows() - g.D.rows();
  const double W = sim.modes().frequency();
  ModalGuards slope;
  slope.P.resize(2, nr);
  slope.D.resize(2, nr);
  if (nr > 0) {
    const Eigen::VectorXd& w2 = mode.modes->omega_squared();
    const Eigen::VectorXd& sg = mode.modes->decay();
    const Eigen::RowVectorXd d_row =
        row >= first_d ? Eigen::RowVectorXd(g.D.row(row - first_d)) : Eigen::RowVectorXd::Zero(nr);
    slope.P.row(0) = d_row.cwiseProduct(w2.transpose());                                   // −h'
    slope.D.row(0) = -(g.P.row(row) - 2.0 * d_row.cwiseProduct(sg.transpose()));
  }
  slope.P.row(1) = -slope.P.row(0);
  slope.D.row(1) = -slope.D.row(0);
  const Harmonic h_slope = Harmonic{g.h0(row), g.hc(row), g.hs(row)}.derivative(W);
  slope.h0 = Eigen::Vector2d(-h_slope.c0, h_slope.c0);
  slope.hc = Eigen::Vector2d(-h_slope.cc, h_slope.cc);
  slope.hs = Eigen::Vector2d(-h_slope.cs, h_slope.cs);
  slope.finish(W);

  long evaluations = 0;
  ModalChainSimulator::Search s(W, &evaluations, nr);
  const double start = from - t0, span = to - t0;
  const double resolution = 8.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(to));
  s.reset(mode.modes, slope, t0, u0, ud0, resolution);
  ModalChainSimulator::Search::Point& p0 = s.point(0);
  s.evaluate(start, p0);
  const double top = std::max(W, mode.modes ? mode.modes->omega().maxCoeff() : 0.0);
  // As DenseSegmentView: the trigger scaled to a slope (× 1e-3 × the fastest rate).
  const double eps = std::max(1e-13 * std::abs(p0.h(0)), tolerance * 1e-3 * std::max(top, 1e-300));
  const double step = top > 0.0 ? 1.0 / top : std::max(span, 1e-300);
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<Minimum> out;
  bool seek_max = p0.h(0) <= 0.0;
  double at = start;
  Buffers buffers(nr);
  for (int guard = 0; at < span && guard < 10000; ++guard) {
    Eigen::VectorXd trigger(2);
    trigger << (seek_max ? eps : inf), (seek_max ? inf : eps);
    s.start(trigger, at);
    double tau = span;
    int which = -1;
    if (!s.first(span, step, &tau, &which) || tau >= span) break;
    if (seek_max && tau > start) {
      const double t = t0 + tau;
      double value, rate;
      guard_at(mode, W, t0, u0, ud0, t - t0, row, &value, &rate, buffers);
      out.push_back({value, t});
    }
    at = std::max(tau, at) + resolution;
    seek_max = !seek_max;
  }
  return out;
}

}  // namespace

std::vector<Minimum> ModalSegmentView::force_local_minima(Eigen::Index a) const {
  std::vector<Minimum> out = guard_maxima(*sim_, *mode_, t_begin(), sim_->segment_u(), sim_->segment_ud(),
                                          mode_->gap_rows + a, t_begin(), t_end(), sim_->force_tolerance());
  for (Minimum& m : out) m.value = -m.value;  // λ = −h
  return out;
}

std::vector<Minimum> ModalSegmentState::guard_local_maxima(Eigen::Index row, double from, double to,
                                                           double tolerance) const {
  return guard_maxima(*sim_, *mode_, t_begin_, u_, ud_, row, from, to, tolerance);
}

double ModalSegmentState::guard(Eigen::Index row, double t) const {
  double value, rate;
  Buffers buffers(mode_->size());
  guard_at(*mode_, sim_->modes().frequency(), t_begin_, u_, ud_, t - t_begin_, row, &value, &rate, buffers);
  return value;
}

Minimum ModalSegmentView::force_minimum(Eigen::Index a) const {
  // The least of the ends and the interior minima (each certified by the search above).
  Minimum best{force(a, t_begin()), t_begin()};
  const double end = force(a, t_end());
  if (end < best.value) best = {end, t_end()};
  for (const Minimum& m : force_local_minima(a))
    if (m.value < best.value) best = m;
  return best;
}

}  // namespace vibro
