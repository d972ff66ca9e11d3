// The modal chain engine's contact modes: a contact set's reduced chain, its modes and its
// guards in modal form (modal.hpp, ModalContactMode), and the basis changes between a mode's
// homogeneous modal state and the physical state.
#include "modal_internal.hpp"

#include <Eigen/QR>

#include <map>
#include <set>
#include <stdexcept>

namespace vibro {

BandedChain with_stop_orders(BandedChain chain, const std::vector<Stop>& stops) {
  for (const Stop& s : stops)
    for (const StopHarmonic& h : s.harmonics) {
      bool present = false;
      for (const ForcingHarmonic& fh : chain.forcing.harmonics) present = present || fh.order == h.order;
      if (!present)
        chain.forcing.harmonics.push_back(
            {h.order, Eigen::VectorXd::Zero(chain.dof()), Eigen::VectorXd::Zero(chain.dof())});
    }
  return chain;
}

void ModalGuards::finish(double frequency) {
  abs_P = P.cwiseAbs();
  abs_D = D.cwiseAbs();
  curvature = (frequency * frequency) * (hc.cwiseAbs2() + hs.cwiseAbs2()).cwiseSqrt();
  jerk = frequency * curvature;
  for (Eigen::Index h = 0; h < rates.size(); ++h) {
    const double r = rates(h);
    const Eigen::VectorXd A = (xc.col(h).cwiseAbs2() + xs.col(h).cwiseAbs2()).cwiseSqrt();
    curvature += (r * r) * A;
    jerk += (r * r * r) * A;
  }
}

void ModalGuards::add_extra_row(Eigen::Index i, double t, double* value, double* slope, double* curvature) const {
  for (Eigen::Index h = 0; h < rates.size(); ++h) {
    const double r = rates(h), c = std::cos(r * t), s = std::sin(r * t);
    *value += xc(i, h) * c + xs(i, h) * s;
    *slope += r * (xs(i, h) * c - xc(i, h) * s);
    if (curvature) *curvature -= (r * r) * (xc(i, h) * c + xs(i, h) * s);
  }
}

void ModalGuards::add_extra(double t, Eigen::Ref<Eigen::VectorXd> value, Eigen::Ref<Eigen::VectorXd> slope,
                            Eigen::Ref<Eigen::VectorXd> curvature) const {
  for (Eigen::Index h = 0; h < rates.size(); ++h) {
    const double r = rates(h), c = std::cos(r * t), s = std::sin(r * t);
    value += xc.col(h) * c + xs.col(h) * s;
    slope += r * (xs.col(h) * c - xc.col(h) * s);
    curvature -= (r * r) * (xc.col(h) * c + xs.col(h) * s);
  }
}

namespace detail {

/// Builds the modal form of contact set `set` (modal.hpp, ModalContactMode), or returns null and
/// says why in `why_not` when the set is one the modal engine cannot reduce.
namespace {

/// The modal form of the held rigid stops `set` on the chain of `free` (the free chain, or the
/// chain with the engaged compliant stops `engaged`, whose guards are −g_j).
std::unique_ptr<ModalContactMode> build_reduction(const ChainModes& free, const std::vector<Stop>& stops,
                                                  const ContactSet& set, const ContactSet& engaged,
                                                  std::string* why_not, TridiagonalSolver route) {
  const auto start = std::chrono::steady_clock::now();
  auto mode = std::make_unique<ModalContactMode>();
  mode->stuck = set;
  mode->engaged = engaged;
  const BandedChain& ch = free.chain();
  const Eigen::Index n = free.dof();
  const double W = free.frequency();
  const double alpha = ch.rayleigh_mass, beta = ch.rayleigh_stiffness;
  // The drive's extra harmonics (system.hpp): their rates, as ChainModes has them.
  const auto H = static_cast<Eigen::Index>(ch.forcing.harmonics.size());
  Eigen::VectorXd rates(H);
  for (Eigen::Index h = 0; h < H; ++h) rates(h) = ch.forcing.harmonics[static_cast<std::size_t>(h)].rate(W);
  mode->coordinate.assign(static_cast<std::size_t>(n), -1);
  mode->o0 = Eigen::VectorXd::Zero(n);
  mode->oc = Eigen::VectorXd::Zero(n);
  mode->os = Eigen::VectorXd::Zero(n);
  // Held stops moving with higher harmonics give the offsets harmonics of those orders, on the
  // drive's slots (with_stop_orders gives the chain one for every order a stop moves at).
  bool held_harmonics = false;
  for (int j : set) held_harmonics = held_harmonics || stops[static_cast<std::size_t>(j)].has_higher_harmonics();
  if (held_harmonics) {
    mode->oxc = Eigen::MatrixXd::Zero(n, H);
    mode->oxs = Eigen::MatrixXd::Zero(n, H);
  }
  // Row `to` of the offsets' harmonics: row `from`'s (none if from < 0) plus sign × stop s's.
  auto carry_extra = [&](Eigen::Index to, Eigen::Index from, double sign, const Stop& s) {
    if (!held_harmonics) return;
    if (from >= 0) {
      mode->oxc.row(to) = mode->oxc.row(from);
      mode->oxs.row(to) = mode->oxs.row(from);
    }
    for (std::size_t i = 0; i < s.harmonics.size(); ++i) {
      const auto h = static_cast<Eigen::Index>(forcing_slot(ch.forcing, s.harmonics[i].order));
      mode->oxc(to, h) += sign * s.h_cos(i);
      mode->oxs(to, h) += sign * s.h_sin(i);
    }
  };
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
      if (s.kind == Stop::Kind::normal) {
        *why_not = stop_text(stops, j) +
                   " would be held (the motion comes to rest on it): a stop held along a general normal couples "
                   "the masses of its normal, and the modal engine reduces a chain only by fixing masses or "
                   "joining neighbours (use solver.engine: dense)";
        return nullptr;
      }
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
        const double sign = s.kind == Stop::Kind::upper ? 1.0 : -1.0;
        set_o(anchor, sign * stop_motion(s));
        carry_extra(anchor, -1, sign, s);
      }
      for (Eigen::Index l = anchor; l < g.hi; ++l) {  // x_mass - x_other = s
        const Stop& s = stops[static_cast<std::size_t>(tie[static_cast<std::size_t>(l)])];
        Harmonic next = get_o(l);
        next += (s.mass == l ? -1.0 : 1.0) * stop_motion(s);
        set_o(l + 1, next);
        carry_extra(l + 1, l, s.mass == l ? -1.0 : 1.0, s);
      }
      for (Eigen::Index l = anchor - 1; l >= g.lo; --l) {
        const Stop& s = stops[static_cast<std::size_t>(tie[static_cast<std::size_t>(l)])];
        Harmonic next = get_o(l + 1);
        next += (s.mass == l ? 1.0 : -1.0) * stop_motion(s);
        set_o(l, next);
        carry_extra(l, l + 1, s.mass == l ? 1.0 : -1.0, s);
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
      // Each extra harmonic h of rate r forces the reduced chain as Tᵀ(f_h − M o_h'' − C o_h' − K o_h),
      // o_h the offsets' harmonic of that order (zero unless a held stop moves at it): the first
      // harmonic's formulas with Ω → r.
      for (const ForcingHarmonic& fh : f.harmonics)
        red.forcing.harmonics.push_back({fh.order, Eigen::VectorXd::Zero(nr), Eigen::VectorXd::Zero(nr)});
      std::vector<Eigen::VectorXd> Fhc, Fhs;  // per harmonic, when the offsets have harmonics
      if (held_harmonics) {
        Eigen::VectorXd Kc, Ks;
        for (Eigen::Index h = 0; h < H; ++h) {
          const double r = rates(h);
          const Eigen::VectorXd oc_h = mode->oxc.col(h), os_h = mode->oxs.col(h);
          stiffness_times(ch, oc_h, Kc);
          stiffness_times(ch, os_h, Ks);
          const auto& fh = f.harmonics[static_cast<std::size_t>(h)];
          Fhc.push_back((fh.cosine.array() + r * r * m * oc_h.array() - r * (alpha * m * os_h.array() + beta * Ks.array()) -
                         Kc.array())
                            .matrix());
          Fhs.push_back((fh.sine.array() + r * r * m * os_h.array() + r * (alpha * m * oc_h.array() + beta * Kc.array()) -
                         Ks.array())
                            .matrix());
        }
      }
      for (Eigen::Index r = 0; r < nr; ++r) {
        const Eigen::Index a = mode->first[static_cast<std::size_t>(r)], b = mode->last[static_cast<std::size_t>(r)];
        for (Eigen::Index l = a; l <= b; ++l) {
          red.mass(r) += ch.mass(l);
          red.stiffness_diagonal(r) += ch.stiffness_diagonal(l) + (l < b ? 2.0 * ch.stiffness_off(l) : 0.0);
          red.forcing.constant(r) += F0(l);
          red.forcing.cosine(r) += Fc(l);
          red.forcing.sine(r) += Fs(l);
          for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
            red.forcing.harmonics[h].cosine(r) += held_harmonics ? Fhc[h](l) : f.harmonics[h].cosine(l);
            red.forcing.harmonics[h].sine(r) += held_harmonics ? Fhs[h](l) : f.harmonics[h].sine(l);
          }
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
  // The extra harmonics of X_l are φ_l·p_h(t) + o_l,h(t) (the offsets' part: held stops moving
  // with higher harmonics).
  auto offset_of = [&](Eigen::Index l) {
    Periodic o = Periodic::of({mode->o0(l), mode->oc(l), mode->os(l)}, H);
    if (held_harmonics) {
      o.c = mode->oxc.row(l).transpose();
      o.s = mode->oxs.row(l).transpose();
    }
    return o;
  };
  std::map<Eigen::Index, std::pair<Eigen::VectorXd, Periodic>> rows;
  auto add_particular = [&](std::pair<Eigen::VectorXd, Periodic>& entry) {
    entry.second += Harmonic{entry.first.dot(md->particular_constant()), entry.first.dot(md->particular_cosine()),
                             entry.first.dot(md->particular_sine())};
    if (H > 0) {
      entry.second.c += md->particular_harmonic_cosine().transpose() * entry.first;
      entry.second.s += md->particular_harmonic_sine().transpose() * entry.first;
    }
  };
  auto mass_row = [&](Eigen::Index l) -> const std::pair<Eigen::VectorXd, Periodic>& {
    auto it = rows.find(l);
    if (it != rows.end()) return it->second;
    std::pair<Eigen::VectorXd, Periodic> entry{Eigen::VectorXd::Zero(nr), offset_of(l)};
    const Eigen::Index r = mode->coordinate[static_cast<std::size_t>(l)];
    if (r >= 0) {
      entry.first = md->phi_row(r);
      add_particular(entry);
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
        if (!w.general()) w.for_each([&](Eigen::Index l, double) { masses.insert(l); });  // (general: gap_row)
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
      std::pair<Eigen::VectorXd, Periodic> entry{phi.row(static_cast<Eigen::Index>(c)).transpose(), offset_of(l)};
      add_particular(entry);
      rows.emplace(l, std::move(entry));
    }
  }

  const auto m = static_cast<Eigen::Index>(stops.size());
  const auto held = static_cast<Eigen::Index>(set.size());
  const auto engaged_count = static_cast<Eigen::Index>(engaged.size());
  ModalGuards& g = mode->guards;
  g.P = Eigen::MatrixXd::Zero(m, nr);
  g.D = Eigen::MatrixXd::Zero(held + engaged_count, nr);
  g.h0 = Eigen::VectorXd::Zero(m);
  g.hc = Eigen::VectorXd::Zero(m);
  g.hs = Eigen::VectorXd::Zero(m);
  g.xc = Eigen::MatrixXd::Zero(m, H);
  g.xs = Eigen::MatrixXd::Zero(m, H);
  g.rates = rates;
  auto set_harmonic = [&](Eigen::Index row, const Periodic& h) {
    g.h0(row) = h.first.c0;
    g.hc(row) = h.first.cc;
    g.hs(row) = h.first.cs;
    if (H > 0) {
      g.xc.row(row) = h.c.transpose();
      g.xs.row(row) = h.s.transpose();
    }
  };
  // Row `row` = sign × the gap g_j = w_jᵀ x - s_j(t).
  auto gap_row = [&](int j, Eigen::Index row, double sign) {
    const Stop& s = stops[static_cast<std::size_t>(j)];
    const Normal w = normal_of(s);
    Periodic h = Periodic::of(-1.0 * stop_motion(s), H);
    for (std::size_t i = 0; i < s.harmonics.size(); ++i) {  // − the stop's higher harmonics
      const auto slot = static_cast<Eigen::Index>(forcing_slot(ch.forcing, s.harmonics[i].order));
      h.c(slot) -= s.h_cos(i);
      h.s(slot) -= s.h_sin(i);
    }
    if (w.general()) {
      // wᵀx = wᵀ(T y + o): the row Φᵀ Tᵀw = Φ⁻¹ M_r⁻¹ Tᵀw (one O(N n_r) product, no N × n_r rows
      // formed), its particular part, and wᵀo of the offsets.
      std::pair<Eigen::VectorXd, Periodic> entry{Eigen::VectorXd::Zero(nr), Periodic::of({}, H)};
      Eigen::VectorXd reduced = Eigen::VectorXd::Zero(nr);
      w.for_each([&](Eigen::Index l, double weight) {
        const Eigen::Index r = mode->coordinate[static_cast<std::size_t>(l)];
        if (r >= 0) reduced(r) += weight;
        entry.second += weight * offset_of(l);
      });
      if (nr > 0) {
        ChainModes::Workspace work;
        const Eigen::MatrixXd y = reduced.cwiseQuotient(md->chain().mass);
        Eigen::MatrixXd u(nr, 1);
        md->tangent_to_modal(y, u, work);
        entry.first = u.col(0);
        add_particular(entry);
        g.P.row(row) += sign * entry.first.transpose();
      }
      h += entry.second;
    } else {
      w.for_each([&](Eigen::Index l, double weight) {
        const auto& [phi, X] = mass_row(l);
        if (nr > 0) g.P.row(row) += (sign * weight) * phi.transpose();
        h += weight * X;
      });
    }
    set_harmonic(row, sign * h);
  };
  // Gaps of the stops neither held nor engaged.
  for (int j = 0; j < static_cast<int>(m); ++j) {
    if (contains(set, j) || contains(engaged, j)) continue;
    const auto row = static_cast<Eigen::Index>(mode->watched.size());
    mode->watched.push_back(j);
    gap_row(j, row, 1.0);
  }
  mode->gap_rows = static_cast<Eigen::Index>(mode->watched.size());
  mode->watched.insert(mode->watched.end(), set.begin(), set.end());
  mode->engaged_rows_from = static_cast<Eigen::Index>(mode->watched.size());
  // −g_j of the engaged compliant stops: it rises through 0 when the gap reopens (D rows 0).
  for (int j : engaged) {
    mode->watched.push_back(j);
    gap_row(j, static_cast<Eigen::Index>(mode->watched.size()) - 1, -1.0);
  }
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
      std::vector<Periodic> hg(static_cast<std::size_t>(size));
      for (Eigen::Index l = grp.lo; l <= grp.hi; ++l) {
        const Eigen::Index a = l - grp.lo;
        const auto [phi, X] = mass_row(l);
        if (nr > 0) Pg.row(a) = -ch.mass(l) * phi.cwiseProduct(w2).transpose();
        Periodic h = ch.mass(l) * X.derivative(W, rates).derivative(W, rates);
        h += (alpha * ch.mass(l)) * X.derivative(W, rates);
        for (Eigen::Index lp = std::max<Eigen::Index>(l - 1, 0); lp <= std::min(l + 1, n - 1); ++lp) {
          const double k = stiffness_entry(ch, l, lp);
          const auto& [phi_p, X_p] = mass_row(lp);
          if (nr > 0) Pg.row(a) += k * phi_p.transpose();
          h += k * X_p;
          h += (beta * k) * X_p.derivative(W, rates);
        }
        h += Harmonic{-ch.forcing.constant(l), -ch.forcing.cosine(l), -ch.forcing.sine(l)};
        for (Eigen::Index e = 0; e < H; ++e) {
          h.c(e) -= ch.forcing.harmonics[static_cast<std::size_t>(e)].cosine(l);
          h.s(e) -= ch.forcing.harmonics[static_cast<std::size_t>(e)].sine(l);
        }
        hg[static_cast<std::size_t>(a)] = h;
      }
      for (std::size_t c = 0; c < members.size(); ++c) {
        const auto a_idx = std::lower_bound(set.begin(), set.end(), members[c]) - set.begin();
        const Eigen::Index row = mode->gap_rows + a_idx;
        Periodic h = Periodic::of({}, H);
        for (Eigen::Index a = 0; a < size; ++a) {
          const double p = pinv(static_cast<Eigen::Index>(c), a);
          if (p == 0.0) continue;
          if (nr > 0) g.P.row(row) += p * Pg.row(a);
          h += p * hg[static_cast<std::size_t>(a)];
        }
        set_harmonic(row, h);
        if (nr > 0) g.D.row(a_idx) = beta * g.P.row(row);  // (no free mass: D has no columns)
      }
    }
  }
  g.finish(W);
  mode->build_seconds = seconds_since(start);
  mode->bytes = (mode->owned ? mode->owned->bytes() : 0) +
                sizeof(double) * static_cast<std::size_t>(2 * (m + held + engaged_count) * nr + 4 * n);
  return mode;
}

}  // namespace

BandedChain engaged_chain(const BandedChain& chain, const std::vector<Stop>& stops, const ContactSet& engaged) {
  BandedChain out = chain;
  const double W = chain.forcing.frequency;
  HarmonicForcing& f = out.forcing;
  for (int j : engaged) {
    const Stop& s = stops[static_cast<std::size_t>(j)];
    const Normal w = normal_of(s);
    const double k = s.stiffness, c = s.damping;
    // K + k_s w wᵀ on the band: w has one entry, or two on neighbours (checked by the simulator).
    out.stiffness_diagonal(w.i) += k * w.wi * w.wi;
    if (w.k >= 0) {
      out.stiffness_diagonal(w.k) += k * w.wk * w.wk;
      out.stiffness_off(std::min(w.i, w.k)) += k * w.wi * w.wk;
    }
    // f + w (k_s s + c_s s' − F_p), as the dense engine's engaged mode (contact.cpp).
    auto add = [&](Eigen::VectorXd& v, double amount) {
      v(w.i) += amount * w.wi;
      if (w.k >= 0) v(w.k) += amount * w.wk;
    };
    add(f.constant, k * s.s0() - s.preload);
    add(f.cosine, k * s.s_cos() + c * W * s.s_sin());
    add(f.sine, k * s.s_sin() - c * W * s.s_cos());
    for (std::size_t i = 0; i < s.harmonics.size(); ++i) {
      ForcingHarmonic& fh = f.harmonics[forcing_slot(f, s.harmonics[i].order)];
      const double r = fh.rate(W), hc = s.h_cos(i), hs = s.h_sin(i);
      add(fh.cosine, k * hc + c * r * hs);
      add(fh.sine, k * hs - c * r * hc);
    }
  }
  return out;
}

std::unique_ptr<ModalContactMode> build_mode(const ChainModes& free, const std::vector<Stop>& stops,
                                             const ContactSet& set, std::string* why_not, TridiagonalSolver route) {
  ContactSet held, engaged;
  for (int j : set) (stops[static_cast<std::size_t>(j)].is_compliant() ? engaged : held).push_back(j);
  if (engaged.empty()) return build_reduction(free, stops, set, engaged, why_not, route);
  // Engaged compliant stops: the chain with their springs and dashpots (still tridiagonal and,
  // with c_s = β k_s, still C = αM + βK) and their forces, in modal form by its own tridiagonal
  // eigenproblem; the held rigid stops then reduce it as they reduce the free chain.
  const auto start = std::chrono::steady_clock::now();
  std::unique_ptr<ChainModes> base;
  try {
    const TridiagonalSolver solver =
        route == TridiagonalSolver::eigen || route == TridiagonalSolver::lapack ? route : free.solver();
    base = std::make_unique<ChainModes>(engaged_chain(free.chain(), stops, engaged), solver);
  } catch (const InvalidInput& e) {
    *why_not = "the chain with the engaged compliant stops cannot be put in modal form: " + std::string(e.what());
    return nullptr;
  }
  auto mode = build_reduction(*base, stops, held, engaged, why_not, route);
  if (!mode) return nullptr;
  mode->bytes += base->bytes();
  mode->engaged_base = std::move(base);
  mode->build_seconds = seconds_since(start);
  return mode;
}

void offset_extra(const ModalContactMode& mode, double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) {
  x.setZero();
  v.setZero();
  const Eigen::VectorXd& rates = mode.guards.rates;
  for (Eigen::Index h = 0; h < mode.oxc.cols(); ++h) {
    const double r = rates(h), c = std::cos(r * t), s = std::sin(r * t);
    x += mode.oxc.col(h) * c + mode.oxs.col(h) * s;
    v += r * (mode.oxs.col(h) * c - mode.oxc.col(h) * s);
  }
}

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
  if (mode.oxc.size() > 0) {
    offset_extra(mode, t, b.ox.head(n), b.ov.head(n));
    x += b.ox.head(n);
    v += b.ov.head(n);
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
  const bool extra = mode.oxc.size() > 0;
  if (extra) offset_extra(mode, t, b.ox.head(x.size()), b.ov.head(x.size()));
  for (Eigen::Index r = 0; r < nr; ++r) {
    double sy = 0.0, sv = 0.0, sm = 0.0;
    for (Eigen::Index l = mode.first[static_cast<std::size_t>(r)]; l <= mode.last[static_cast<std::size_t>(r)]; ++l) {
      sy += mass(l) * (x(l) - (mode.o0(l) + mode.oc(l) * c + mode.os(l) * s) - (extra ? b.ox(l) : 0.0));
      sv += mass(l) * (v(l) - W * (mode.os(l) * c - mode.oc(l) * s) - (extra ? b.ov(l) : 0.0));
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
              Buffers& b, double* curvature) {
  const ModalGuards& g = mode.guards;
  const double t = t0 + tau, c = std::cos(W * t), s = std::sin(W * t);
  *value = g.h0(row) + g.hc(row) * c + g.hs(row) * s;
  *slope = W * (g.hs(row) * c - g.hc(row) * s);
  if (curvature) *curvature = -W * W * (g.hc(row) * c + g.hs(row) * s);
  if (g.harmonics() > 0) g.add_extra_row(row, t, value, slope, curvature);
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

}  // namespace detail
}  // namespace vibro
