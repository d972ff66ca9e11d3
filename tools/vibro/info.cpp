#include "info.hpp"

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

}  // namespace

std::string describe_scene(const io::Scene& scene) {
  const LinearSystem& sys = scene.system;
  const Eigen::Index n = sys.dof();
  std::string out = fmt::format("Scene {}{}: {} degrees of freedom, {} stops\n", scene.file,
                                scene.name.empty() ? "" : " (" + scene.name + ")", n, scene.stops.size());

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

  out += "\nStops (g = w·x - s(t) ≤ 0):\n";
  for (std::size_t j = 0; j < scene.stops.size(); ++j) {
    const Stop& s = scene.stops[j];
    const char* kind = s.kind == Stop::Kind::upper ? "upper" : s.kind == Stop::Kind::lower ? "lower" : "between";
    out += fmt::format("  [{}] {:<20} {:<7} mass {}{}  at {:.6g}  r = {:.6g}{}\n", j, s.name, kind, s.mass,
                       s.kind == Stop::Kind::between ? fmt::format(" - mass {}", s.other) : "", s.position,
                       s.restitution,
                       s.amplitude > 0 ? fmt::format("  moving ±{:.6g} phase {:.6g}", s.amplitude, s.phase) : "");
  }

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
