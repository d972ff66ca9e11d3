#include "info.hpp"

#include "vibro/io/run_kinds.hpp"

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include <cmath>
#include <stdexcept>

namespace vibro::cli {
namespace {

std::string matrix_text(const Eigen::MatrixXd& m, const std::string& indent) {
  std::string out;
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    out += indent + "[";
    for (Eigen::Index j = 0; j < m.cols(); ++j) {
      const double v = std::abs(m(i, j)) < 1e-14 ? 0.0 : m(i, j);
      out += fmt::format("{}{:>11.6g}", j ? ", " : "", v);
    }
    out += "]\n";
  }
  return out;
}

std::string vector_text(const Eigen::VectorXd& v) {
  std::string out = "[";
  for (Eigen::Index i = 0; i < v.size(); ++i) out += fmt::format("{}{:.6g}", i ? ", " : "", v(i));
  return out + "]";
}

std::string set_text(const ContactSet& s) {
  std::string out = "{";
  for (std::size_t i = 0; i < s.size(); ++i) out += fmt::format("{}{}", i ? ", " : "", s[i]);
  return out + "}";
}

std::string stops_text(const io::Scene& scene) {
  // "  moving ±a phase φ" and "  order k: cos c sin s" per higher harmonic; empty for a fixed stop.
  auto motion_text = [](const Stop& s) {
    std::string m = s.amplitude > 0 ? fmt::format("  moving ±{:.6g} phase {:.6g}", s.amplitude, s.phase) : "";
    for (const StopHarmonic& h : s.harmonics) m += fmt::format("  order {}: cos {:.6g} sin {:.6g}", h.order, h.cosine, h.sine);
    return m;
  };
  std::string out = "\nStops (g = w·x - s(t) ≤ 0):\n";
  for (std::size_t j = 0; j < scene.stops.size(); ++j) {
    const Stop& s = scene.stops[j];
    if (s.kind == Stop::Kind::normal) {
      std::string n;
      for (Eigen::Index i = 0; i < s.direction.size(); ++i) n += fmt::format("{}{:.6g}", i ? ", " : "", s.direction(i));
      out += fmt::format("  [{}] {:<20} normal  n = [{}]  at {:.6g}  r = {:.6g}{}\n", j, s.name, n, s.position, s.restitution,
                         motion_text(s));
      continue;
    }
    const char* kind = s.kind == Stop::Kind::upper ? "upper" : s.kind == Stop::Kind::lower ? "lower" : "between";
    out += fmt::format("  [{}] {:<20} {:<7} mass {}{}  at {:.6g}  r = {:.6g}{}\n", j, s.name, kind, s.mass,
                       s.kind == Stop::Kind::between ? fmt::format(" - mass {}", s.other) : "", s.position,
                       s.restitution,
                       motion_text(s));
  }
  return out;
}

/// A scene for the modal engine: its chain's natural frequencies from the tridiagonal
/// A = M^{-1/2} K M^{-1/2} (eigenvalues only: O(n²) time, O(n) memory; no mode shapes, no dense
/// matrices, no contact sets — those are the dense engine's).
std::string describe_modal(const io::Scene& scene) {
  const BandedChain& chain = *scene.chain;
  const Eigen::Index n = chain.dof();
  const Eigen::VectorXd inv_sqrt_m = chain.mass.cwiseSqrt().cwiseInverse();
  const Eigen::VectorXd diag = chain.stiffness_diagonal.cwiseProduct(inv_sqrt_m.cwiseAbs2());
  Eigen::VectorXd off(std::max<Eigen::Index>(n - 1, 0));
  for (Eigen::Index i = 0; i + 1 < n; ++i) off(i) = chain.stiffness_off(i) * inv_sqrt_m(i) * inv_sqrt_m(i + 1);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig;
  eig.computeFromTridiagonal(diag, off, Eigen::EigenvaluesOnly);
  std::string out = fmt::format(
      "\nChain in banded form: M diagonal, K tridiagonal, C = αM + βK with α = {:.6g}, β = {:.6g}\n",
      chain.rayleigh_mass, chain.rayleigh_stiffness);
  out += "Natural frequencies (undamped, rad per unit time) and modal damping ratios ζ = (α/ω + βω)/2";
  const Eigen::Index shown = 8;
  out += n > 2 * shown ? fmt::format(" (the {} lowest and {} highest of {}):\n", shown, shown, n) : ":\n";
  for (Eigen::Index j = 0; j < n; ++j) {
    if (n > 2 * shown && j == shown) out += "  …\n";
    if (n > 2 * shown && j >= shown && j < n - shown) continue;
    const double w = std::sqrt(std::max(0.0, eig.eigenvalues()(j)));
    out += fmt::format("  mode {}: ω = {:.12g}   ζ = {:.6g}\n", j, w,
                       w > 0 ? (chain.rayleigh_mass / w + chain.rayleigh_stiffness * w) / 2 : 0.0);
  }
  const HarmonicForcing& f = scene.forcing();
  Eigen::Index driven = 0;
  for (Eigen::Index i = 0; i < n; ++i)
    if (f.constant(i) != 0.0 || f.cosine(i) != 0.0 || f.sine(i) != 0.0) ++driven;
  out += fmt::format("Forcing: Ω = {:.12g}, on {} of the {} masses\n", f.frequency, driven, n);
  return out + stops_text(scene);
}

}  // namespace

std::string run_text(const io::Scene& scene) {
  const io::RunKindInfo& kind = io::run_kind(scene.run.kind);
  std::string out = fmt::format("Run: {}: {}\n", kind.name, kind.summary);
  out += "Run kinds (run.kind):\n";
  for (const io::RunKindInfo& k : io::run_kinds())
    out += fmt::format("  {:<9} {}{}\n", k.name, k.summary, k.section ? fmt::format(" (run.{})", k.section) : "");
  return out;
}

std::string describe_scene(const io::Scene& scene) {
  std::string out = fmt::format("Scene {}{}: {} degrees of freedom, {} stops\n", scene.file,
                                scene.name.empty() ? "" : " (" + scene.name + ")", scene.dof(), scene.stops.size());
  out += fmt::format("Engine: {} ({})\n", to_string(scene.engine), scene.engine_reason);
  out += run_text(scene);
  if (scene.engine == io::EngineKind::modal) return out + describe_modal(scene);
  const LinearSystem& sys = scene.system();
  const Eigen::Index n = sys.dof();

  // Undamped modes K φ = ω² M φ, mass-normalised; modal damping φᵀCφ = 2 ζ ω where C is
  // proportional (ΦᵀCΦ diagonal), else the damping ratios of the complex eigenvalues.
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(sys.stiffness(), sys.mass());
  const Eigen::MatrixXd phi = eig.eigenvectors();
  const Eigen::MatrixXd modal_c = phi.transpose() * sys.damping() * phi;
  const double off = (modal_c - Eigen::MatrixXd(modal_c.diagonal().asDiagonal())).cwiseAbs().maxCoeff();
  const bool proportional = off <= 1e-12 * std::max(1.0, modal_c.cwiseAbs().maxCoeff());
  out += "\nNatural frequencies (undamped, rad per unit time) and modal damping ratios:\n";
  for (Eigen::Index j = 0; j < n; ++j) {
    const double w = std::sqrt(std::max(0.0, eig.eigenvalues()(j)));
    const std::string zeta = w > 0 && proportional ? fmt::format("{:.6g}", modal_c(j, j) / (2 * w))
                                                   : (w > 0 ? "(non-proportional)" : "(rigid-body mode)");
    out += fmt::format("  mode {}: ω = {:.12g}   ζ = {}\n", j, w, zeta);
  }
  out += "Mode shapes (columns, mass-normalised):\n" + matrix_text(phi, "  ");
  out += fmt::format("Forcing: Ω = {:.12g}, constant {}, cosine {}, sine {}\n", sys.forcing().frequency,
                     vector_text(sys.forcing().constant), vector_text(sys.forcing().cosine),
                     vector_text(sys.forcing().sine));
  for (const ForcingHarmonic& h : sys.forcing().harmonics)
    out += fmt::format("  harmonic {} (at {:.12g}): cosine {}, sine {}\n", h.order, h.rate(sys.forcing().frequency),
                       vector_text(h.cosine), vector_text(h.sine));

  out += stops_text(scene);

  const ImpactSystem impact = scene.impact_system();
  ContactModes modes(impact);
  const std::size_t m = scene.stops.size();
  std::vector<ContactSet> sets;
  if (m <= 6) {
    for (unsigned mask = 1; mask < (1u << m); ++mask) {
      ContactSet s;
      for (unsigned j = 0; j < m; ++j)
        if (mask & (1u << j)) s.push_back(static_cast<int>(j));
      sets.push_back(s);
    }
  } else {
    for (std::size_t j = 0; j < m; ++j) sets.push_back({static_cast<int>(j)});
    out += fmt::format("\n({} stops: only single-stop contact sets are listed; others are built on first use)\n", m);
  }
  for (const ContactSet& set : sets) {
    out += fmt::format("\nContact set {}:\n", set_text(set));
    try {
      const ContactMode& mode = modes.get(set);
      out += "  restitution matrix R (v+ = R v-, all stops taking an impulse):\n" +
             matrix_text(mode.restitution_matrix(), "    ");
      if (proportional)
        out += "  in undamped modal coordinates Φ⁻¹ R Φ:\n" +
               matrix_text(phi.inverse() * mode.restitution_matrix() * phi, "    ");
      const auto& red = mode.reduced();
      std::string coords;
      for (auto i : red.free) coords += fmt::format("{}x{}", coords.empty() ? "" : ", ", i);
      out += fmt::format("  sticking subsystem in y = ({}), {} DOF:\n", coords.empty() ? "none" : coords, red.free.size());
      out += "    M_r =\n" + matrix_text(red.mass, "      ") + "    C_r =\n" + matrix_text(red.damping, "      ") +
             "    K_r =\n" + matrix_text(red.stiffness, "      ");
      out += fmt::format("    f_r(t) = {} + {} cos Ωt + {} sin Ωt\n", vector_text(red.forcing.constant),
                         vector_text(red.forcing.cosine), vector_text(red.forcing.sine));
      out += "  contact forces λ = F · [x; v; cos Ωt; sin Ωt; 1] (λ > 0 holds):\n" +
             matrix_text(red.force_rows, "    ");
    } catch (const std::runtime_error& e) {
      out += fmt::format("  degenerate: {}\n", e.what());
    }
  }
  return out;
}

}  // namespace vibro::cli
