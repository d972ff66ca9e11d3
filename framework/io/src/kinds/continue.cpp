#include "vibro/io/kinds/continue.hpp"

#include "kinds.hpp"
#include "../run_section.hpp"

#include "../datasets.hpp"

#include "vibro/bounded_wait.hpp"
#include "vibro/friction_tangent.hpp"
#include "vibro/io/result_file.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <regex>

namespace vibro::io {
namespace {

using detail::integers;
using detail::reals;
using detail::table;

/// The data D of a built scene's system (parameter.hpp).
struct Data {
  Eigen::MatrixXd M, C, K;
  Eigen::VectorXd F0, Fc, Fs;
  double omega = 0.0;
  std::vector<std::array<double, 7>> stops;  // s0, sc, ss, r, and a compliant stop's k_s, c_s, F_p
  std::vector<Eigen::VectorXd> Hc, Hs;       // extra harmonics (system.hpp)
  std::vector<Eigen::VectorXd> stop_hc, stop_hs;  // per stop: its higher harmonics' h_cos, h_sin (stops.hpp)
  std::vector<std::array<double, 3>> friction;    // per frictional contact: N, μ_s, μ_k (friction.hpp)
};

Data data_of(const Scene& s) {
  const LinearSystem& sys = s.system();
  Data d{sys.mass(), sys.damping(), sys.stiffness(), sys.forcing().constant, sys.forcing().cosine, sys.forcing().sine,
         sys.forcing().frequency, {}, {}, {}, {}, {}, {}};
  for (const Stop& st : s.stops) {
    d.stops.push_back({st.s0(), st.s_cos(), st.s_sin(), st.restitution, st.stiffness, st.damping, st.preload});
    const auto H = static_cast<Eigen::Index>(st.harmonics.size());
    d.stop_hc.emplace_back(H);
    d.stop_hs.emplace_back(H);
    for (Eigen::Index i = 0; i < H; ++i) {
      d.stop_hc.back()(i) = st.h_cos(static_cast<std::size_t>(i));
      d.stop_hs.back()(i) = st.h_sin(static_cast<std::size_t>(i));
    }
  }
  for (const ForcingHarmonic& h : sys.forcing().harmonics) {
    d.Hc.push_back(h.cosine);
    d.Hs.push_back(h.sine);
  }
  for (const FrictionContact& c : s.friction) d.friction.push_back({c.normal_load, c.static_coefficient, c.kinetic_coefficient});
  return d;
}

/// The largest magnitude of a + b·scale over every entry of the data (for the affinity check:
/// a = D(p + h) + D(p − h), b = D(p), scale = −2).
double largest(const Data& a, const Data& b, double scale) {
  double m = 0.0;
  auto over = [&](const auto& x, const auto& y) { m = std::max(m, (x + scale * y).cwiseAbs().maxCoeff()); };
  over(a.M, b.M);
  over(a.C, b.C);
  over(a.K, b.K);
  over(a.F0, b.F0);
  over(a.Fc, b.Fc);
  over(a.Fs, b.Fs);
  m = std::max(m, std::abs(a.omega + scale * b.omega));
  for (std::size_t h = 0; h < a.Hc.size(); ++h) {
    over(a.Hc[h], b.Hc[h]);
    over(a.Hs[h], b.Hs[h]);
  }
  for (std::size_t j = 0; j < a.stops.size(); ++j)
    for (std::size_t i = 0; i < a.stops[j].size(); ++i) m = std::max(m, std::abs(a.stops[j][i] + scale * b.stops[j][i]));
  for (std::size_t j = 0; j < a.friction.size(); ++j)
    for (std::size_t i = 0; i < a.friction[j].size(); ++i)
      m = std::max(m, std::abs(a.friction[j][i] + scale * b.friction[j][i]));
  for (std::size_t j = 0; j < a.stop_hc.size(); ++j)
    if (a.stop_hc[j].size() > 0) {
      over(a.stop_hc[j], b.stop_hc[j]);
      over(a.stop_hs[j], b.stop_hs[j]);
    }
  return m;
}

SystemDerivative difference(const Data& plus, const Data& minus, double h) {
  SystemDerivative d;
  const double k = 1.0 / (2.0 * h);
  d.mass = (plus.M - minus.M) * k;
  d.damping = (plus.C - minus.C) * k;
  d.stiffness = (plus.K - minus.K) * k;
  d.constant = (plus.F0 - minus.F0) * k;
  d.cosine = (plus.Fc - minus.Fc) * k;
  d.sine = (plus.Fs - minus.Fs) * k;
  d.frequency = (plus.omega - minus.omega) * k;
  for (std::size_t h = 0; h < plus.Hc.size(); ++h) {
    d.harmonic_cosine.push_back((plus.Hc[h] - minus.Hc[h]) * k);
    d.harmonic_sine.push_back((plus.Hs[h] - minus.Hs[h]) * k);
  }
  for (std::size_t j = 0; j < plus.stops.size(); ++j) {
    std::array<double, 7> e{};
    for (std::size_t i = 0; i < e.size(); ++i) e[i] = (plus.stops[j][i] - minus.stops[j][i]) * k;
    d.stops.push_back({e[0], e[1], e[2], e[3], e[4], e[5], e[6]});
  }
  for (std::size_t j = 0; j < plus.friction.size(); ++j)
    d.friction.push_back({(plus.friction[j][0] - minus.friction[j][0]) * k, (plus.friction[j][1] - minus.friction[j][1]) * k,
                          (plus.friction[j][2] - minus.friction[j][2]) * k});
  for (std::size_t j = 0; j < plus.stop_hc.size(); ++j) {
    const Eigen::VectorXd c = (plus.stop_hc[j] - minus.stop_hc[j]) * k, s = (plus.stop_hs[j] - minus.stop_hs[j]) * k;
    d.stop_harmonic_cosine.emplace_back(c.data(), c.data() + c.size());
    d.stop_harmonic_sine.emplace_back(s.data(), s.data() + s.size());
  }
  return d;
}

/// How a path enters the system: the frequency, a stop's phase (closed forms), or affinely
/// with a constant derivative.
struct Entry {
  enum class Kind { frequency, phase, affine, force_parameter } kind = Kind::affine;
  int stop = -1;
  std::string name;  // force_parameter: the name in `parameters`
  SystemDerivative affine;
};

[[noreturn]] void refuse(const SceneDocument& doc, const std::string& path, const std::string& why) {
  throw SceneError(doc.file(), 1, 1, path, why);
}

Entry classify(const SceneDocument& doc, const std::string& path) {
  Entry e;
  if (path == "forcing.frequency") {
    e.kind = Entry::Kind::frequency;
    return e;
  }
  static const std::regex phase(R"(stops\[(\d+)\]\.phase)");
  std::smatch m;
  if (std::regex_match(path, m, phase)) {
    e.kind = Entry::Kind::phase;
    e.stop = std::stoi(m[1].str());
    return e;
  }
  // A named parameter of the nonlinear forces: it moves only the forces (the Taylor engine's
  // variational equations take its derivative, SystemDerivative::force_parameters).
  static const std::regex named(R"(parameters\.([A-Za-z_][A-Za-z0-9_]*))");
  if (std::regex_match(path, m, named)) {
    e.kind = Entry::Kind::force_parameter;
    e.name = m[1].str();
    if (doc.build_point().forces.forces.empty())
      refuse(doc, path, "is a parameter of the nonlinear forces, and this scene has none: it moves nothing");
    return e;
  }
  static const std::regex normal(R"(stops\[(\d+)\]\.normal\[(\d+)\])");
  if (std::regex_match(path, m, normal))
    refuse(doc, path,
           "is a component of a stop's normal, which is not a continuation parameter (the derivatives follow a stop's position, "
           "amplitude, phase, restitution and a compliant stop's stiffness, damping and preload); continue in one of "
           "those, or sweep the normal (run.kind: sweep)");
  static const std::regex surface(R"(friction\[(\d+)\]\.surface\.(amplitude|phase))");
  if (std::regex_match(path, m, surface))
    refuse(doc, path,
           "is the motion of a frictional contact's surface, which is not a continuation parameter (the derivatives "
           "follow a contact's normal_load, static and kinetic coefficients); continue in one of those, or sweep it "
           "(run.kind: sweep)");
  const double p = doc.get(path);
  const Data d0 = data_of(doc.build_point());
  // The largest step that keeps the scene valid on both sides: affine data make the central
  // difference exact to rounding, ε|D|/h, so the step is taken as large as the scene allows.
  const double base = p != 0.0 ? std::abs(p) : 1.0;
  std::string neighbour;  // why the scene beside p was invalid (the last step tried)
  for (double h = 1e-2 * base; h >= 1e-10 * base; h *= 0.1) {
    Data plus, minus;
    try {
      SceneDocument a(doc), b(doc);
      a.set(path, p + h);
      b.set(path, p - h);
      plus = data_of(a.build_point());
      minus = data_of(b.build_point());
    } catch (const SceneError& e) {
      neighbour = e.path().empty() ? e.problem() : e.path() + ": " + e.problem();
      continue;
    } catch (const InvalidInput& e) {
      neighbour = e.what();
      continue;
    }
    const double size = std::max({largest(plus, d0, 0.0), largest(minus, d0, 0.0), 1e-300});
    Data sum = plus;
    sum.M += minus.M;
    sum.C += minus.C;
    sum.K += minus.K;
    sum.F0 += minus.F0;
    sum.Fc += minus.Fc;
    sum.Fs += minus.Fs;
    sum.omega += minus.omega;
    for (std::size_t q = 0; q < sum.Hc.size(); ++q) {
      sum.Hc[q] += minus.Hc[q];
      sum.Hs[q] += minus.Hs[q];
    }
    for (std::size_t j = 0; j < sum.stops.size(); ++j)
      for (std::size_t i = 0; i < sum.stops[j].size(); ++i) sum.stops[j][i] += minus.stops[j][i];
    for (std::size_t j = 0; j < sum.friction.size(); ++j)
      for (std::size_t i = 0; i < sum.friction[j].size(); ++i) sum.friction[j][i] += minus.friction[j][i];
    for (std::size_t j = 0; j < sum.stop_hc.size(); ++j) {
      sum.stop_hc[j] += minus.stop_hc[j];
      sum.stop_hs[j] += minus.stop_hs[j];
    }
    if (largest(sum, d0, -2.0) > 64.0 * std::numeric_limits<double>::epsilon() * size)
      refuse(doc, path,
             "enters the system nonlinearly (its second difference does not vanish); continuation needs a value "
             "that enters M, C, K, the forcing or the stops linearly, forcing.frequency or a stop's phase");
    e.affine = difference(plus, minus, h);
    if (e.affine.is_zero())
      refuse(doc, path,
             "does not change the system (an initial value or a solver setting?): continue in a value of the "
             "model, the forcing or the stops");
    return e;
  }
  refuse(doc, path, "cannot be varied on its own around " + number_text(p) +
                        " (an off-diagonal matrix entry needs its mirror: continue in a model.chain value instead)" +
                        (neighbour.empty() ? std::string() : "; beside it the scene is invalid: " + neighbour));
}

SystemDerivative derivative_at(const Entry& e, const Scene& s) {
  switch (e.kind) {
    case Entry::Kind::frequency: {
      SystemDerivative d = SystemDerivative::frequency_only();
      if (s.base) {  // the base's drive depends on Ω (ω C ι, ω² M ι): its d/dΩ (base_motion.hpp)
        const HarmonicForcing rate = base_forcing_rate(s.forcing(), *s.base);
        d.cosine = rate.cosine;
        d.sine = rate.sine;
        for (const ForcingHarmonic& h : rate.harmonics) {
          d.harmonic_cosine.push_back(h.cosine);
          d.harmonic_sine.push_back(h.sine);
        }
      }
      return d;
    }
    case Entry::Kind::phase: {
      // s(t) = s0 + σ a cos(Ωt + φ): d/dφ of (sc, ss) = (σ a cos φ, −σ a sin φ) is (ss, −sc).
      SystemDerivative d;
      d.stops.resize(s.stops.size());
      const Stop& st = s.stops.at(static_cast<std::size_t>(e.stop));
      d.stops[static_cast<std::size_t>(e.stop)] = {0.0, st.s_sin(), -st.s_cos(), 0.0};
      return d;
    }
    case Entry::Kind::affine: return e.affine;
    case Entry::Kind::force_parameter: {
      SystemDerivative d;
      const auto& params = s.forces.parameters;
      d.force_parameters = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(params.size()));
      for (std::size_t j = 0; j < params.size(); ++j)
        if (params[j].first == e.name) d.force_parameters(static_cast<Eigen::Index>(j)) = 1.0;
      return d;
    }
  }
  return {};
}

/// Modal chains of at least this many masses make their modes under run_bounded, as make_engine
/// does for the run's own engine (scene.cpp).
constexpr Eigen::Index kBoundedModalFromMasses = 256;
/// Dense systems of at least this many degrees of freedom are built under run_bounded, as the
/// corrector factorises (corrector.cpp).
constexpr Eigen::Index kBoundedFromCoordinates = 64;

/// The engine continuation drives at one point of the scene (the engine the base scene resolved
/// to); a continuation makes one for each parameter value, a two-parameter curve one for each
/// point of the plane. Its set-up cannot poll the run's interrupt flag, so for large systems it
/// runs under run_bounded (bounded_wait.hpp): raising the flag throws Interrupted within 10 ms,
/// which continuation takes as an interrupted map. The same construction on the same data: the
/// same bits.
std::unique_ptr<FamilyEngine> engine_at(const Scene& s, EngineKind engine, SystemDerivative d,
                                        const SimulatorOptions& solver) {
  if (engine != EngineKind::modal || !s.friction.empty()) {
    // The dense system at this value is built here, on its first use: M's Cholesky factor and the
    // definiteness checks of C and K (LinearSystem, O(n³): seconds from a thousand coordinates on).
    const bool large = s.dof() >= kBoundedFromCoordinates;
    return run_bounded(large ? solver.interrupt : nullptr,
                       [dense = s.dense, stops = s.stops, forces = s.forces, friction = s.friction, engine,
                        d = std::move(d), solver]() mutable -> std::unique_ptr<FamilyEngine> {
                         // A friction scene's contacts are the family's "stops", after the stops
                         // if it has any (friction_tangent.hpp).
                         if (!friction.empty() && stops.empty())
                           return friction_family_engine(dense.get(), std::move(friction), std::move(d), solver);
                         ImpactSystem system(dense.get(), std::move(stops));
                         if (!friction.empty())
                           return friction_stop_family_engine(std::move(system), std::move(friction), std::move(d),
                                                              solver);
                         if (engine == EngineKind::taylor)
                           return taylor_family_engine(std::move(system), std::move(forces), std::move(d), solver);
                         return dense_family_engine(std::move(system), std::move(d), solver);
                       });
  }
  if (!s.chain) throw InvalidInput("the chain's damping is not proportional at this value (modal engine)");
  // The chain's modes at this value (one LAPACK call, and the family engine's own mechanics).
  const bool long_chain = s.chain->dof() >= kBoundedModalFromMasses;
  return run_bounded(long_chain ? solver.interrupt : nullptr,
                     [chain = *s.chain, stops = s.stops, d = std::move(d),
                      options = modal_options(solver)]() mutable -> std::unique_ptr<FamilyEngine> {
                       return modal_family_engine(std::move(chain), std::move(stops), std::move(d), options);
                     });
}

std::vector<Eigen::VectorXd> multipliers_part(const std::vector<BranchPoint>& pts, bool imag) {
  std::vector<Eigen::VectorXd> out;
  for (const BranchPoint& p : pts)
    out.push_back(imag ? Eigen::VectorXd(p.multipliers.values.imag()) : Eigen::VectorXd(p.multipliers.values.real()));
  return out;
}

void write_branches(ResultFile& file, const ContinuationResult& r, std::size_t n, std::size_t m, const std::string& path) {
  std::vector<BranchPoint> all;
  std::vector<std::int64_t> id, k, stable, zeros, located, iterations, first, count, branch_k, parent;
  std::vector<std::string> ends;
  for (std::size_t b = 0; b < r.branches.size(); ++b) {
    const Branch& br = r.branches[b];
    first.push_back(static_cast<std::int64_t>(all.size()));
    count.push_back(static_cast<std::int64_t>(br.points.size()));
    branch_k.push_back(br.k);
    parent.push_back(br.parent);
    ends.push_back(br.end);
    for (const BranchPoint& p : br.points) {
      all.push_back(p);
      id.push_back(static_cast<std::int64_t>(b));
    }
  }
  std::vector<double> p, phase, t0, radius, tangent, residual;
  std::vector<Eigen::VectorXd> x, v, signature, sticking, x_fixed, v_fixed;
  std::vector<std::int64_t> fixed_ok;
  for (const BranchPoint& q : all) {
    // The state at the fixed phase (0 where its run failed: fixed_ok says which).
    const bool ok = q.x_fixed.size() == q.x.size() && q.x_fixed.allFinite() && q.v_fixed.allFinite();
    fixed_ok.push_back(ok ? 1 : 0);
    x_fixed.push_back(ok ? q.x_fixed : Eigen::VectorXd::Zero(q.x.size()));
    v_fixed.push_back(ok ? q.v_fixed : Eigen::VectorXd::Zero(q.v.size()));
    sticking.push_back(q.sticking);
    p.push_back(q.p);
    phase.push_back(q.phase);
    t0.push_back(q.t0);
    k.push_back(q.k);
    stable.push_back(q.multipliers.stable ? 1 : 0);
    zeros.push_back(q.multipliers.structural_zeros);
    radius.push_back(q.multipliers.spectral_radius);
    tangent.push_back(q.tangent_p);
    residual.push_back(q.residual);
    located.push_back(q.located ? 1 : 0);
    iterations.push_back(q.corrector_iterations);
    x.push_back(q.x);
    v.push_back(q.v);
    Eigen::VectorXd sig(static_cast<Eigen::Index>(3 * m));
    for (std::size_t j = 0; j < m; ++j) {
      sig(static_cast<Eigen::Index>(j)) = q.signature.impacts[j];
      sig(static_cast<Eigen::Index>(m + j)) = q.signature.chatters[j];
      sig(static_cast<Eigen::Index>(2 * m + j)) = q.signature.phases[j];
    }
    signature.push_back(sig);
  }
  const std::size_t rows = all.size();
  std::vector<std::string> columns;
  for (const char* what : {"impacts", "chatters", "phases"})
    for (std::size_t j = 0; j < m; ++j) columns.push_back(fmt::format("{} s{}", what, j));
  Dataset sig = table("signature", signature, 3 * m);
  sig.labels.emplace_back("columns", columns);
  file.write_group("branch",
                   {integers("branch", id), reals("p", p, {rows}), reals("phase", phase, {rows}), reals("t0", t0, {rows}),
                    table("x", x, n), table("v", v, n), integers("k", k), integers("stable", stable),
                    reals("spectral_radius", radius, {rows}), integers("structural_zeros", zeros),
                    table("multipliers_real", multipliers_part(all, false), 2 * n),
                    table("multipliers_imag", multipliers_part(all, true), 2 * n), sig,
                    table("sticking_fraction", sticking, m), reals("tangent_p", tangent, {rows}),
                    reals("residual", residual, {rows}),
                    integers("located", located), integers("corrector_iterations", iterations),
                    table("x_fixed", x_fixed, n), table("v_fixed", v_fixed, n), integers("fixed_ok", fixed_ok)},
                   {{"parameter", path}, {"fixed_phase", fmt::format("{}", r.fixed_phase)}});
  // The summary of the branches and how they connect.
  std::vector<std::int64_t> from, joins, located_on;
  std::vector<double> p_min, p_max;
  std::vector<std::string> starts;
  for (std::size_t b = 0; b < r.branches.size(); ++b) {
    const Branch& br = r.branches[b];
    from.push_back(br.bifurcation);
    joins.push_back(br.joins);
    starts.push_back(br.start);
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const BranchPoint& q : br.points) lo = std::min(lo, q.p), hi = std::max(hi, q.p);
    p_min.push_back(br.points.empty() ? 0.0 : lo);
    p_max.push_back(br.points.empty() ? 0.0 : hi);
    located_on.push_back(std::count_if(r.bifurcations.begin(), r.bifurcations.end(),
                                       [b](const Bifurcation& f) { return f.branch == static_cast<int>(b); }));
  }
  const std::size_t nb = r.branches.size();
  Dataset end_count = integers("count", count);
  end_count.labels.emplace_back("end", ends);
  file.write_group("branches",
                   {integers("k", branch_k), integers("parent", parent), integers("first", first), end_count,
                    integers("bifurcation", from), integers("joins", joins), reals("p_min", p_min, {nb}),
                    reals("p_max", p_max, {nb}), integers("bifurcations", located_on), detail::texts("start", starts)},
                   {{"budget", r.budget}});
  std::vector<std::int64_t> rp, rb, rk, rknown, rshift;
  std::vector<double> rpv, rdist;
  for (const RecognisedBranch& q : r.recognised) {
    rp.push_back(q.parent);
    rb.push_back(q.bifurcation);
    rk.push_back(q.k);
    rknown.push_back(q.known);
    rshift.push_back(q.shift);
    rpv.push_back(q.p);
    rdist.push_back(q.distance);
  }
  const std::size_t nr = r.recognised.size();
  file.write_group("recognised", {integers("parent", rp), integers("bifurcation", rb), integers("k", rk),
                                  reals("p", rpv, {nr}), integers("known", rknown), integers("shift", rshift),
                                  reals("distance", rdist, {nr})});
}

/// The branches and how they connect: per branch its period, parameter range, parent and the
/// doubling it was switched at, the bifurcations located on it and its end; the switchings onto
/// branches already followed; the budget, if one was reached.
std::string branch_summary(const ContinuationResult& r, const std::string& path) {
  std::string text = fmt::format("  {:>6} {:>6} {:>15} {:>15} {:>6} {:>6} {:>6}  {}\n", "branch", "period",
                                 path.size() <= 15 ? path + " min" : "p min", "p max", "parent", "from", "bifs", "end");
  for (std::size_t b = 0; b < r.branches.size(); ++b) {
    const Branch& br = r.branches[b];
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const BranchPoint& q : br.points) lo = std::min(lo, q.p), hi = std::max(hi, q.p);
    const auto located = std::count_if(r.bifurcations.begin(), r.bifurcations.end(),
                                       [b](const Bifurcation& f) { return f.branch == static_cast<int>(b); });
    auto id = [](int i) { return i >= 0 ? std::to_string(i) : std::string("-"); };
    text += fmt::format("  {:>6} {:>5}T {:>15.10f} {:>15.10f} {:>6} {:>6} {:>6}  {}\n", b, br.k, lo, hi, id(br.parent),
                        id(br.bifurcation), located, br.end);
  }
  for (const RecognisedBranch& q : r.recognised)
    text += fmt::format("  the period-{}T branch from bifurcation {} (on branch {}) is branch {}, already followed "
                        "(its orbit at {} = {:.10f}, shifted by {} periods, within {:.1e}): not followed again\n",
                        q.k, q.bifurcation, q.parent, q.known, path, q.p, q.shift, q.distance);
  if (!r.budget.empty()) text += "  budget: " + r.budget + "\n";
  return text;
}

void write_bifurcations(ResultFile& file, const ContinuationResult& r, std::size_t n) {
  std::vector<std::int64_t> kind, stop, branch, smooth, evaluations, k;
  std::vector<double> p, lo, hi, value, phase, t0;
  std::vector<Eigen::VectorXd> x, v;
  std::vector<std::string> notes;
  for (const Bifurcation& b : r.bifurcations) {
    kind.push_back(static_cast<std::int64_t>(b.kind));
    stop.push_back(b.stop);
    branch.push_back(b.branch);
    smooth.push_back(b.smooth ? 1 : 0);
    evaluations.push_back(b.evaluations);
    k.push_back(b.point.k);
    p.push_back(b.p);
    lo.push_back(b.p_low);
    hi.push_back(b.p_high);
    value.push_back(std::isfinite(b.value) ? b.value : 0.0);  // meaningful where smooth = 1
    phase.push_back(b.point.phase);
    t0.push_back(b.point.t0);
    x.push_back(b.point.x);
    v.push_back(b.point.v);
    notes.push_back(b.note);
  }
  const std::size_t rows = r.bifurcations.size();
  Dataset kinds = integers("kind", kind);
  kinds.labels.emplace_back("names", bifurcation_kind_names());
  Dataset notes_on = integers("smooth", smooth);
  notes_on.labels.emplace_back("notes", notes);
  file.write_group("bifurcations",
                   {kinds, reals("p", p, {rows}), reals("p_low", lo, {rows}), reals("p_high", hi, {rows}),
                    integers("stop", stop), integers("branch", branch), reals("value", value, {rows}), notes_on,
                    integers("evaluations", evaluations), integers("k", k), reals("phase", phase, {rows}),
                    reals("t0", t0, {rows}), table("x", x, n), table("v", v, n)});
}

void write_curves(ResultFile& file, const std::vector<Curve>& curves, const std::string& p1, const std::string& p2) {
  std::vector<std::int64_t> id, kind, stop;
  std::vector<double> a, b, value;
  std::vector<std::string> ends;
  for (std::size_t c = 0; c < curves.size(); ++c) {
    ends.push_back(curves[c].end);
    for (const CurvePoint& q : curves[c].points) {
      id.push_back(static_cast<std::int64_t>(c));
      kind.push_back(static_cast<std::int64_t>(curves[c].kind));
      stop.push_back(curves[c].stop);
      a.push_back(q.p1);
      b.push_back(q.p2);
      value.push_back(std::isfinite(q.value) ? q.value : 0.0);
    }
  }
  const std::size_t rows = id.size();
  Dataset kinds = integers("kind", kind);
  kinds.labels.emplace_back("names", bifurcation_kind_names());
  Dataset curve = integers("curve", id);
  curve.labels.emplace_back("end", ends);
  file.write_group("curve", {curve, kinds, integers("stop", stop), reals("p1", a, {rows}), reals("p2", b, {rows}),
                             reals("value", value, {rows})},
                   {{"p1", p1}, {"p2", p2}});
}

/// /codim2: the codimension-two points of the curves, one row each (docs/results.md).
void write_codim_two(ResultFile& file, const std::vector<Curve>& curves, const std::string& p1, const std::string& p2) {
  std::vector<std::int64_t> id, kind, stop, after, located;
  std::vector<double> a, b, width, value;
  std::vector<std::string> notes;
  for (std::size_t c = 0; c < curves.size(); ++c)
    for (const CodimTwoPoint& q : curves[c].special) {
      id.push_back(static_cast<std::int64_t>(c));
      kind.push_back(static_cast<std::int64_t>(q.kind));
      stop.push_back(q.stop);
      after.push_back(q.after);
      located.push_back(q.located ? 1 : 0);
      a.push_back(q.p1);
      b.push_back(q.p2);
      width.push_back(q.width);
      value.push_back(std::isfinite(q.value) ? q.value : 0.0);
      notes.push_back(q.note);
    }
  const std::size_t rows = id.size();
  Dataset kinds = integers("kind", kind);
  kinds.labels.emplace_back("names", codim_two_kind_names());
  Dataset curve = integers("curve", id);
  if (rows > 0) curve.labels.emplace_back("notes", notes);
  file.write_group("codim2", {curve, kinds, integers("stop", stop), integers("after", after), reals("p1", a, {rows}),
                              reals("p2", b, {rows}), integers("located", located), reals("width", width, {rows}),
                              reals("value", value, {rows})},
                   {{"p1", p1}, {"p2", p2}});
}

}  // namespace

SystemDerivative parameter_derivative(const SceneDocument& doc, const std::string& path) {
  return derivative_at(classify(doc, path), doc.build_point());
}

ContinuationFamily continuation_family(const SceneDocument& doc, const std::string& path, EngineKind engine,
                                         const SimulatorOptions& solver) {
  const Entry entry = classify(doc, path);
  return [doc, path, entry, engine, solver](double p) {
    // A value the scene rejects (a corrector's Newton step can reach Ω < 0 near a grazing, where
    // the map's Jacobian is nearly singular) is no system at p: InvalidInput, which continuation
    // takes as "no orbit there" and answers with a shorter step, rather than the end of the run.
    try {
      SceneDocument point(doc);
      point.set(path, p);
      const Scene s = point.build_point();
      return engine_at(s, engine, derivative_at(entry, s), solver);
    } catch (const SceneError& e) {
      throw InvalidInput(e.what());
    }
  };
}

/// /impact_map of a continuation (record.impact_map; docs/results.md): each branch point's orbit
/// run once over its period kT from its section state, with the impacts of that run and the
/// point's row of /branch. An orbit whose run stops early (or an interrupted run) has no rows.
void write_impact_map(ResultFile& file, const SceneDocument& doc, const Scene& scene, const std::string& path,
                      const ContinuationResult& result, const RunRequest& request) {
  std::vector<double> t, phase, velocity;
  std::vector<std::int64_t> stop, point;
  std::vector<Eigen::VectorXd> x, v;
  SceneDocument at(doc);
  std::int64_t row = 0;
  for (const Branch& b : result.branches)
    for (const BranchPoint& q : b.points) {
      if (request.interrupt && request.interrupt->load()) break;
      at.set(path, q.p);
      Scene built = at.build_point();
      built.solver.interrupt = request.interrupt;
      ImpactMap map;
      std::unique_ptr<vibro::Engine> engine;
      try {
        engine = make_engine(built);  // a long modal chain's set-up is bounded: Interrupted
      } catch (const Interrupted&) {
        break;
      }
      const RunSummary s = engine->run(q.t0, q.x, q.v, q.t0 + q.k * built.period(), {&map});
      if (s.status == RunStatus::completed) {
        t.insert(t.end(), map.t.begin(), map.t.end());
        phase.insert(phase.end(), map.phase.begin(), map.phase.end());
        velocity.insert(velocity.end(), map.velocity.begin(), map.velocity.end());
        stop.insert(stop.end(), map.stop.begin(), map.stop.end());
        x.insert(x.end(), map.x.begin(), map.x.end());
        v.insert(v.end(), map.v.begin(), map.v.end());
        point.insert(point.end(), map.t.size(), row);
      }
      ++row;
    }
  std::vector<std::string> names;
  for (const Stop& st : scene.stops) names.push_back(st.name);
  const std::size_t r = t.size(), n = static_cast<std::size_t>(scene.dof());
  Dataset stops = integers("stop", stop, {r}, Dataset::Type::i32);
  stops.labels.emplace_back("stops", names);
  file.write_group("impact_map", {reals("t", t, {r}), std::move(stops), reals("phase", phase, {r}),
                                  reals("velocity", velocity, {r}), table("x", x, n), table("v", v, n),
                                  integers("point", point)});
}

RunReport run_continuation(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  const auto wall_start = std::chrono::steady_clock::now();
  const ContinueSpec& spec = scene.run.continuation;
  // The constraints of the signature and of the bifurcations: the stops, or the frictional contacts.
  std::vector<std::string> constraint_names;
  for (const Stop& st : scene.stops) constraint_names.push_back(st.name);
  for (const FrictionContact& fc : scene.friction) constraint_names.push_back(fc.name);
  const std::size_t n = static_cast<std::size_t>(scene.dof()), m = constraint_names.size();
  const double p0 = doc.get(spec.path);

  ContinuationOptions o;
  o.p_min = spec.p_min;
  o.p_max = spec.p_max;
  o.direction = spec.direction;
  o.period = spec.period;
  o.phase = spec.phase;
  o.step = spec.step;
  o.min_step = spec.min_step;
  o.max_step = spec.max_step;
  o.parameter_scale = spec.parameter_scale;
  o.max_points = spec.max_points;
  o.tolerance = spec.tolerance;
  o.locate = spec.locate;
  o.locate_tolerance = spec.locate_tolerance;
  o.max_doublings = spec.max_doublings;
  o.max_branches = spec.max_branches;
  o.max_total_points = spec.max_total_points;
  o.switch_at_start = spec.switch_at_start;
  o.solver = scene.solver;
  o.solver.interrupt = request.interrupt;
  const ContinuationFamily family = continuation_family(doc, spec.path, scene.engine, o.solver);

  ResultFile file = open_result_file(request, scene, current_meta(1));
  // The guess: the transient from `initial`, then Newton shooting at p0.
  const double t_guess = scene.t0 + scene.run.transient_periods * scene.period();
  Scene built = scene;
  built.solver = o.solver;
  // The run's engine (a long modal chain's modes, under run_bounded): an interrupt in its set-up
  // is an interrupted transient, the file written with no branch.
  RunSummary warm;
  try {
    warm = make_engine(built)->run(scene.t0, scene.x0, scene.v0, t_guess);
  } catch (const Interrupted&) {
    warm.status = RunStatus::interrupted;
  }
  const auto stopped = [&] { return request.interrupt && request.interrupt->load(); };
  if (warm.status != RunStatus::completed && warm.status != RunStatus::interrupted)
    throw SceneError(scene.file, 1, 1, "run.transient_periods",
                     std::string("the transient before the first orbit stopped early (") + to_string(warm.status) +
                         "): " + warm.message);
  auto progress = [&](const Branch& b, const BranchPoint& q) {
    if (q.located) return;
    std::fprintf(stderr, "  branch k=%d  %s = %.10f  %-8s  max|mu| = %-10.4g  %s\n", b.k, spec.path.c_str(), q.p,
                 q.multipliers.stable ? "stable" : "unstable", q.multipliers.spectral_radius, q.signature.text().c_str());
  };
  // Interrupted before the first branch point (the transient, the start's shooting or its
  // factorisations): no branch, the file written with status interrupted.
  ContinuationResult result;
  try {
    if (warm.status == RunStatus::completed) result = continue_orbits(family, p0, t_guess, warm.x, warm.v, o, progress);
  } catch (const Interrupted&) {
  } catch (const InvalidInput& e) {
    if (!stopped()) throw SceneError(scene.file, 1, 1, "run.continue", e.what());
  }
  std::vector<Curve> curves;
  // The curves' two parameters classified: the dense system built at the point and beside it,
  // three times or more (M's Cholesky factor, C's and K's definiteness: O(n³), seconds from a
  // thousand coordinates on), under run_bounded for large systems as the corrector's LU is; an
  // interrupt there follows no curve.
  std::optional<std::pair<Entry, Entry>> entries;
  if (!spec.curve_path.empty() && !result.bifurcations.empty() && !stopped()) {
    try {
      entries = run_bounded(scene.dof() >= kBoundedFromCoordinates ? request.interrupt : nullptr,
                            [doc, p1 = spec.path, p2 = spec.curve_path] {
                              return std::pair<Entry, Entry>(classify(doc, p1), classify(doc, p2));
                            });
    } catch (const Interrupted&) {
    }
  }
  if (entries) {
    const Entry& e1 = entries->first;
    const Entry& e2 = entries->second;
    // A point the scene rejects (a corrector's step can reach Ω < 0) is no system there, as in
    // continuation_family: InvalidInput, which the line's continuation takes as no orbit.
    const PlaneContinuationFamily plane = [&doc, &spec, &o, e1, e2, engine = scene.engine](double a, double b) {
      try {
        SceneDocument point(doc);
        point.set(spec.path, a);
        point.set(spec.curve_path, b);
        const Scene s = point.build_point();
        SystemDerivative d1 = derivative_at(e1, s);
        return PlaneEngine{engine_at(s, engine, d1, o.solver), d1, derivative_at(e2, s)};
      } catch (const SceneError& e) {
        throw InvalidInput(e.what());
      }
    };
    CurveOptions co;
    co.p1_min = spec.p_min;
    co.p1_max = spec.p_max;
    co.p2_min = spec.curve_min;
    co.p2_max = spec.curve_max;
    co.step = spec.curve_step;
    co.max_points = spec.curve_max_points;
    co.branch = o;
    const double p2 = doc.get(spec.curve_path);
    for (const Bifurcation& b : result.bifurcations) {
      const std::string kind = to_string(b.kind);
      if (!b.smooth || std::find(spec.curve_kinds.begin(), spec.curve_kinds.end(), kind) == spec.curve_kinds.end()) continue;
      for (int dir : {1, -1}) {
        if (stopped()) break;  // interrupted: no further curve (the one cut short ends "interrupted")
        co.direction = dir;
        curves.push_back(follow_curve(plane, b, p2, co));
        std::fprintf(stderr, "  curve of the %s at %s = %.10f (stop %d), %s: %zu points (%s)\n", kind.c_str(),
                     spec.path.c_str(), b.p, b.stop, dir > 0 ? "up" : "down", curves.back().points.size(),
                     curves.back().end.c_str());
        for (const CodimTwoPoint& q : curves.back().special)
          std::fprintf(stderr, "    %s at %s = %.10f, %s = %.10f%s%s%s\n", to_string(q.kind), spec.path.c_str(), q.p1,
                       spec.curve_path.c_str(), q.p2, q.located ? "" : " (not located)", q.note.empty() ? "" : ": ",
                       q.note.c_str());
      }
    }
  }

  write_branches(file, result, n, m, spec.path);
  write_bifurcations(file, result, n);
  if (scene.record.impact_map) write_impact_map(file, doc, scene, spec.path, result, request);
  if (!spec.curve_path.empty()) write_curves(file, curves, spec.path, spec.curve_path);
  // Codimension-two points exist on curves of folds, doublings and tori only.
  bool multiplier_kinds = false;
  for (const std::string& kind : spec.curve_kinds) multiplier_kinds |= kind != "grazing" && kind != "rising";
  if (!spec.curve_path.empty() && multiplier_kinds) write_codim_two(file, curves, spec.path, spec.curve_path);
  const bool interrupted = request.interrupt && request.interrupt->load();
  std::size_t points = 0;
  for (const Branch& b : result.branches) points += b.points.size();
  file.set_outcome(interrupted ? "interrupted" : "completed",
                   interrupted ? "interrupted: the branches end where the interrupt stopped their orbits"
                               : (result.budget.empty() ? "" : "budget: " + result.budget),
                   {{"branches", static_cast<std::int64_t>(result.branches.size())},
                    {"points", static_cast<std::int64_t>(points)},
                    {"bifurcations", static_cast<std::int64_t>(result.bifurcations.size())},
                    {"recognised", static_cast<std::int64_t>(result.recognised.size())},
                    {"tangent_maps", result.maps}});
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  RunMeta meta = current_meta(1);
  meta.wall_seconds = wall;
  file.finish(meta);

  std::string text = fmt::format("Continued {} in [{}, {}]: {} branches, {} points, {} tangent maps, {:.2f} s.\n",
                                 spec.path, spec.p_min, spec.p_max, result.branches.size(), points, result.maps, wall);
  text += branch_summary(result, spec.path);
  text += fmt::format("  {:<16} {:>6} {:>18} {:>10} {:>11} {:>7}\n", "bifurcation", "stop", spec.path, "bracket", "value", "branch");
  for (const Bifurcation& b : result.bifurcations)
    text += fmt::format("  {:<16} {:>6} {:>18.12f} {:>10.1e} {:>11} {:>7}\n", to_string(b.kind),
                        b.stop >= 0 ? constraint_names.at(static_cast<std::size_t>(b.stop)) : std::string("-"), b.p,
                        b.p_high - b.p_low, b.smooth ? fmt::format("{:.2e}", b.value) : std::string("(bisected)"), b.branch);
  text += fmt::format("Results in {}.", file.path());
  return {interrupted ? 130 : 0, text, request.in_memory ? file.image() : std::vector<char>{}};
}

}  // namespace vibro::io

namespace vibro::io::detail {
namespace {

/// run.continue (docs/scenes.md).
void parse_continue_section(RunSection& s) {
  Reader& r = s.r;
  RunSpec& run = s.run;
  // The parameters with their place and dD/dp, checked once the engine is known: continuation
  // on the modal engine differentiates along Ω, the forcing and the stops' data only, and a path
  // that moves M, C or K moves the chain's modes (analysis/modal_tangent.hpp).
  struct ContinuationPath {
    YAML::Node at;
    std::string key, path;
    SystemDerivative derivative;
  };
  auto paths = std::make_shared<std::vector<ContinuationPath>>();
  const YAML::Node ct = s.node;
  if (ct && s.full) {
    ContinueSpec& c = run.continuation;
    r.expect_map(ct, "run.continue", {"path", "range", "direction", "period", "phase", "step", "min_step", "max_step",
                                      "parameter_scale", "max_points", "tolerance", "locate", "locate_tolerance", "max_doublings", "max_branches",
                                      "max_total_points", "curve", "switch"});
    // A continuation parameter: a number the file sets, outside `run` (and, below, one that
    // moves the system: kinds/continue.cpp checks that through the parameter's derivative).
    auto parameter = [&](const YAML::Node& node, const std::string& path) {
      if (!node) r.fail(ct, path, "missing: the scene value to continue in, e.g. forcing.frequency");
      const std::string text = r.text(node, path);
      if (text.rfind("run.", 0) == 0) r.fail(node, path, "the run section cannot be a parameter");
      try {
        (void)s.doc.get(text);
      } catch (const SceneError& e) {
        r.fail(node, path, "'" + text + "' does not name a number in this scene: " + e.problem());
      }
      return text;
    };
    auto range = [&](const YAML::Node& node, const std::string& path, double& lo, double& hi, double value) {
      if (!node) r.fail(ct, path, "missing: [min, max], the limits of the parameter");
      const std::vector<double> v = r.numbers(node, path, 2, "min, max", false);
      if (!(v[0] < v[1])) r.fail(node, path, "expected min < max, found [" + number_text(v[0]) + ", " + number_text(v[1]) + "]");
      if (!(value >= v[0] && value <= v[1]))
        r.fail(node, path, "the scene's value " + number_text(value) + " lies outside [" + number_text(v[0]) + ", " +
                               number_text(v[1]) + "]: the branch starts there");
      lo = v[0];
      hi = v[1];
    };
    // The parameter must move the system, linearly or in closed form (vibro/io/kinds/continue.hpp).
    // Kept, with their place, for the engine's check below (what the modal engine differentiates).
    auto moves = [&](const YAML::Node& node, const std::string& key, const std::string& path) {
      try {
        paths->push_back({node, key, path, parameter_derivative(s.doc, path)});
      } catch (const SceneError& e) {
        r.fail(node, key, "'" + path + "' " + e.problem());
      }
    };
    c.path = parameter(ct["path"], "run.continue.path");
    moves(ct["path"], "run.continue.path", c.path);
    range(ct["range"], "run.continue.range", c.p_min, c.p_max, s.doc.get(c.path));
    if (ct["direction"]) c.direction = r.choice(ct["direction"], "run.continue.direction", {"up", "down"}) == "up" ? 1 : -1;
    if (ct["period"]) c.period = static_cast<int>(r.integer(ct["period"], "run.continue.period", 1, 1024));
    if (ct["phase"]) c.phase = r.number_in(ct["phase"], "run.continue.phase", -1e3, 1e3, "a phase in radians");
    if (ct["step"]) c.step = r.number_in(ct["step"], "run.continue.step", 1e-12, 1.0, "a step in (0, 1] (scaled arclength)");
    if (ct["min_step"]) c.min_step = r.number_in(ct["min_step"], "run.continue.min_step", 1e-15, 1.0, "a step in (0, 1]");
    if (ct["max_step"]) c.max_step = r.number_in(ct["max_step"], "run.continue.max_step", 1e-12, 1.0, "a step in (0, 1]");
    if (c.min_step > c.max_step) r.fail(ct, "run.continue.min_step", "must not exceed run.continue.max_step");
    if (ct["parameter_scale"])
      c.parameter_scale = r.number_in(ct["parameter_scale"], "run.continue.parameter_scale", std::numeric_limits<double>::min(),
                                      std::numeric_limits<double>::max(), "a scale > 0 in the parameter's units");
    if (ct["max_points"]) c.max_points = static_cast<int>(r.integer(ct["max_points"], "run.continue.max_points", 2, 1000000));
    if (ct["tolerance"]) c.tolerance = r.number_in(ct["tolerance"], "run.continue.tolerance", 1e-15, 1e-4, "a relative tolerance in [1e-15, 1e-4]");
    if (ct["locate"]) c.locate = r.boolean(ct["locate"], "run.continue.locate");
    if (ct["locate_tolerance"]) c.locate_tolerance = r.number_in(ct["locate_tolerance"], "run.continue.locate_tolerance", 1e-15, 1e300, "a width > 0 in the parameter's units");
    if (ct["max_doublings"]) c.max_doublings = static_cast<int>(r.integer(ct["max_doublings"], "run.continue.max_doublings", 0, 8));
    if (ct["max_branches"]) c.max_branches = static_cast<int>(r.integer(ct["max_branches"], "run.continue.max_branches", 1, 100000));
    if (ct["max_total_points"]) c.max_total_points = static_cast<long>(r.integer(ct["max_total_points"], "run.continue.max_total_points", 2, 100000000));
    if (ct["switch"])  // the only switching a start can ask for (a restart at a located doubling)
      c.switch_at_start = r.choice(ct["switch"], "run.continue.switch", {"period_doubling", "none"}) == "period_doubling";
    if (const YAML::Node cv = ct["curve"]) {
      r.expect_map(cv, "run.continue.curve", {"path", "range", "step", "max_points", "kinds"});
      c.curve_path = parameter(cv["path"], "run.continue.curve.path");
      if (c.curve_path == c.path) r.fail(cv["path"], "run.continue.curve.path", "must differ from run.continue.path");
      moves(cv["path"], "run.continue.curve.path", c.curve_path);
      range(cv["range"], "run.continue.curve.range", c.curve_min, c.curve_max, s.doc.get(c.curve_path));
      if (cv["step"]) c.curve_step = r.number_in(cv["step"], "run.continue.curve.step", 1e-9, 1.0, "a step in (0, 1] (scaled)");
      if (cv["max_points"]) c.curve_max_points = static_cast<int>(r.integer(cv["max_points"], "run.continue.curve.max_points", 2, 100000));
      if (const YAML::Node k = cv["kinds"]) {
        if (!k.IsSequence() || k.size() == 0)
          r.fail(k, "run.continue.curve.kinds", "expected a list of grazing, rising, fold, period_doubling, neimark_sacker");
        c.curve_kinds.clear();
        for (std::size_t i = 0; i < k.size(); ++i)
          c.curve_kinds.push_back(r.choice(k[i], "run.continue.curve.kinds[" + std::to_string(i) + "]",
                                           {"grazing", "rising", "fold", "period_doubling", "neimark_sacker"}));
      }
    }
  }
  s.engine_checks.push_back([paths, &r](EngineKind engine, const std::string& reason) {
    if (engine == EngineKind::modal)
      for (const ContinuationPath& c : *paths) {
        std::vector<std::string> moved;
        const SystemDerivative& d = c.derivative;
        for (const auto& [m, name] : {std::pair{&d.mass, "mass"}, {&d.damping, "damping"}, {&d.stiffness, "stiffness"}})
          if (m->size() > 0 && !m->isZero(0.0)) moved.emplace_back(name);
        if (moved.empty()) continue;
        std::string list = moved.front();
        for (std::size_t i = 1; i < moved.size(); ++i) list += (i + 1 == moved.size() ? " and " : ", ") + moved[i];
        r.fail(c.at, c.key,
               "'" + c.path + "' moves the " + list + (moved.size() > 1 ? " matrices" : " matrix") + ", and this scene resolves to the modal engine (" + reason +
                   "), whose continuation differentiates only along the forcing frequency, the forcing and the stops' "
                   "data (M, C and K fix its modes): set solver.engine: dense, or continue in one of those");
      }
    if (engine == EngineKind::modal)  // a compliant stop's spring or dashpot moves its engaged sets' modes
      for (const ContinuationPath& c : *paths)
        for (std::size_t j = 0; j < c.derivative.stops.size(); ++j)
          if (c.derivative.stops[j].stiffness != 0.0 || c.derivative.stops[j].damping != 0.0) {
            r.fail(c.at, c.key,
                   "'" + c.path + "' moves the stiffness or damping of compliant stops[" + std::to_string(j) +
                       "], and this scene resolves to the modal engine (" + reason +
                       "), which keeps the modes of the contact sets it is engaged in fixed: set solver.engine: dense, "
                       "or continue in its preload, its position or another parameter");
            break;
          }
    if (engine == EngineKind::taylor)  // the lifted variational equation does not move M (taylor_tangent.cpp)
      for (const ContinuationPath& c : *paths)
        if (c.derivative.mass.size() > 0 && !c.derivative.mass.isZero(0.0))
          r.fail(c.at, c.key,
                 "'" + c.path + "' moves the mass matrix, and this scene runs on the Taylor engine (" + reason +
                     "), whose continuation differentiates along Ω, the forcing, C, K, the stops' data and the "
                     "parameters of the forces: continue in one of those");
  });
}

}  // namespace

RunKindInfo continue_kind() {
  RunKindInfo k;
  k.name = "continue";
  k.kind = RunSpec::Kind::continuation;
  k.summary = "branches of periodic orbits by shooting and pseudo-arclength continuation, their stability and bifurcations";
  k.section = "continue";
  k.missing = "missing: run.kind: continue needs run.continue (path and range)";
  k.groups = {"branch", "branches", "recognised", "bifurcations", "curve", "codim2", "impact_map"};
  k.every_process = false;
  k.stoppable = true;
  k.parse = parse_continue_section;
  k.run = run_continuation;
  return k;
}

}  // namespace vibro::io::detail
