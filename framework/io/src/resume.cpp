// Resuming an interrupted sweep (ResultFile::open_partial, docs/results.md "Writing,
// interruption, resume"): the old `.partial` must hold the same scene; the points it counted are
// read back, each checked, and copied into a new file that replaces it.
#include "result_file_impl.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>

namespace vibro::io {

namespace detail {

namespace {

/// Resuming: the interrupted file's /scene (and tolerances) must be this scene's.
void require_same_scene(const Store& old, const Scene& scene) {
  const std::string hint = ": the interrupted run used another scene (edited file or other "
                           "--set values); it can only be resumed with the same one";
  if (!old.exists("/scene") || !old.exists("/meta"))
    throw ResultError(old.name() + ": not a vibro result file (no /scene or /meta)");
  if (old.text_attribute("/scene", "yaml") != scene.yaml_text)
    throw ResultError(old.name() + ": /scene attribute yaml: differs from " + scene.file + hint);
  for (const Dataset& c : scene_datasets(scene)) {
    const std::string path = "/scene/" + c.name;
    bool same = old.exists(path) && old.extent(path) == Dims(c.shape.begin(), c.shape.end());
    if (same && c.type == Type::str) same = old.read_texts(path) == c.texts;
    if (same && c.type == Type::f64) same = old.read_reals(path) == c.reals;
    if (same && (c.type == Type::i32 || c.type == Type::i64)) same = old.read_integers(path) == c.integers;
    if (!same) throw ResultError(old.name() + ": " + path + ": differs" + hint);
  }
  for (const auto& [name, value] : scene_numbers(scene))
    if (old.reals_attribute("/scene", name) != std::vector<double>{value})
      throw ResultError(old.name() + ": /scene attribute " + name + ": differs" + hint);
  for (const auto& [name, value] : tolerances(scene.solver))
    if (old.reals_attribute("/meta", name) != std::vector<double>{value})
      throw ResultError(old.name() + ": /meta attribute " + name + ": differs" + hint);
  const std::vector<std::string> attributes = old.attribute_names("/meta");
  if (std::find(attributes.begin(), attributes.end(), "engine") != attributes.end() &&
      old.text_attribute("/meta", "engine") != to_string(scene.engine))
    throw ResultError(old.name() + ": /meta attribute engine: " + old.text_attribute("/meta", "engine") +
                      ", this scene runs with the " + to_string(scene.engine) + " engine" + hint);
}

/// Copies the scalar and string-array attributes of `object` (what /meta holds).
void copy_attributes(const Store& from, const Store& to, const std::string& object) {
  for (const std::string& name : from.attribute_names(object)) {
    switch (from.attribute_kind(object, name)) {
      case Store::Attribute::text: to.set_text(object, name, from.text_attribute(object, name)); break;
      case Store::Attribute::texts: to.set_texts(object, name, from.texts_attribute(object, name)); break;
      case Store::Attribute::integer: to.set_integer(object, name, from.integer_attribute(object, name)); break;
      case Store::Attribute::real: to.set_real(object, name, from.reals_attribute(object, name).at(0)); break;
    }
  }
}

/// Reads back, in order, the points an interrupted sweep counted as complete, checking each:
/// a point whose data cannot be read or holds fill values (a kill can leave HDF5 metadata half
/// flushed) ends the read, and it and the points after it are computed again.
class CompletedPoints {
 public:
  CompletedPoints(const Store& old, const std::vector<std::string>& groups, std::size_t counted)
      : old_(old), groups_(groups), readable_(counted) {
    try {
      for (const char* name : {"values", "status", "counts", "t_end", "x_end", "v_end"})
        limit(old_.extent(std::string("/sweep/") + name)[0]);
      values_ = old_.read_reals("/sweep/values");
      parameters_ = old_.extent("/sweep/values")[1];
      status_ = old_.read_integers("/sweep/status");
      if (old_.exists("/sweep/message")) {
        messages_ = old_.read_texts("/sweep/message");
        limit(messages_.size());
      }
      counts_ = old_.read_integers("/sweep/counts");
      t_end_ = old_.read_reals("/sweep/t_end");
      x_end_ = old_.read_reals("/sweep/x_end");
      v_end_ = old_.read_reals("/sweep/v_end");
      dof_ = old_.extent("/sweep/x_end")[1];
      for (const std::string& group : groups_) {
        rows_[group] = old_.read_integers("/" + group + "/rows");
        limit(rows_[group].size());
        offset_[group] = 0;
      }
    } catch (const DamagedData&) {
      throw;  // damage is refused, not recomputed over: see open_partial
    } catch (const ResultError&) {
      readable_ = 0;
    }
  }

  /// Points that may be read: at most the number counted.
  std::size_t readable() const { return readable_; }

  /// Point p (call with p = 0, 1, … in order); nothing if it is damaged.
  std::optional<PointRecord> read(std::size_t p) {
    try {
      return read_checked(p);
    } catch (const DamagedData&) {
      throw;
    } catch (const ResultError&) {
      return std::nullopt;
    }
  }

 private:
  void limit(std::size_t n) { readable_ = std::min(readable_, n); }

  template <class T>
  static std::vector<T> slice(const std::vector<T>& all, std::size_t row, std::size_t width) {
    return {all.begin() + static_cast<std::ptrdiff_t>(row * width),
            all.begin() + static_cast<std::ptrdiff_t>((row + 1) * width)};
  }
  static bool finite(const std::vector<double>& v) {
    return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
  }
  static bool non_negative(const std::vector<std::int64_t>& v) {
    return std::all_of(v.begin(), v.end(), [](std::int64_t x) { return x >= 0; });
  }

  std::optional<PointRecord> read_checked(std::size_t p) {
    PointRecord point;
    const std::size_t ncounts = count_names().size();
    point.values = slice(values_, p, parameters_);
    point.status = status_[p];
    if (p < messages_.size()) point.message = messages_[p];
    point.counts = slice(counts_, p, ncounts);
    point.t_end = t_end_[p];
    point.x_end = slice(x_end_, p, dof_);
    point.v_end = slice(v_end_, p, dof_);
    if (!finite(point.values) || !finite(point.x_end) || !finite(point.v_end) ||
        !std::isfinite(point.t_end) || point.status < 0 || point.status > 2 ||
        !non_negative(point.counts))
      return std::nullopt;

    for (const std::string& group : groups_) {
      const std::int64_t r = rows_[group][p];
      if (r < 0) return std::nullopt;
      Table table{group, is_ragged(group), static_cast<std::size_t>(r), {}};
      for (const std::string& name : old_.children("/" + group)) {
        if (name == "rows") continue;
        const std::string path = "/" + group + "/" + name;
        const Dims dims = old_.extent(path);
        Dataset c;
        c.name = name;
        c.type = old_.stored_type(path);
        Dims shape, start, count;
        if (table.ragged) {  // rows along the first axis, each of the trailing shape
          if (dims.empty() || offset_[group] + table.rows > dims[0]) return std::nullopt;
          shape = {table.rows};
          shape.insert(shape.end(), dims.begin() + 1, dims.end());
          start.assign(dims.size(), 0);
          start[0] = offset_[group];
          count = shape;
        } else {
          if (dims.size() < 2 || p >= dims[0] || table.rows > dims[1]) return std::nullopt;
          shape = {table.rows};
          shape.insert(shape.end(), dims.begin() + 2, dims.end());
          start.assign(dims.size(), 0);
          start[0] = p;
          count = {1};
          count.insert(count.end(), shape.begin(), shape.end());
        }
        c.shape.assign(shape.begin(), shape.end());
        const std::size_t size = static_cast<std::size_t>(element_count(shape));
        void* buffer = nullptr;
        switch (c.type) {
          case Type::f64: c.reals.resize(size); buffer = c.reals.data(); break;
          case Type::i32: case Type::i64: c.integers.resize(size); buffer = c.integers.data(); break;
          case Type::str: return std::nullopt;
        }
        old_.read_block(path, c.type, start, count, buffer);
        if (!finite(c.reals) || !non_negative(c.integers))
          return std::nullopt;
        for (const std::string& attribute : old_.attribute_names(path))
          if (old_.attribute_kind(path, attribute) == Store::Attribute::texts)
            c.labels.emplace_back(attribute, old_.texts_attribute(path, attribute));
        if (name == "point") {  // regenerated when written; here only checked
          if (!std::all_of(c.integers.begin(), c.integers.end(),
                           [p](std::int64_t q) { return q == static_cast<std::int64_t>(p); }))
            return std::nullopt;
          continue;
        }
        table.datasets.push_back(std::move(c));
      }
      if (table.ragged) offset_[group] += table.rows;
      point.tables.push_back(std::move(table));
    }
    return point;
  }

  const Store& old_;
  std::vector<std::string> groups_;
  std::size_t readable_;
  std::vector<double> values_, t_end_, x_end_, v_end_;
  std::vector<std::int64_t> status_, counts_;
  std::vector<std::string> messages_;  // (none in a file from before /sweep/message existed)
  std::size_t parameters_ = 0, dof_ = 0;
  std::map<std::string, std::vector<std::int64_t>> rows_;
  std::map<std::string, hsize_t> offset_;
};

}  // namespace

}  // namespace detail

ResultFile ResultFile::open_partial(const std::string& path, const Scene& scene, bool overwrite) {
  const std::string partial = partial_path(path);
  if (scene.run.kind != RunSpec::Kind::sweep)
    throw ResultError(partial + ": only a sweep can be resumed (this scene's run.kind is simulate)");
  auto lock = std::make_unique<detail::OutputLock>(path, scene.file, overwrite);
  if (!std::filesystem::exists(partial))
    throw ResultError(partial + ": no interrupted run to resume (file not found)");
  detail::Store old(partial, detail::Store::Mode::read);
  detail::require_same_scene(old, scene);

  // The finished points are copied into a new file that then replaces the old one: nothing a
  // kill may have left half-flushed in the old file is carried over, and until the rename the
  // old file is untouched (a failure here removes only the copy).
  const std::string rebuilt = partial + ".resume";
  detail::OutputLock::remove_if_present(rebuilt);  // a killed resume's scratch copy (we hold the lock)
  ResultFile file(std::make_unique<Impl>(std::move(lock), path, rebuilt, detail::Store::Mode::create, scene));
  Impl& f = *file.impl_;
  f.write_scene(scene);
  f.store.create_group("/meta");
  detail::copy_attributes(old, f.store, "/meta");
  f.store.set_integer("/meta", "resumed", old.integer_attribute("/meta", "resumed") + 1);
  if (old.exists("/sweep")) {
    const std::vector<std::string> names = old.texts_attribute("/sweep", "parameters");
    f.start_sweep(names, static_cast<std::size_t>(old.integer_attribute("/sweep", "points")));
    const auto counted = static_cast<std::size_t>(old.integer_attribute("/sweep", "completed"));
    // A point that cannot be read (metadata a kill left half-flushed) is computed again; a
    // checksum that does not match is damage to the file, and nothing in it can be trusted.
    try {
      detail::CompletedPoints points(old, detail::recorded_groups(f.record), counted);
      for (std::size_t p = 0; p < points.readable(); ++p) {
        const std::optional<detail::PointRecord> point = points.read(p);
        if (!point) break;
        f.write_point(p, *point);
        f.completed = p + 1;
      }
    } catch (const detail::DamagedData& e) {
      throw ResultError(std::string(e.what()) + "; the interrupted run cannot be resumed from it: remove " +
                        partial + " to run it again from the start");
    }
  }
  f.commit();
  f.store.close();
  old.close();
  if (std::rename(rebuilt.c_str(), partial.c_str()) != 0)
    throw ResultError(rebuilt + ": cannot rename to " + partial + ": " + std::strerror(errno));
  f.file_name = partial;
  f.keep_unfinished = true;  // whatever happens now, the finished points stay
  f.store = detail::Store(partial, detail::Store::Mode::write);
  return file;
}

}  // namespace vibro::io
