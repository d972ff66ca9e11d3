// The /sweep group and the recorded groups of a sweep (docs/results.md, run.kind: sweep): the
// extendible datasets a sweep appends its points to in grid order (fixed-size data stacked on a
// leading point axis, events and contacts concatenated with a `point` column), the `completed`
// counter that makes an interrupted sweep resumable, and the sums /meta gets when it finishes.
#include "../datasets.hpp"
#include "../result_file_impl.hpp"

#include <algorithm>
#include <stdexcept>

namespace vibro::io {

// The Impl members are documented in result_file_impl.hpp.

void ResultFile::Impl::start_sweep(const std::vector<std::string>& names, std::size_t points) {
  store.create_group("/sweep");
  store.set_texts("/sweep", "parameters", names);
  store.set_integer("/sweep", "points", static_cast<std::int64_t>(points));
  store.set_integer("/sweep", "completed", 0);
  const hsize_t k = names.size(), n = static_cast<hsize_t>(dof), c = detail::count_names().size();
  store.create_extendible("/sweep/values", Type::f64, {0, k}, {256, std::max<hsize_t>(k, 1)});
  store.set_texts("/sweep/values", "parameters", names);
  store.create_extendible("/sweep/status", Type::i32, {0}, {256});
  using detail::status_name;
  store.set_texts("/sweep/status", "names",
                  {status_name(RunStatus::completed), status_name(RunStatus::event_cap),
                   status_name(RunStatus::numerical_failure), status_name(RunStatus::unsupported),
                   status_name(RunStatus::interrupted)});
  store.create_extendible("/sweep/message", Type::str, {0}, {256});
  store.create_extendible("/sweep/counts", Type::i64, {0, c}, {256, c});
  store.set_texts("/sweep/counts", "columns", detail::count_names());
  store.create_extendible("/sweep/t_end", Type::f64, {0}, {256});
  store.create_extendible("/sweep/x_end", Type::f64, {0, n}, {256, std::max<hsize_t>(n, 1)});
  store.create_extendible("/sweep/v_end", Type::f64, {0, n}, {256, std::max<hsize_t>(n, 1)});
  sweep_begun = true;
  total = points;
  parameters = names.size();
}

void ResultFile::Impl::put_row(const std::string& path, Type type, const Dims& row_shape,
                               hsize_t row, const void* data) const {
  Dims dims{0};
  dims.insert(dims.end(), row_shape.begin(), row_shape.end());
  if (!store.exists(path)) {
    Dims chunk{256};
    for (hsize_t d : row_shape) chunk.push_back(std::max<hsize_t>(d, 1));
    store.create_extendible(path, type, dims, chunk);
  }
  dims[0] = row + 1;
  store.set_extent(path, dims);
  Dims start(dims.size(), 0), count = dims;
  start[0] = row;
  count[0] = 1;
  store.write_block(path, type, start, count, data);
}

void ResultFile::Impl::append_stacked(const Table& table, hsize_t p) const {
  const std::string group = "/" + table.group;
  if (!store.exists(group)) {
    store.create_group(group);
    store.set_text(group, "stacking", "stacked");
  }
  for (const Dataset& c : table.datasets) {
    const std::string path = group + "/" + c.name;
    const Dims trailing(c.shape.begin() + 1, c.shape.end());
    if (!store.exists(path)) {
      Dims dims{0, 0};
      dims.insert(dims.end(), trailing.begin(), trailing.end());
      const hsize_t row_size = std::max<hsize_t>(detail::element_count(trailing), 1);
      Dims chunk{1, std::clamp<hsize_t>(c.shape[0], 1, std::max<hsize_t>(8192 / row_size, 1))};
      for (hsize_t d : trailing) chunk.push_back(std::max<hsize_t>(d, 1));
      store.create_extendible(path, c.type, dims, chunk);
      for (const auto& [attribute, values] : c.labels) store.set_texts(path, attribute, values);
    }
    Dims dims = store.extent(path);
    if (!std::equal(trailing.begin(), trailing.end(), dims.begin() + 2, dims.end()))
      throw ResultError(store.name() + ": " + path + ": point " + std::to_string(p) +
                        " has rows of another size than the points before it");
    dims[0] = p + 1;
    dims[1] = std::max<hsize_t>(dims[1], c.shape[0]);
    store.set_extent(path, dims);
    Dims start(dims.size(), 0), count{1};
    start[0] = p;
    count.insert(count.end(), c.shape.begin(), c.shape.end());
    store.write_block(path, c.type, start, count, detail::held_values(c));
  }
  const std::int64_t rows = static_cast<std::int64_t>(table.rows);
  put_row(group + "/rows", Type::i64, {}, p, &rows);
}

void ResultFile::Impl::append_ragged(const Table& table, hsize_t p) const {
  const std::string group = "/" + table.group;
  if (!store.exists(group)) {
    store.create_group(group);
    store.set_text(group, "stacking", "concatenated");
  }
  std::vector<Dataset> datasets = table.datasets;
  datasets.push_back(detail::integers(
      "point", std::vector<std::int64_t>(table.rows, static_cast<std::int64_t>(p)), {table.rows}));
  const hsize_t before = store.exists(group + "/point") ? store.extent(group + "/point")[0] : 0;
  for (const Dataset& c : datasets) {
    // Rows of one value (t, stop) or of a state (x, v: r × n): concatenated along the first axis.
    const std::string path = group + "/" + c.name;
    const Dims trailing(c.shape.begin() + 1, c.shape.end());
    if (!store.exists(path)) {
      const hsize_t row_size = std::max<hsize_t>(detail::element_count(trailing), 1);
      Dims dims{before}, chunk{std::max<hsize_t>(4096 / row_size, 1)};
      for (hsize_t d : trailing) {
        dims.push_back(d);
        chunk.push_back(std::max<hsize_t>(d, 1));
      }
      store.create_extendible(path, c.type, dims, chunk);
      for (const auto& [attribute, values] : c.labels) store.set_texts(path, attribute, values);
    }
    Dims dims{before + table.rows}, start{before}, count{table.rows};
    for (hsize_t d : trailing) {
      dims.push_back(d);
      start.push_back(0);
      count.push_back(d);
    }
    store.set_extent(path, dims);
    store.write_block(path, c.type, start, count, detail::held_values(c));
  }
  const std::int64_t rows = static_cast<std::int64_t>(table.rows);
  put_row(group + "/rows", Type::i64, {}, p, &rows);
}

void ResultFile::Impl::write_point(hsize_t p, const PointRecord& point) const {
  for (const Table& table : point.tables)
    table.ragged ? append_ragged(table, p) : append_stacked(table, p);
  const hsize_t n = static_cast<hsize_t>(dof);
  put_row("/sweep/values", Type::f64, {point.values.size()}, p, point.values.data());
  put_row("/sweep/status", Type::i32, {}, p, &point.status);
  const char* message = point.message.c_str();
  put_row("/sweep/message", Type::str, {}, p, &message);
  put_row("/sweep/counts", Type::i64, {point.counts.size()}, p, point.counts.data());
  put_row("/sweep/t_end", Type::f64, {}, p, &point.t_end);
  put_row("/sweep/x_end", Type::f64, {n}, p, point.x_end.data());
  put_row("/sweep/v_end", Type::f64, {n}, p, point.v_end.data());
}

void ResultFile::Impl::commit() const {
  store.flush();
  if (sweep_begun) store.set_integer("/sweep", "completed", static_cast<std::int64_t>(completed));
  store.flush();
}

void ResultFile::Impl::sum_sweep() {
  const std::vector<std::int64_t> all = store.read_integers("/sweep/counts");
  const std::size_t columns = detail::count_names().size();
  for (std::size_t k = 0; k < columns; ++k) {
    std::int64_t sum = 0;
    for (std::size_t i = k; i < all.size(); i += columns) sum += all[i];
    store.set_integer("/meta", detail::count_names()[k], sum);
  }
  const std::vector<std::int64_t> statuses = store.read_integers("/sweep/status");
  const auto early = std::count_if(statuses.begin(), statuses.end(), [](std::int64_t s) { return s != 0; });
  status = early == 0 ? "completed" : "points_stopped_early";
  message = early == 0 ? std::string()
                         : std::to_string(early) + " of " + std::to_string(total) +
                               " points stopped early (see /sweep/status and /sweep/message)";
}

void ResultFile::begin_sweep(const std::vector<std::string>& parameters, std::size_t points) {
  Impl& f = *impl_;
  if (!f.sweep_run) throw std::logic_error("results: begin_sweep on a simulation");
  if (f.sweep_begun) {
    if (f.store.texts_attribute("/sweep", "parameters") != parameters || f.total != points)
      throw ResultError(f.store.name() + ": /sweep: the file sweeps other parameters or another "
                        "grid than this scene");
    return;
  }
  f.start_sweep(parameters, points);
  f.commit();
}

void ResultFile::append_point(std::size_t index, const std::vector<double>& values,
                              const Recording& recording) {
  Impl& f = *impl_;
  if (!f.sweep_begun) throw std::logic_error("results: append_point before begin_sweep");
  if (index != f.completed || index >= f.total)
    throw std::logic_error("results: append_point(" + std::to_string(index) + "): expected point " +
                           std::to_string(f.completed) + " of " + std::to_string(f.total) +
                           " (points are appended in grid order)");
  if (values.size() != f.parameters)
    throw std::logic_error("results: append_point: " + std::to_string(values.size()) +
                           " parameter values for " + std::to_string(f.parameters) + " parameters");
  const RunSummary& s = recording.summary;
  if (s.x.size() != f.dof || s.v.size() != f.dof)
    throw std::logic_error("results: append_point: the summary's final state has the wrong size");

  // Everything is checked before anything is written: a rejected point leaves no trace.
  const std::string where = " (point " + std::to_string(index) + ")";
  detail::PointRecord point;
  point.tables = f.checked_tables(recording, where);
  point.values = values;
  point.status = static_cast<std::int64_t>(s.status);
  point.message = s.message;
  point.counts = detail::counts(s);
  point.t_end = s.t;
  Eigen::VectorXd x_end = s.x, v_end = s.v;  // in the result's frame (record.frame)
  recording.frame.to_result(s.t, x_end, v_end);
  point.x_end.assign(x_end.data(), x_end.data() + x_end.size());
  point.v_end.assign(v_end.data(), v_end.data() + v_end.size());
  const Dataset checks[] = {detail::reals("values", point.values, {values.size()}),
                            detail::reals("t_end", {s.t}, {1}), detail::vector_dataset("x_end", x_end),
                            detail::vector_dataset("v_end", v_end)};
  for (const Dataset& c : checks) detail::require_finite(f.store.name(), "/sweep/" + c.name, c, where);

  f.write_point(static_cast<hsize_t>(index), point);
  f.completed = index + 1;
  f.commit();
}

std::size_t ResultFile::completed_points() const { return impl_->completed; }
std::size_t ResultFile::total_points() const { return impl_->total; }

bool ResultFile::last_state(double& t, Eigen::VectorXd& x, Eigen::VectorXd& v) const {
  const Impl& f = *impl_;
  if (f.completed == 0) return false;
  const std::size_t last = f.completed - 1, n = static_cast<std::size_t>(f.dof);
  t = f.store.read_reals("/sweep/t_end")[last];
  const std::vector<double> xs = f.store.read_reals("/sweep/x_end");
  const std::vector<double> vs = f.store.read_reals("/sweep/v_end");
  x = Eigen::Map<const Eigen::VectorXd>(xs.data() + last * n, f.dof);
  v = Eigen::Map<const Eigen::VectorXd>(vs.data() + last * n, f.dof);
  return true;
}

}  // namespace vibro::io
