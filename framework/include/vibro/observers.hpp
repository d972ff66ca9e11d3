#pragma once
/// \file observers.hpp
/// What a run records. The simulator calls only the observers a run was given; with none it does
/// no recording work at all (no samples evaluated, no minima searched, nothing stored).
///
/// An observer sees two things:
///  * segments: the exact motion in one contact mode over [t_begin, t_end] (a SegmentView). Any
///    state inside it is computed from the exact flow, never interpolated;
///  * events: impacts, sticks, releases and chatter limits (time, stop, normal rates before and
///    after, contact force); the state around an event is the end of one segment and the start
///    of the next.
///
/// Provided here: EventLog, ContactLog (contact intervals with the minimum contact force and its
/// time, the quantity that detects rising), Samples (exact states at requested times), Poincare
/// (stroboscopic points at the forcing period), ImpactMap (the state before each impact), PeriodStatistics (sticking proportion of each
/// stop and impacts per forcing period). Section (crossings of a hyperplane in the positions) is
/// in section.hpp.
#include "vibro/contact.hpp"
#include "vibro/events.hpp"

#include <string>
#include <vector>

namespace vibro {

/// engage / disengage: a compliant stop's gap turning positive / returning to zero (stops.hpp);
/// the state is continuous there, v_before = v_after = g'_j, force = its push N after the switch.
/// friction_stick / friction_slip / friction_reversal: a frictional contact (friction.hpp; `stop` is
/// then the contact's index) sticks, starts to slip, or reverses its slip; v_before = v_after = its
/// relative velocity u (0 to the trigger), force = its friction force F after the event.
enum class EventKind { impact, stick, release, chatter_limit, engage, disengage, friction_stick, friction_slip, friction_reversal };
const char* to_string(EventKind kind);

struct Event {
  double t = 0.0;
  int stop = -1;
  EventKind kind = EventKind::impact;
  double v_before = 0.0;  ///< g'_j before (approach speed > 0 means towards the stop)
  double v_after = 0.0;   ///< g'_j after
  double force = 0.0;     ///< contact force λ_j after the event (0 when free)
};

/// What an observer is told when a run begins: enough to size its tables and find the forcing
/// period, without the model itself (so an engine that never forms dense matrices, such as the
/// modal chain engine of modal.hpp, can serve the same observers).
struct RunContext {
  Eigen::Index dof = 0;      ///< degrees of freedom n
  std::size_t stops = 0;     ///< number of stops
  double frequency = 0.0;    ///< forcing frequency Ω (0: unforced)
  /// ε_g = trigger·L, the trigger level of the stops' gaps (absolute length; 0 when the engine
  /// does not say): the level a passive guard on the positions uses too (section.hpp).
  double gap_trigger = 0.0;
};

/// A hyperplane in the positions, h(x) = nᵀx − c, watched without acting on the motion (a
/// passive guard; section.hpp).
struct Hyperplane {
  Eigen::VectorXd normal;  ///< n (one entry per coordinate, not all zero)
  double value = 0.0;      ///< c
  double at(const Eigen::Ref<const Eigen::VectorXd>& x) const { return normal.dot(x) - value; }
};

/// A crossing of a hyperplane: the time of the root of h = 0 and the direction, +1 upwards
/// (h passing from ≤ 0 to > ε) or −1 downwards (from ≥ 0 to < −ε).
struct PlaneCrossing {
  double t = 0.0;
  int direction = 1;
};

/// Exact motion in one contact mode over [t_begin, t_end], as an engine exposes it to observers.
/// Each engine implements it from its own exact flow: DenseSegmentView (the general engine,
/// simulator.hpp) and the modal engine's view (modal.hpp). States and forces inside a segment
/// are computed, never interpolated.
class SegmentView {
 public:
  virtual ~SegmentView() = default;
  double t_begin() const { return t_begin_; }
  double t_end() const { return t_end_; }
  virtual Eigen::Index dof() const = 0;
  /// The stops held throughout the segment (sorted); force(a, t) refers to active()[a].
  virtual const ContactSet& active() const = 0;
  /// Full state at t ∈ [t_begin, t_end] from the exact flow.
  virtual void state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const = 0;
  /// States at t[0], …, t[count - 1] ∈ [t_begin, t_end] at once: column k of x and v (n × count
  /// or wider) is state(t[k]), bit for bit. Observers that record many states per segment
  /// (Samples) call this: an engine can settle once what each state() call settles again. The
  /// default calls state() per time.
  virtual void states(const double* t, Eigen::Index count, Eigen::Ref<Eigen::MatrixXd> x,
                      Eigen::Ref<Eigen::MatrixXd> v) const;
  /// Contact force λ of the a-th stop of active() at t.
  virtual double force(Eigen::Index a, double t) const = 0;
  /// Certified minimum of that force over the segment (value, time).
  virtual Minimum force_minimum(Eigen::Index a) const = 0;
  /// Interior local minima of that force (λ' = 0 with λ' rising through zero), in time order:
  /// found as the crossings of the guard λ' with the same certified search as events
  /// (events.hpp), so none is missed. These are what detects rising: the orbit becomes tangent to
  /// the boundary ∂S (λ = 0) where the least interior minimum touches zero.
  virtual std::vector<Minimum> force_local_minima(Eigen::Index a) const = 0;
  /// The crossings of the hyperplane h(t) = nᵀx(t) − c over [t_begin, t_end], appended to `out`
  /// in time order, found by the certified search of the events (events.hpp) on the rows h and
  /// −h written in the segment's own exact flow (a guard source apart from the engine's, so
  /// the motion and the engine's search are untouched). Crossings alternate: `side` is where
  /// the motion was last certified (−1: h ≤ ε since the last crossing, so the next one is
  /// upwards; +1: above, downwards) and is updated. An upward crossing is h rising above
  /// `trigger` (ε > 0), located at the root of h = 0 before it to a few ulps of t, as an event;
  /// an excursion that stays within ε of the hyperplane (a touch) is not a crossing. The
  /// default throws InvalidInput: an engine that cannot search its segments says so.
  virtual void plane_crossings(const Hyperplane& plane, double trigger, int& side,
                               std::vector<PlaneCrossing>& out) const;

 protected:
  SegmentView(double t_begin, double t_end) : t_begin_(t_begin), t_end_(t_end) {}
  SegmentView(const SegmentView&) = default;
  SegmentView& operator=(const SegmentView&) = default;

 private:
  double t_begin_, t_end_;
};

/// The general engine's segment: one ContactMode's exact flow (contact.hpp, events.hpp).
class DenseSegmentView final : public SegmentView {
 public:
  /// `scratch` (optional; the event loop passes its own) holds two augmented states of the
  /// full system, so that state() allocates nothing (after the mode's first state, which
  /// tabulates its rows: ContactMode::state_rows); without it state() allocates.
  DenseSegmentView(const ContactMode& mode, const Segment& segment, double t_begin, double t_end,
                   double force_tolerance, Eigen::VectorXd* scratch = nullptr)
      : SegmentView(t_begin, t_end), mode_(&mode), segment_(&segment),
        force_tolerance_(force_tolerance), scratch_(scratch) {}

  const ContactMode& mode() const { return *mode_; }
  /// n: the mode's coordinates, free and dependent (to_full's rows also count the forcing's
  /// harmonics, augmented_size).
  Eigen::Index dof() const override {
    return static_cast<Eigen::Index>(mode_->reduced().free.size() + mode_->reduced().dependent.size());
  }
  const ContactSet& active() const override { return mode_->active(); }
  void state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const override;
  /// Times inside (t_begin, t_end) in runs, each by one batched Segment::evaluate; the ends as
  /// state() takes them. Allocates nothing that state() would not.
  void states(const double* t, Eigen::Index count, Eigen::Ref<Eigen::MatrixXd> x,
              Eigen::Ref<Eigen::MatrixXd> v) const override;
  double force(Eigen::Index a, double t) const override;
  Minimum force_minimum(Eigen::Index a) const override;
  std::vector<Minimum> force_local_minima(Eigen::Index a) const override;
  void plane_crossings(const Hyperplane& plane, double trigger, int& side,
                       std::vector<PlaneCrossing>& out) const override;

 private:
  const ContactMode* mode_;
  const Segment* segment_;
  double force_tolerance_;
  Eigen::VectorXd* scratch_;
};

class Observer {
 public:
  virtual ~Observer() = default;
  virtual void begin(const RunContext& /*run*/, double /*t0*/) {}
  virtual void segment(const SegmentView& /*view*/) {}
  virtual void event(const Event& /*event*/) {}
  virtual void end(double /*t_end*/) {}
};

class EventLog : public Observer {
 public:
  void event(const Event& e) override { events.push_back(e); }
  std::vector<Event> events;
};

/// One interval of contact of one stop (a sticking phase).
/// force_min is the least contact force inside the interval away from its ends: the smallest
/// interior local minimum of λ (see SegmentView::force_local_minima), or, where λ has none, the
/// smaller of its values at the start and, if the interval did not end by a release, at the end.
/// It is positive while the stop holds; rising happens where it reaches zero. A chatter released
/// before its accumulation point (the force turned before the bounces converged) never stuck
/// and leaves no interval.
struct ContactInterval {
  int stop = -1;
  double t_start = 0.0, t_end = 0.0;
  double force_min = 0.0, t_force_min = 0.0;
  bool closed = false;  ///< false if the run ended while the stop was still held
};

class ContactLog : public Observer {
 public:
  void begin(const RunContext& run, double t0) override;
  void segment(const SegmentView& view) override;
  void event(const Event& e) override;
  void end(double t_end) override;
  std::vector<ContactInterval> intervals;

 private:
  std::vector<long> open_;  // index into intervals per stop, -1 if free
  std::vector<bool> has_interior_;  // per stop: its open interval has an interior minimum
  std::vector<double> last_end_force_;  // per stop: λ at the end of its last segment
};

/// Exact states at requested times (sorted ascending): column k of x and v is the state at t[k].
/// Both the times and n are known when a run begins, so begin() sizes the storage of every
/// requested time at once and recording a sample allocates nothing (a vector per sample cost
/// more than evaluating it). A time before the run's start or after its end is not recorded;
/// end() drops the columns left over. A second run with the same Samples carries on with the
/// times after the last one taken, appending its columns.
///
///     vibro::Samples samples({0.5, 1.0, 1.5});
///     sim.run(t0, x0, v0, 2.0, {&samples});
///     samples.x.col(1);  // x at t = 1.0 (n)
class Samples : public Observer {
 public:
  explicit Samples(std::vector<double> times) : times_(std::move(times)) {}
  void begin(const RunContext& run, double t0) override;
  void segment(const SegmentView& view) override;
  void end(double t_end) override;
  std::vector<double> t;
  Eigen::MatrixXd x, v;  ///< n × t.size()

 private:
  std::vector<double> times_;
  std::size_t next_ = 0;
};

/// States at t = phase + k·2π/Ω, k = 0, 1, … (Ω > 0 required). How many is not known before
/// the run ends, so each is stored as it comes (one vector each: a few per forcing period).
class Poincare : public Observer {
 public:
  explicit Poincare(double phase_time = 0.0) : phase_time_(phase_time) {}
  void begin(const RunContext& run, double t0) override;
  void segment(const SegmentView& view) override;
  std::vector<double> t;
  std::vector<Eigen::VectorXd> x, v;

 private:
  double phase_time_, period_ = 0.0;
  long next_k_ = 0;
};

/// The impact map: the state just before every impact (of any stop; `stop` says which), the
/// section that papers in the field plot as forcing phase against impact velocity. The state is
/// the end of the segment that reaches the impact, from the exact flow; simultaneous impacts
/// give one row each with the same state. An impact at the run's very start (the initial state
/// on a stop, approaching it) has no segment before it and no row. Bounces of a chatter are
/// impacts and have rows; its accumulation point (a chatter limit) is not an impact.
class ImpactMap : public Observer {
 public:
  void begin(const RunContext& run, double t0) override;
  void segment(const SegmentView& view) override;
  void event(const Event& e) override;
  std::vector<double> t;
  std::vector<double> phase;     ///< Ωt mod 2π in [0, 2π) (0 when unforced)
  std::vector<double> velocity;  ///< the approach speed g'_j before the impact (Event::v_before)
  std::vector<int> stop;
  std::vector<Eigen::VectorXd> x, v;  ///< the state just before

 private:
  double omega_ = 0.0, last_t_ = 0.0;
  bool has_last_ = false;
  Eigen::VectorXd last_x_, last_v_;
};

/// Per forcing period [t0 + kT, t0 + (k+1)T): time each stop sticks (as a fraction of T) and
/// number of impacts of each stop. A stop caught by the chatter rule sticks from the chatter
/// limit (the accumulation point of its bounces), as in ContactLog.
class PeriodStatistics : public Observer {
 public:
  void begin(const RunContext& run, double t0) override;
  void segment(const SegmentView& view) override;
  void event(const Event& e) override;
  std::vector<Eigen::VectorXd> sticking_fraction;  ///< one vector (per stop) per period
  std::vector<Eigen::VectorXi> impacts;

 private:
  void ensure(long k);
  double t0_ = 0.0, period_ = 0.0;
  std::size_t stops_ = 0;
  std::vector<double> sticks_from_;  // per stop: time of its last chatter limit
};

}  // namespace vibro
