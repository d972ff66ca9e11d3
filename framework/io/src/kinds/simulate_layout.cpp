// The recorded groups of a run (docs/results.md: events, contacts, samples, poincare, stats):
// how a Recording becomes Tables of Datasets, and a simulation's file (run.kind: simulate,
// ResultFile::write_simulation). A sweep stacks or concatenates the same Tables point by point
// (sweep_layout.cpp).
#include "../datasets.hpp"
#include "../result_file_impl.hpp"

#include <algorithm>
#include <iterator>
#include <stdexcept>

namespace vibro::io {

namespace detail {

namespace {

constexpr const char* kGroups[] = {"events", "contacts", "samples", "poincare", "impact_map", "section", "stats"};

/// The kinds' names in code order; engage and disengage only for scenes with compliant stops
/// (a scene without them writes the four rigid kinds); the friction kinds (after those six) only
/// for scenes with friction.
std::vector<std::string> event_kind_names(bool compliant, bool friction) {
  std::vector<std::string> names{to_string(EventKind::impact), to_string(EventKind::stick),
                                 to_string(EventKind::release), to_string(EventKind::chatter_limit)};
  if (compliant || friction) {
    names.emplace_back(to_string(EventKind::engage));
    names.emplace_back(to_string(EventKind::disengage));
  }
  if (friction)
    for (EventKind k : {EventKind::friction_stick, EventKind::friction_slip, EventKind::friction_reversal})
      names.emplace_back(to_string(k));
  return names;
}

/// States is Samples' n × r matrix or Poincaré's vector of r vectors (see rows_dataset).
template <class States>
Table states_table(std::string group, const std::vector<double>& t, const States& x, const States& v,
                   Eigen::Index dof) {
  Table table{std::move(group), false, t.size(), {}};
  table.datasets.push_back(reals("t", t, {t.size()}));
  table.datasets.push_back(rows_dataset("x", x, dof));
  table.datasets.push_back(rows_dataset("v", v, dof));
  return table;
}

}  // namespace

Table section_table(const Section& section, Eigen::Index dof) {
  const std::size_t r = section.t.size();
  Table table{"section", true, r, {}};
  table.datasets.push_back(reals("t", section.t, {r}));
  table.datasets.push_back(reals("phase", section.phase, {r}));
  table.datasets.push_back(
      integers("direction", std::vector<std::int64_t>(section.crossing.begin(), section.crossing.end()), {r}, Type::i32));
  table.datasets.push_back(rows_dataset("x", section.x, dof));
  table.datasets.push_back(rows_dataset("v", section.v, dof));
  return table;
}

bool is_ragged(const std::string& group) {
  return group == "events" || group == "contacts" || group == "impact_map" || group == "section";
}

/// The groups a recording writes. /stats gets one row per period begun in the recorded span
/// when the run completed: periods without contact or impact leave no row in the observer and
/// are zero rows here.
std::vector<Table> recorded_tables(const Recording& rec, Eigen::Index dof,
                                   const std::vector<std::string>& stop_names, bool compliant,
                                   bool friction) {
  std::vector<Table> tables;
  if (rec.events) {
    const std::vector<Event>& events = rec.events->events;
    const std::size_t r = events.size();
    std::vector<double> t, before, after, force;
    std::vector<std::int64_t> stop, kind;
    for (const Event& e : events) {
      t.push_back(e.t);
      stop.push_back(e.stop);
      kind.push_back(static_cast<std::int64_t>(e.kind));
      before.push_back(e.v_before);
      after.push_back(e.v_after);
      force.push_back(e.force);
    }
    Table table{"events", true, r, {}};
    table.datasets.push_back(reals("t", std::move(t), {r}));
    table.datasets.push_back(integers("stop", std::move(stop), {r}, Type::i32));
    table.datasets.push_back(integers("kind", std::move(kind), {r}, Type::i32));
    table.datasets.back().labels.emplace_back("names", event_kind_names(compliant, friction));
    table.datasets.push_back(reals("v_before", std::move(before), {r}));
    table.datasets.push_back(reals("v_after", std::move(after), {r}));
    table.datasets.push_back(reals("force", std::move(force), {r}));
    tables.push_back(std::move(table));
  }
  if (rec.contacts) {
    const std::vector<ContactInterval>& intervals = rec.contacts->intervals;
    const std::size_t r = intervals.size();
    std::vector<double> t_start, t_end, force_min, t_force_min;
    std::vector<std::int64_t> stop, closed;
    for (const ContactInterval& c : intervals) {
      stop.push_back(c.stop);
      t_start.push_back(c.t_start);
      t_end.push_back(c.t_end);
      force_min.push_back(c.force_min);
      t_force_min.push_back(c.t_force_min);
      closed.push_back(c.closed ? 1 : 0);
    }
    Table table{"contacts", true, r, {}};
    table.datasets.push_back(integers("stop", std::move(stop), {r}, Type::i32));
    table.datasets.push_back(reals("t_start", std::move(t_start), {r}));
    table.datasets.push_back(reals("t_end", std::move(t_end), {r}));
    table.datasets.push_back(reals("force_min", std::move(force_min), {r}));
    table.datasets.push_back(reals("t_force_min", std::move(t_force_min), {r}));
    table.datasets.push_back(integers("closed", std::move(closed), {r}, Type::i32));
    tables.push_back(std::move(table));
  }
  if (rec.samples) tables.push_back(states_table("samples", rec.samples->t, rec.samples->x,
                                                 rec.samples->v, dof));
  if (rec.poincare) tables.push_back(states_table("poincare", rec.poincare->t, rec.poincare->x,
                                                  rec.poincare->v, dof));
  if (rec.impact_map) {
    const ImpactMap& map = *rec.impact_map;
    const std::size_t r = map.t.size();
    Table table{"impact_map", true, r, {}};
    table.datasets.push_back(reals("t", map.t, {r}));
    table.datasets.push_back(integers("stop", std::vector<std::int64_t>(map.stop.begin(), map.stop.end()), {r}, Type::i32));
    table.datasets.back().labels.emplace_back("stops", stop_names);
    table.datasets.push_back(reals("phase", map.phase, {r}));
    table.datasets.push_back(reals("velocity", map.velocity, {r}));
    table.datasets.push_back(rows_dataset("x", map.x, dof));
    table.datasets.push_back(rows_dataset("v", map.v, dof));
    tables.push_back(std::move(table));
  }
  if (rec.section) tables.push_back(section_table(*rec.section, dof));
  if (rec.statistics) {
    const PeriodStatistics& s = *rec.statistics;
    const std::size_t m = stop_names.size();
    std::size_t rows = s.sticking_fraction.size();
    if (rec.summary.status == RunStatus::completed) rows = std::max(rows, rec.periods);
    std::vector<double> fraction(rows * m, 0.0);
    std::vector<std::int64_t> impacts(rows * m, 0);
    for (std::size_t k = 0; k < s.sticking_fraction.size(); ++k)
      for (std::size_t j = 0; j < m; ++j) {
        const auto jj = static_cast<Eigen::Index>(j);
        fraction[k * m + j] = s.sticking_fraction[k](jj);
        impacts[k * m + j] = s.impacts[k](jj);
      }
    Table table{"stats", false, rows, {}};
    table.datasets.push_back(reals("sticking_fraction", std::move(fraction), {rows, m}));
    table.datasets.push_back(integers("impacts", std::move(impacts), {rows, m}, Type::i32));
    for (Dataset& c : table.datasets) c.labels.emplace_back("stops", stop_names);
    tables.push_back(std::move(table));
  }
  return tables;
}

std::vector<std::string> recorded_groups(const RecordSpec& record) {
  std::vector<std::string> groups;
  if (record.events) groups.push_back("events");
  if (record.contacts) groups.push_back("contacts");
  if (records_samples(record)) groups.push_back("samples");
  if (record.poincare) groups.push_back("poincare");
  if (record.impact_map) groups.push_back("impact_map");
  if (record.section) groups.push_back("section");
  if (record.statistics) groups.push_back("stats");
  return groups;
}

}  // namespace detail

void ResultFile::Impl::require_groups(const Recording& rec) const {
  const bool expected[] = {record.events, record.contacts, detail::records_samples(record),
                           record.poincare, record.impact_map, record.section.has_value(), record.statistics};
  const bool present[] = {rec.events.has_value(), rec.contacts.has_value(),
                          rec.samples.has_value(), rec.poincare.has_value(),
                          rec.impact_map.has_value(), rec.section.has_value(), rec.statistics.has_value()};
  for (std::size_t g = 0; g < std::size(detail::kGroups); ++g)
    if (expected[g] != present[g])
      throw std::logic_error(std::string("results: the recording ") +
                             (present[g] ? "has " : "lacks ") + detail::kGroups[g] +
                             " but the scene records " + (expected[g] ? "it" : "no such group") +
                             ": use Recording::for_scene");
}

std::vector<detail::Table> ResultFile::Impl::checked_tables(const Recording& rec,
                                                            const std::string& where) const {
  require_groups(rec);
  std::vector<Table> tables = detail::recorded_tables(rec, dof, stops, compliant, friction);
  for (const Table& t : tables)
    for (const Dataset& c : t.datasets)
      detail::require_finite(store.name(), "/" + t.group + "/" + c.name, c, where);
  return tables;
}

void ResultFile::write_simulation(const Recording& recording) {
  Impl& f = *impl_;
  if (f.sweep_run) throw std::logic_error("results: write_simulation on a sweep (use append_point)");
  if (f.simulation_written) throw std::logic_error("results: write_simulation called twice");
  const std::vector<detail::Table> tables = f.checked_tables(recording, "");
  for (const detail::Table& table : tables) {
    f.store.create_group("/" + table.group);
    for (const Dataset& c : table.datasets) f.store.write("/" + table.group + "/" + c.name, c);
  }
  const RunSummary& s = recording.summary;
  const std::vector<std::int64_t> values = detail::counts(s);
  for (std::size_t k = 0; k < values.size(); ++k)
    f.store.set_integer("/meta", detail::count_names()[k], values[k]);
  f.store.set_real("/meta", "t_reached", s.t);
  f.store.set_texts("/meta", "warnings", s.warnings);
  f.store.flush();
  f.status = detail::status_name(s.status);
  f.message = s.message;
  f.simulation_written = true;
}

}  // namespace vibro::io
