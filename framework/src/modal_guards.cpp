// ModalGuardSource (modal.hpp): a chain's guards in modal coordinates as the certified crossing
// search of events.hpp sees them (guard_source.hpp): values, slopes and curvatures from the
// modes' exact flow, bounds on |h''| and |h'''| from each mode's energy.
#include "vibro/modal.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace vibro {

ModalGuardSource::ModalGuardSource(Eigen::Index capacity)
    : u_(capacity), ud_(capacity), udd_(capacity), uddd_(capacity), b2_(capacity), b3_(capacity), b4_(capacity) {}

void ModalGuardSource::retarget(const ChainModes* modes, const ModalGuards& guards, double frequency, double t0,
                                const Eigen::Ref<const Eigen::VectorXd>& u0,
                                const Eigen::Ref<const Eigen::VectorXd>& ud0) {
  modes_ = modes;
  guards_ = &guards;
  W_ = frequency;
  t0_ = t0;
  nr_ = modes ? modes->dof() : 0;
  if (u0.size() != nr_ || ud0.size() != nr_ || (nr_ > 0 && guards.P.cols() != nr_))
    throw std::invalid_argument("ModalGuardSource::retarget: the state's or the guards' size is not the modes' count");
  u0_ = u0.data();
  ud0_ = ud0.data();
  if (u_.size() < nr_)  // a capacity below the modes' count: grow (not in the event loop)
    for (Eigen::VectorXd* v : {&u_, &ud_, &udd_, &uddd_, &b2_, &b3_, &b4_}) v->resize(nr_);
  // Each bound is a sum of n_r + 2 nonnegative terms, each a product of a few rounded factors.
  inflate_ = 1.0 + 1e-12 + 2.0 * static_cast<double>(nr_ + 8) * std::numeric_limits<double>::epsilon();
}

void ModalGuardSource::flow(double tau, int order) const {
  ++evaluations_;
  if (!modes_) return;
  auto u = u_.head(nr_), ud = ud_.head(nr_), udd = udd_.head(nr_);
  modes_->advance(tau, Eigen::Map<const Eigen::VectorXd>(u0_, nr_), Eigen::Map<const Eigen::VectorXd>(ud0_, nr_), u,
                  ud);
  const Eigen::VectorXd& sg = modes_->decay();
  const Eigen::VectorXd& w2 = modes_->omega_squared();
  if (order >= 2) udd = -(2.0 * sg.cwiseProduct(ud) + w2.cwiseProduct(u));
  if (order >= 3) uddd_.head(nr_) = -(2.0 * sg.cwiseProduct(udd) + w2.cwiseProduct(ud));
}

void ModalGuardSource::mode_bounds(bool fourth) const {
  // a = √(u'² + ω²u²); β₂a, β₃a, β₄a as in modal.hpp (ModalGuardSource).
  const auto two_s = 2.0 * modes_->decay().array();
  const auto w = modes_->omega().array();
  const auto w2 = modes_->omega_squared().array();
  const auto u = u_.head(nr_).array(), ud = ud_.head(nr_).array();
  auto b2 = b2_.head(nr_).array(), b3 = b3_.head(nr_).array();
  // b4 holds a until b2 and b3 are formed.
  auto a = b4_.head(nr_).array();
  a = (ud * ud + w2 * (u * u)).sqrt();
  b2 = (two_s + w) * a;
  b3 = two_s * b2 + w2 * a;
  if (fourth) b4_.head(nr_).array() = two_s * b3 + w2 * b2;
}

void ModalGuardSource::sample(double tau, SegmentSample& out) const {
  const ModalGuards& g = *guards_;
  const Eigen::Index rows = g.rows(), nd = g.D.rows();
  const bool rates = nd > 0;
  out.tau = tau;
  out.h.resize(rows);
  out.d.resize(rows);
  out.c.resize(rows);
  out.growth.resize(2 * rows);
  auto B2 = out.growth.head(rows), B3 = out.growth.tail(rows);
  flow(tau, rates ? 3 : 2);
  if (modes_) {
    mode_bounds(rates);
    const auto u = u_.head(nr_), ud = ud_.head(nr_), udd = udd_.head(nr_);
    out.h.noalias() = g.P * u;
    out.d.noalias() = g.P * ud;
    out.c.noalias() = g.P * udd;
    B2.noalias() = g.abs_P * b2_.head(nr_);
    B3.noalias() = g.abs_P * b3_.head(nr_);
    if (rates) {
      out.h.tail(nd).noalias() += g.D * ud;
      out.d.tail(nd).noalias() += g.D * udd;
      out.c.tail(nd).noalias() += g.D * uddd_.head(nr_);
      B2.tail(nd).noalias() += g.abs_D * b3_.head(nr_);
      B3.tail(nd).noalias() += g.abs_D * b4_.head(nr_);
    }
  } else {
    out.h.setZero();
    out.d.setZero();
    out.c.setZero();
    out.growth.setZero();
  }
  const double t = t0_ + tau, c = std::cos(W_ * t), s = std::sin(W_ * t);
  out.h += g.h0 + g.hc * c + g.hs * s;
  out.d += W_ * (g.hs * c - g.hc * s);
  out.c -= (W_ * W_) * (g.hc * c + g.hs * s);
  B2 = (B2 + g.curvature) * inflate_;
  B3 = (B3 + W_ * g.curvature) * inflate_;
}

void ModalGuardSource::row_jet(Eigen::Index i, double tau, double* h, double* d, double* c) const {
  const ModalGuards& g = *guards_;
  const Eigen::Index first_d = g.rows() - g.D.rows();
  const bool rates = i >= first_d;
  flow(tau, rates ? 3 : 2);
  double value = 0.0, slope = 0.0, curvature = 0.0;
  if (modes_) {
    const auto P = g.P.row(i);
    value = P.dot(u_.head(nr_));
    slope = P.dot(ud_.head(nr_));
    curvature = P.dot(udd_.head(nr_));
    if (rates) {
      const auto D = g.D.row(i - first_d);
      value += D.dot(ud_.head(nr_));
      slope += D.dot(udd_.head(nr_));
      curvature += D.dot(uddd_.head(nr_));
    }
  }
  const double t = t0_ + tau, cs = std::cos(W_ * t), sn = std::sin(W_ * t);
  *h = value + (g.h0(i) + g.hc(i) * cs + g.hs(i) * sn);
  *d = slope + W_ * (g.hs(i) * cs - g.hc(i) * sn);
  *c = curvature - (W_ * W_) * (g.hc(i) * cs + g.hs(i) * sn);
}

double ModalGuardSource::value(Eigen::Index i, double tau, int derivative) const {
  if (derivative < 0 || derivative > 2)
    throw std::invalid_argument("ModalGuardSource::value: derivative " + std::to_string(derivative) +
                                " is not 0, 1 or 2");
  double h, d, c;
  row_jet(i, tau, &h, &d, &c);
  return derivative == 0 ? h : (derivative == 1 ? d : c);
}

double ModalGuardSource::second_derivative_bound(Eigen::Index i, double a, double /*b*/) const {
  // The bound from the state at a holds on [a, ∞) (modal.hpp).
  const ModalGuards& g = *guards_;
  const Eigen::Index first_d = g.rows() - g.D.rows();
  double bound = g.curvature(i);
  flow(a, 1);
  if (modes_) {
    mode_bounds(false);
    bound += g.abs_P.row(i).dot(b2_.head(nr_));
    if (i >= first_d) bound += g.abs_D.row(i - first_d).dot(b3_.head(nr_));
  }
  return bound * inflate_;
}

double ModalGuardSource::derivative_bound(int derivative, Eigen::Index i, const SegmentSample& a,
                                          const SegmentSample& /*b*/) const {
  // The sample at the left end holds B₂ then B₃ per row, valid on [a.tau, ∞).
  if (derivative != 2 && derivative != 3)
    throw std::invalid_argument("ModalGuardSource::derivative_bound: derivative " + std::to_string(derivative) +
                                " is not 2 or 3");
  return a.growth(derivative == 2 ? i : a.h.size() + i);
}

void ModalGuardSource::state(double tau, Eigen::Ref<Eigen::VectorXd> u, Eigen::Ref<Eigen::VectorXd> ud) const {
  ++evaluations_;
  if (!modes_) return;
  modes_->advance(tau, Eigen::Map<const Eigen::VectorXd>(u0_, nr_), Eigen::Map<const Eigen::VectorXd>(ud0_, nr_), u,
                  ud);
}

}  // namespace vibro
