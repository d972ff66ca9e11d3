#include "vibro/observers.hpp"

#include "vibro/section.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <numbers>
#include <stdexcept>

namespace vibro {

const char* to_string(EventKind kind) {
  switch (kind) {
    case EventKind::impact: return "impact";
    case EventKind::stick: return "stick";
    case EventKind::release: return "release";
    case EventKind::chatter_limit: return "chatter-limit";
    case EventKind::engage: return "engage";
    case EventKind::disengage: return "disengage";
    case EventKind::friction_stick: return "friction-stick";
    case EventKind::friction_slip: return "friction-slip";
    case EventKind::friction_reversal: return "friction-reversal";
  }
  return "?";
}

void DenseSegmentView::state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const {
  const Eigen::Index n = x.size();
  Eigen::VectorXd local;
  Eigen::VectorXd& buffer = scratch_ ? *scratch_ : local;
  if (t == t_end() || t == t_begin()) {
    // At the ends, the engine's own arithmetic (the reduced state, then T), bit for bit as
    // before the table below: the engine carries on from the end state (simulator.cpp), and the
    // analysis layer joins the view's states on either side of an event (linearisation.cpp
    // reads both ends of every segment), where a difference of rounding biases, e.g., a
    // conservative system's Lyapunov sum (test_lyapunov.cpp). Without storing anything in the
    // segment's cache of exponentials, which the engine's search reads (Segment::state_unstored).
    const auto& red = mode_->reduced();
    const Eigen::Index full = red.to_full.rows(), size = red.flow->size();
    if (buffer.size() < full + size) buffer.resize(full + size);
    auto zr = buffer.head(size);
    auto z = buffer.segment(size, full);
    if (t == t_begin())
      zr = segment_->initial_state();  // the state the engine started the segment from
    else
      segment_->state_unstored(t - t_begin(), zr);
    mode_->expand(zr, z);
    x = z.head(n);
    v = z.segment(n, n);
    return;
  }
  // Elsewhere x and v straight from the segment's flow through the mode's rows [x; v] (T and
  // the basis folded into one table per segment, Segment::evaluate): a few times cheaper, the
  // same exact form rounded in another order.
  Eigen::Map<Eigen::MatrixXd> xs(x.data(), n, 1), vs(v.data(), n, 1);
  segment_->evaluate(mode_->state_rows(), &t, 1, t_begin(), xs, vs);
}

void SegmentView::states(const double* t, Eigen::Index count, Eigen::Ref<Eigen::MatrixXd> x,
                         Eigen::Ref<Eigen::MatrixXd> v) const {
  for (Eigen::Index k = 0; k < count; ++k) state(t[k], x.col(k), v.col(k));
}

void DenseSegmentView::states(const double* t, Eigen::Index count, Eigen::Ref<Eigen::MatrixXd> x,
                              Eigen::Ref<Eigen::MatrixXd> v) const {
  const auto at_end = [this](double ts) { return ts == t_begin() || ts == t_end(); };
  for (Eigen::Index k = 0; k < count;) {
    if (at_end(t[k])) {  // the engine's arithmetic, as state() (above)
      state(t[k], x.col(k), v.col(k));
      ++k;
      continue;
    }
    Eigen::Index run = 1;
    while (k + run < count && !at_end(t[k + run])) ++run;
    segment_->evaluate(mode_->state_rows(), t + k, run, t_begin(), x.middleCols(k, run), v.middleCols(k, run));
    k += run;
  }
}

double DenseSegmentView::force(Eigen::Index a, double t) const {
  const auto& red = mode_->reduced();
  return -segment_->value(red.gap_rows + a, t - t_begin());
}

Minimum DenseSegmentView::force_minimum(Eigen::Index a) const {
  // The watch row is -λ: minimise λ = -row.
  const Eigen::Index row = mode_->reduced().gap_rows + a;
  const Minimum m = minimize_row(*segment_, row, 0.0, t_end() - t_begin(), force_tolerance_, -1.0);
  return {m.value, t_begin() + m.tau};
}

std::vector<Minimum> DenseSegmentView::force_local_minima(Eigen::Index a) const {
  const auto& red = mode_->reduced();
  const Eigen::Index row = red.gap_rows + a;
  // Guards λ' and -λ' (the watch row is -λ): an interior minimum is λ' crossing 0 upwards, a
  // maximum -λ' crossing upwards. The search alternates between them, one guard armed at a time
  // (the other's trigger is +∞), so it steps from extremum to extremum without stalling.
  Eigen::MatrixXd rows(2, red.watch->rows(1).cols());
  rows.row(0) = -red.watch->rows(1).row(row);
  rows.row(1) = red.watch->rows(1).row(row);
  const Functionals slope(*red.flow, rows);
  const Segment seg(slope, segment_->t0(), segment_->initial_state());
  const double span = t_end() - t_begin();
  const double inf = std::numeric_limits<double>::infinity();
  const double eps = std::max(1e-13 * std::abs(seg.value(0, 0.0)), force_tolerance_ * 1e-3 * red.flow->spectral_radius());
  const double resolution = 8.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(t_end()));
  const double step = 1.0 / std::max(red.flow->spectral_radius(), 1e-300);
  std::vector<Minimum> out;
  bool seek_min = seg.value(0, 0.0) <= 0.0;
  double from = 0.0;
  for (int guard = 0; from < span && guard < 10000; ++guard) {
    Eigen::VectorXd trigger(2);
    trigger << (seek_min ? eps : inf), (seek_min ? inf : eps);
    CrossingFinder finder(seg, trigger, resolution);
    std::optional<Crossing> hit;
    for (double s = from; s < span && !hit;) {
      const double e = std::min(s + step, span);
      hit = finder.first(s, e);
      s = e;
    }
    if (!hit || hit->tau >= span) break;
    if (seek_min && hit->tau > 0.0) out.push_back({force(a, t_begin() + hit->tau), t_begin() + hit->tau});
    from = std::max(hit->tau, from) + resolution;
    seek_min = !seek_min;
  }
  return out;
}

void DenseSegmentView::plane_crossings(const Hyperplane& plane, double trigger, int& side,
                                       std::vector<PlaneCrossing>& out) const {
  // h = nᵀx − c as a row of the full augmented state [x; v; cos; sin; 1; …] (the 1 at 2n + 2),
  // carried to the reduced state by T, and −h beside it.
  const auto& red = mode_->reduced();
  const Eigen::Index n = dof();
  Eigen::RowVectorXd full = Eigen::RowVectorXd::Zero(red.to_full.rows());
  full.head(n) = plane.normal.transpose();
  full(2 * n + 2) = -plane.value;
  Eigen::MatrixXd rows(2, red.to_full.cols());
  rows.row(0) = full * red.to_full;
  rows.row(1) = -rows.row(0);
  const Functionals guards(*red.flow, std::move(rows));
  const Segment seg(guards, segment_->t0(), segment_->initial_state());
  const double step = 1.0 / std::max(red.flow->spectral_radius(), 1e-300);
  locate_plane_crossings(seg, t_begin(), t_end() - t_begin(), step, trigger, side, out);
}

// --- ContactLog ------------------------------------------------------------------------------

void ContactLog::begin(const RunContext& run, double) {
  open_.assign(run.stops, -1);
  has_interior_.assign(run.stops, false);
  last_end_force_.assign(run.stops, 0.0);
}

void ContactLog::event(const Event& e) {
  auto& slot = open_[static_cast<std::size_t>(e.stop)];
  if (e.kind == EventKind::stick || e.kind == EventKind::chatter_limit) {
    if (slot >= 0) return;
    slot = static_cast<long>(intervals.size());
    intervals.push_back({e.stop, e.t, e.t, e.force, e.t, false});
    has_interior_[static_cast<std::size_t>(e.stop)] = false;
  } else if (e.kind == EventKind::release && slot >= 0) {
    const auto index = static_cast<std::size_t>(slot);
    slot = -1;
    if (e.t <= intervals[index].t_start) {
      // Released before the chatter's accumulation point: the bounces never converged, the
      // stop never stuck (the simulator held it only within the chatter rule's O(u²/a)).
      intervals.erase(intervals.begin() + static_cast<std::ptrdiff_t>(index));
      for (long& other : open_)
        if (other > static_cast<long>(index)) --other;
      return;
    }
    intervals[index].t_end = e.t;
    intervals[index].closed = true;
  }
}

void ContactLog::segment(const SegmentView& view) {
  const ContactSet& active = view.active();
  for (std::size_t a = 0; a < active.size(); ++a) {
    const auto j = static_cast<std::size_t>(active[a]);
    const long slot = open_[j];
    if (slot < 0) continue;
    auto& iv = intervals[static_cast<std::size_t>(slot)];
    const auto idx = static_cast<Eigen::Index>(a);
    // Interior minima take precedence; until one is seen, the least value at segment starts.
    for (const Minimum& m : view.force_local_minima(idx)) {
      if (m.tau < iv.t_start) continue;  // before the chatter limit: not yet sticking
      if (!has_interior_[j] || m.value < iv.force_min) {
        iv.force_min = m.value;
        iv.t_force_min = m.tau;
      }
      has_interior_[j] = true;
    }
    if (!has_interior_[j]) {
      // The interval starts at the chatter limit, which can lie inside (or after) this segment
      // when the chatter rule caught the stop early: take its first value inside the interval.
      const double t_first = std::clamp(iv.t_start, view.t_begin(), view.t_end());
      const double first = view.force(idx, t_first);
      if (t_first <= iv.t_start || first < iv.force_min) {
        iv.force_min = first;
        iv.t_force_min = t_first;
      }
    }
    iv.t_end = view.t_end();
    last_end_force_[j] = view.force(idx, view.t_end());
  }
}

void ContactLog::end(double t_end) {
  for (std::size_t j = 0; j < open_.size(); ++j) {
    if (open_[j] < 0) continue;
    auto& iv = intervals[static_cast<std::size_t>(open_[j])];
    iv.t_end = t_end;
    // Still held at the end of the run: the end is not a release, so it counts.
    if (!has_interior_[j] && last_end_force_[j] < iv.force_min) {
      iv.force_min = last_end_force_[j];
      iv.t_force_min = t_end;
    }
  }
}

// --- Samples, Poincare ---------------------------------------------------------------------------

namespace {

/// Appends the exact state at ts to (t, x, v) if ts lies in the segment.
void record_state(const SegmentView& view, double ts, std::vector<double>& t,
                  std::vector<Eigen::VectorXd>& x, std::vector<Eigen::VectorXd>& v) {
  if (ts < view.t_begin()) return;
  Eigen::VectorXd xs(view.dof()), vs(view.dof());
  view.state(ts, xs, vs);
  t.push_back(ts);
  x.push_back(std::move(xs));
  v.push_back(std::move(vs));
}

}  // namespace

void Samples::begin(const RunContext& run, double) {
  // Room for the times still to come beside what an earlier run recorded.
  const auto recorded = static_cast<Eigen::Index>(t.size());
  if (recorded > 0 && x.rows() != run.dof)
    throw InvalidInput("samples: a run of " + std::to_string(run.dof) + " DOF after one of " +
                       std::to_string(x.rows()) + " DOF; use one Samples per system");
  const Eigen::Index capacity = recorded + static_cast<Eigen::Index>(times_.size() - next_);
  t.reserve(static_cast<std::size_t>(capacity));
  x.conservativeResize(run.dof, capacity);
  v.conservativeResize(run.dof, capacity);
}

void Samples::segment(const SegmentView& view) {
  // The times up to t_end, those before t_begin skipped; the others (one run when the times are
  // sorted) in one states() call, straight into their columns.
  const auto inside = [&view](double ts) { return ts >= view.t_begin() && ts <= view.t_end(); };
  while (next_ < times_.size() && times_[next_] <= view.t_end()) {
    if (!inside(times_[next_])) {
      ++next_;
      continue;
    }
    const std::size_t first = next_;
    while (next_ < times_.size() && inside(times_[next_])) ++next_;
    const auto k = static_cast<Eigen::Index>(t.size());
    const auto count = static_cast<Eigen::Index>(next_ - first);
    view.states(times_.data() + first, count, x.middleCols(k, count), v.middleCols(k, count));
    t.insert(t.end(), times_.begin() + static_cast<std::ptrdiff_t>(first),
             times_.begin() + static_cast<std::ptrdiff_t>(next_));
  }
}

void Samples::end(double) {
  const auto recorded = static_cast<Eigen::Index>(t.size());
  if (x.cols() == recorded) return;
  x.conservativeResize(Eigen::NoChange, recorded);
  v.conservativeResize(Eigen::NoChange, recorded);
}

void Poincare::begin(const RunContext& run, double t0) {
  const double omega = run.frequency;
  if (!(omega > 0.0)) throw InvalidInput("poincare: needs a forcing frequency > 0");
  period_ = 2.0 * std::numbers::pi / omega;
  next_k_ = static_cast<long>(std::ceil((t0 - phase_time_) / period_ - 1e-12));
}

void Poincare::segment(const SegmentView& view) {
  for (;; ++next_k_) {
    const double ts = phase_time_ + static_cast<double>(next_k_) * period_;
    if (ts > view.t_end()) break;
    record_state(view, ts, t, x, v);
  }
}

// --- ImpactMap ---------------------------------------------------------------------------------

void ImpactMap::begin(const RunContext& run, double /*t0*/) {
  omega_ = run.frequency;
  last_x_.resize(run.dof);
  last_v_.resize(run.dof);
  has_last_ = false;
}

// The segment's end is where its event happens (the frame reports a segment, then its event):
// one state per segment, the only work this observer adds.
void ImpactMap::segment(const SegmentView& view) {
  last_t_ = view.t_end();
  view.state(last_t_, last_x_, last_v_);
  has_last_ = true;
}

void ImpactMap::event(const Event& e) {
  if (e.kind != EventKind::impact || !has_last_ || e.t != last_t_) return;
  t.push_back(e.t);
  double theta = omega_ > 0.0 ? std::fmod(omega_ * e.t, 2.0 * std::numbers::pi) : 0.0;
  if (theta < 0.0) theta += 2.0 * std::numbers::pi;
  phase.push_back(theta);
  velocity.push_back(e.v_before);
  stop.push_back(e.stop);
  x.push_back(last_x_);
  v.push_back(last_v_);
}

// --- PeriodStatistics ----------------------------------------------------------------------------

void PeriodStatistics::begin(const RunContext& run, double t0) {
  const double omega = run.frequency;
  if (!(omega > 0.0)) throw InvalidInput("statistics: per-period statistics need a forcing frequency > 0");
  period_ = 2.0 * std::numbers::pi / omega;
  t0_ = t0;
  stops_ = run.stops;
  sticks_from_.assign(stops_, -std::numeric_limits<double>::infinity());
}

void PeriodStatistics::ensure(long k) {
  while (static_cast<long>(sticking_fraction.size()) <= k) {
    sticking_fraction.push_back(Eigen::VectorXd::Zero(static_cast<Eigen::Index>(stops_)));
    impacts.push_back(Eigen::VectorXi::Zero(static_cast<Eigen::Index>(stops_)));
  }
}

void PeriodStatistics::segment(const SegmentView& view) {
  for (int j : view.active()) {
    // A stop caught by the chatter rule is held from the impact that triggered it, but it sticks
    // only from the bounces' accumulation point on (the chatter-limit event's time), as in
    // ContactLog: count from there.
    double a = std::max(view.t_begin(), sticks_from_[static_cast<std::size_t>(j)]);
    const double b = view.t_end();
    while (a < b) {
      const long k = static_cast<long>(std::floor((a - t0_) / period_));
      const double period_end = t0_ + static_cast<double>(k + 1) * period_;
      const double piece = std::min(b, period_end) - a;
      ensure(k);
      sticking_fraction[static_cast<std::size_t>(k)](j) += piece / period_;
      a = std::min(b, period_end);
      if (piece <= 0.0) break;
    }
  }
}

void PeriodStatistics::event(const Event& e) {
  if (e.kind == EventKind::chatter_limit) sticks_from_[static_cast<std::size_t>(e.stop)] = e.t;
  if (e.kind != EventKind::impact) return;
  const long k = static_cast<long>(std::floor((e.t - t0_) / period_));
  ensure(k);
  impacts[static_cast<std::size_t>(k)](e.stop) += 1;
}

}  // namespace vibro
