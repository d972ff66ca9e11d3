#pragma once
// Private to vibro_core: the certified crossing search of events.hpp on the modal chain
// engine's guards (ModalGuards: values, slopes and |h''| bounds of every row from the modal
// state, O(n_r) per row and time). Its certification is the chord and end-slope bounds of
// events.hpp with B₂ from the modal amplitudes; it halves where they fail and refines roots by
// safeguarded Newton.
#include "modal_internal.hpp"

#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

namespace vibro {
namespace detail {

/// Upper bound of h over [a, b] from the end values and slopes and B ≥ |h''| (events.hpp).
inline double upper_bound(double ha, double da, double hb, double db, double B, double L) {
  const double chord = std::max(ha, hb) + B * L * L / 8.0;
  const double from_a = std::max(ha, ha + da * L + 0.5 * B * L * L);
  const double from_b = std::max(hb, hb - db * L + 0.5 * B * L * L);
  return std::min({chord, from_a, from_b});
}

}  // namespace detail

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
      if (advance_to(b, tau, row)) return true;
      a = b;
    }
    return false;
  }

  /// One step of that walk: the crossing in [a, b], a the previous step's b (or `from`).
  bool advance_to(double b, double* tau, int* row) {
    if (g_->rows() == 0) return false;
    evaluate(b, stack_[1]);
    if (search(0, 1, 2, tau, row)) return true;
    std::swap(stack_[0], stack_[1]);
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
    return detail::upper_bound(a.h(i), a.d(i), b.h(i), b.d(i), a.bound(i), b.tau - a.tau) <= trig_(i);
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
      if (detail::upper_bound(A.h(above), A.d(above), R.h(above), R.d(above), A.bound(above), r - A.tau) <=
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

}  // namespace vibro
