// The modal chain engine's segments as observers see them (observers.hpp): ModalSegmentView
// and ModalSegmentState, with the certified search (events.hpp) of their guards' extrema.
#include "modal_internal.hpp"

#include "vibro/events.hpp"
#include "vibro/section.hpp"

#include <limits>
#include <optional>
#include <vector>

namespace vibro {
using detail::Buffers;
using detail::Harmonic;
using detail::guard_at;
using detail::to_physical;

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
    if (m.harmonic_rates().size() > 0) m.add_particular(t, 1.0, q, qd);
    phi = m.phi_rows(coordinates);
  }
  Eigen::Index next = 0;
  for (Eigen::Index i = 0; i < k; ++i) {
    const Eigen::Index l = masses[static_cast<std::size_t>(i)];
    x(i) = md.o0(l) + md.oc(l) * c + md.os(l) * s;
    v(i) = W * (md.os(l) * c - md.oc(l) * s);
    for (Eigen::Index h = 0; h < md.oxc.cols(); ++h) {  // held stops' higher harmonics
      const double r = md.guards.rates(h), ch = std::cos(r * t), sh = std::sin(r * t);
      x(i) += md.oxc(l, h) * ch + md.oxs(l, h) * sh;
      v(i) += r * (md.oxs(l, h) * ch - md.oxc(l, h) * sh);
    }
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
/// at a time (the other's trigger is +∞), as DenseSegmentView::force_local_minima. With `minima`,
/// the interior local minima instead (ModalSegmentState::guard_local_minima).
std::vector<Minimum> guard_maxima(const ModalChainSimulator& sim, const ModalContactMode& mode, double t0,
                                  const Eigen::Ref<const Eigen::VectorXd>& u0,
                                  const Eigen::Ref<const Eigen::VectorXd>& ud0, Eigen::Index row, double from,
                                  double to, double tolerance, bool minima = false) {
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
  slope.rates = g.rates;
  slope.xc.resize(2, g.harmonics());
  slope.xs.resize(2, g.harmonics());
  for (Eigen::Index h = 0; h < g.harmonics(); ++h) {  // d/dt of xc cos rt + xs sin rt
    const double r = g.rates(h), c = r * g.xs(row, h), s = -r * g.xc(row, h);
    slope.xc.col(h) = Eigen::Vector2d(-c, c);
    slope.xs.col(h) = Eigen::Vector2d(-s, s);
  }
  slope.finish(W);

  ModalGuardSource source(nr);
  source.retarget(mode.modes, slope, W, t0, u0, ud0);
  const double start = from - t0, span = to - t0;
  const double resolution = 8.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(to));
  const double h_start = source.value(0, start);
  const double top = std::max(W, mode.modes ? mode.modes->omega().maxCoeff() : 0.0);
  // As DenseSegmentView: the trigger scaled to a slope (× 1e-3 × the fastest rate).
  const double eps = std::max(1e-13 * std::abs(h_start), tolerance * 1e-3 * std::max(top, 1e-300));
  const double step = top > 0.0 ? 1.0 / top : std::max(span, 1e-300);
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<Minimum> out;
  bool seek_max = h_start <= 0.0;
  double at = start;
  Buffers buffers(nr);
  CrossingFinder finder;
  for (int guard = 0; at < span && guard < 10000; ++guard) {
    Eigen::VectorXd trigger(2);
    trigger << (seek_max ? eps : inf), (seek_max ? inf : eps);
    finder.retarget(source, trigger, resolution, true);
    std::optional<Crossing> hit;
    for (double a = at; a < span && !hit;) {
      const double b = std::min(a + step, span);
      hit = finder.first(a, b);
      a = b;
    }
    if (!hit || hit->tau >= span) break;
    const double tau = hit->tau;
    if (seek_max != minima && tau > start) {
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

std::vector<Minimum> ModalSegmentState::guard_local_minima(Eigen::Index row, double from, double to,
                                                           double tolerance) const {
  return guard_maxima(*sim_, *mode_, t_begin_, u_, ud_, row, from, to, tolerance, true);
}

double ModalSegmentState::guard(Eigen::Index row, double t) const {
  double value, rate;
  Buffers buffers(mode_->size());
  guard_at(*mode_, sim_->modes().frequency(), t_begin_, u_, ud_, t - t_begin_, row, &value, &rate, buffers);
  return value;
}

void ModalSegmentView::plane_crossings(const Hyperplane& plane, double trigger, int& side,
                                       std::vector<PlaneCrossing>& out) const {
  const ModalContactMode& md = *mode_;
  const Eigen::Index nr = md.size(), n = static_cast<Eigen::Index>(md.coordinate.size());
  const double W = sim_->modes().frequency();
  // x_l = o_l(t) + φ_{r(l)}·(u + p(t)) for a free mass (r ≥ 0), o_l(t) for a held one.
  Harmonic offset{-plane.value, 0.0, 0.0};
  std::vector<Eigen::Index> coordinates;
  std::vector<double> weights;
  const bool moving = md.o0.size() == n;
  for (Eigen::Index l = 0; l < n; ++l) {
    const double w = plane.normal(l);
    if (w == 0.0) continue;
    if (moving) offset += w * Harmonic{md.o0(l), md.oc(l), md.os(l)};
    const Eigen::Index r = md.coordinate[static_cast<std::size_t>(l)];
    if (r >= 0) {
      coordinates.push_back(r);
      weights.push_back(w);
    }
  }
  ModalGuards g;
  g.P = Eigen::MatrixXd::Zero(2, nr);
  g.D.resize(0, nr);
  g.rates = md.guards.rates;
  const Eigen::Index H = g.harmonics();
  g.xc = Eigen::MatrixXd::Zero(2, H);
  g.xs = Eigen::MatrixXd::Zero(2, H);
  if (md.oxc.size() > 0)  // the offsets' higher harmonics (held stops moving with them)
    for (Eigen::Index l = 0; l < n; ++l)
      if (plane.normal(l) != 0.0) {
        g.xc.row(0) += plane.normal(l) * md.oxc.row(l);
        g.xs.row(0) += plane.normal(l) * md.oxs.row(l);
      }
  if (nr > 0 && !coordinates.empty()) {
    const ChainModes& m = *md.modes;
    const Eigen::MatrixXd phi = m.phi_rows(coordinates);
    for (Eigen::Index k = 0; k < phi.rows(); ++k) g.P.row(0) += weights[static_cast<std::size_t>(k)] * phi.row(k);
    offset += Harmonic{g.P.row(0).dot(m.particular_constant()), g.P.row(0).dot(m.particular_cosine()),
                       g.P.row(0).dot(m.particular_sine())};
    if (H > 0) {  // the extra harmonics of φ·p(t)
      g.xc.row(0) += g.P.row(0) * m.particular_harmonic_cosine();
      g.xs.row(0) += g.P.row(0) * m.particular_harmonic_sine();
    }
  }
  if (H > 0) {  // (a row of a 2×0 matrix would offset a null pointer)
    g.xc.row(1) = -g.xc.row(0);
    g.xs.row(1) = -g.xs.row(0);
  }
  g.P.row(1) = -g.P.row(0);
  g.h0 = Eigen::Vector2d(offset.c0, -offset.c0);
  g.hc = Eigen::Vector2d(offset.cc, -offset.cc);
  g.hs = Eigen::Vector2d(offset.cs, -offset.cs);
  g.finish(W);
  ModalGuardSource source(nr);
  source.retarget(md.modes, g, W, t_begin(), sim_->segment_u(), sim_->segment_ud());
  const double top = std::max(W, md.modes ? md.modes->omega().maxCoeff() : 0.0);
  const double span = t_end() - t_begin();
  locate_plane_crossings(source, t_begin(), span, top > 0.0 ? 1.0 / top : span, trigger, side, out);
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

