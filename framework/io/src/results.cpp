/// \file results.cpp
/// Recording (which observers a scene asks for), RunMeta, and the HDF5 result file. The layout
/// written here is specified in docs/results.md; change both together, and only compatibly.
#include "vibro/io/result_file.hpp"

#include "output_lock.hpp"

#include <hdf5.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iterator>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <sstream>
#include <utility>

namespace vibro::io {

// --- Recording, RunMeta --------------------------------------------------------------------------

namespace {

bool records_samples(const RecordSpec& spec) {
  return spec.samples_per_period > 0 || !spec.sample_times.empty();
}

/// Sample times of one recorded span (absolute), ascending.
std::vector<double> sample_times(const Scene& scene, double t_start) {
  const RecordSpec& spec = scene.record;
  const double T = scene.period();
  const double span = scene.run.periods * T;
  std::vector<double> times;
  if (!spec.sample_times.empty()) {
    for (std::size_t i = 0; i < spec.sample_times.size(); ++i) {
      const double s = spec.sample_times[i];
      if (!std::isfinite(s) || s < 0.0 || s > span)
        throw InvalidInput("record.sample_times[" + std::to_string(i) + "] = " + number_text(s) +
                           ": must lie in the recorded span [0, " + number_text(span) +
                           "] (run.periods × period)");
      times.push_back(t_start + s);
    }
    std::sort(times.begin(), times.end());
  } else {
    const auto N = static_cast<double>(spec.samples_per_period);
    const auto count = static_cast<long>(std::floor(N * scene.run.periods + 1e-9));
    for (long i = 0; i < count; ++i) times.push_back(t_start + static_cast<double>(i) * T / N);
  }
  return times;
}

}  // namespace

Recording Recording::for_scene(const Scene& scene, double t_start) {
  const RecordSpec& spec = scene.record;
  const double periods = scene.run.periods;
  Recording rec;
  rec.t_start = t_start;
  rec.t_end = t_start + periods * scene.period();
  rec.periods = static_cast<std::size_t>(std::max(0.0, std::ceil(periods - 1e-9)));

  const bool forced = scene.forcing().frequency > 0.0;
  if (spec.statistics && !forced)
    throw InvalidInput("record.statistics: per-period statistics need a forcing frequency > 0");
  if (spec.poincare && !forced)
    throw InvalidInput("record.poincare: Poincaré sections need a forcing frequency > 0");

  if (spec.events) rec.events.emplace();
  if (spec.contacts) rec.contacts.emplace();
  if (records_samples(spec)) rec.samples.emplace(sample_times(scene, t_start));
  if (spec.poincare) rec.poincare.emplace(t_start);
  if (spec.statistics) rec.statistics.emplace();
  return rec;
}

std::vector<Observer*> Recording::observers() {
  std::vector<Observer*> out;
  if (events) out.push_back(&*events);
  if (contacts) out.push_back(&*contacts);
  if (samples) out.push_back(&*samples);
  if (poincare) out.push_back(&*poincare);
  if (statistics) out.push_back(&*statistics);
  return out;
}

RunMeta current_meta(int threads) {
  RunMeta meta;
#ifdef VIBRO_VERSION
  meta.version = VIBRO_VERSION;
#else
  meta.version = "0.1.0";
#endif
#ifdef VIBRO_GIT_COMMIT
  meta.git_commit = VIBRO_GIT_COMMIT;
#else
  meta.git_commit = "unknown";
#endif
#if defined(__clang__)
  meta.compiler = __VERSION__;
#elif defined(__GNUC__)
  meta.compiler = "GCC " __VERSION__;
#elif defined(__VERSION__)
  meta.compiler = __VERSION__;
#else
  meta.compiler = "unknown";
#endif
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char date[32];
  std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%SZ", &utc);
  meta.date = date;
  meta.threads = threads;
  return meta;
}

// --- HDF5 plumbing -------------------------------------------------------------------------------

namespace {

using Dims = std::vector<hsize_t>;

/// An owned HDF5 identifier, closed by the function that matches its kind.
class Hid {
 public:
  Hid() = default;
  Hid(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  Hid(Hid&& other) noexcept : id_(std::exchange(other.id_, -1)), close_(other.close_) {}
  Hid& operator=(Hid&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = std::exchange(other.id_, -1);
      close_ = other.close_;
    }
    return *this;
  }
  Hid(const Hid&) = delete;
  Hid& operator=(const Hid&) = delete;
  ~Hid() { reset(); }

  /// Closes now; returns the status of the close function (0 if nothing was open).
  herr_t reset() {
    herr_t status = 0;
    if (id_ >= 0 && close_) status = close_(id_);
    id_ = -1;
    return status;
  }
  operator hid_t() const { return id_; }

 private:
  hid_t id_ = -1;
  herr_t (*close_)(hid_t) = nullptr;
};

/// HDF5's description of the last failure (the innermost entry of its error stack).
std::string hdf5_reason() {
  std::string reason;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_DOWNWARD,
      [](unsigned, const H5E_error2_t* error, void* data) -> herr_t {
        if (error->desc && *error->desc) *static_cast<std::string*>(data) = error->desc;
        return 0;
      },
      &reason);
  H5Eclear2(H5E_DEFAULT);
  // A system call's failure comes as "file write failed: time = …, errno = 28, error message =
  // 'No space left on device', buf = …": keep what it says, and what failed.
  const std::string tag = "error message = '";
  const std::size_t at = reason.find(tag);
  if (at != std::string::npos) {
    const std::size_t end = reason.find('\'', at + tag.size());
    reason = reason.substr(0, reason.find(':')) + ": " + reason.substr(at + tag.size(), end - at - tag.size());
  }
  return reason;
}

/// HDF5 errors are reported by exceptions, not printed by the library. And HDF5 does not run its
/// exit handler: after a failed write (a full disk) H5Fclose fails and leaves the file half
/// closed inside the library, and the handler then crashes on it at exit (HDF5 1.10, SIGSEGV in
/// H5F__close_cb). Every file here is closed by its owner, so the handler has nothing to do.
/// H5dont_atexit must come before the library's first use: this is called first by every Store.
void silence_hdf5() {
  static const bool once = [] {
    H5dont_atexit();
    return true;
  }();
  (void)once;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
}

enum class Type { f64, i32, i64, str };

hid_t memory_type(Type type) {
  switch (type) {
    case Type::f64: return H5T_NATIVE_DOUBLE;
    case Type::i32: return H5T_NATIVE_INT32;
    case Type::i64: return H5T_NATIVE_INT64;
    case Type::str: break;
  }
  return -1;
}

hid_t file_type(Type type) {
  switch (type) {
    case Type::f64: return H5T_IEEE_F64LE;
    case Type::i32: return H5T_STD_I32LE;
    case Type::i64: return H5T_STD_I64LE;
    case Type::str: break;
  }
  return -1;
}

/// Variable-length UTF-8 strings (read by h5py as str).
Hid string_type() {
  Hid type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type, H5T_VARIABLE);
  H5Tset_cset(type, H5T_CSET_UTF8);
  return type;
}

hsize_t element_count(const Dims& dims) {
  return std::accumulate(dims.begin(), dims.end(), hsize_t{1}, std::multiplies<>());
}

/// One dataset's content: a row-major array of `shape`, plus string-array attributes.
struct Column {
  std::string name;
  Type type = Type::f64;
  Dims shape;
  std::vector<double> f64;
  std::vector<std::int32_t> i32;
  std::vector<std::int64_t> i64;
  std::vector<std::string> str;
  std::vector<std::pair<std::string, std::vector<std::string>>> labels;

  const void* data() const {
    switch (type) {
      case Type::f64: return f64.data();
      case Type::i32: return i32.data();
      case Type::i64: return i64.data();
      case Type::str: break;
    }
    return nullptr;
  }
};

Column reals(std::string name, std::vector<double> values, Dims shape) {
  Column c;
  c.name = std::move(name);
  c.f64 = std::move(values);
  c.shape = std::move(shape);
  return c;
}

Column int32s(std::string name, std::vector<std::int32_t> values, Dims shape) {
  Column c;
  c.name = std::move(name);
  c.type = Type::i32;
  c.i32 = std::move(values);
  c.shape = std::move(shape);
  return c;
}

Column int64s(std::string name, std::vector<std::int64_t> values, Dims shape) {
  Column c;
  c.name = std::move(name);
  c.type = Type::i64;
  c.i64 = std::move(values);
  c.shape = std::move(shape);
  return c;
}

Column vector_column(std::string name, const Eigen::VectorXd& v) {
  return reals(std::move(name), std::vector<double>(v.data(), v.data() + v.size()),
               {static_cast<hsize_t>(v.size())});
}

Column matrix_column(std::string name, const Eigen::MatrixXd& a) {
  std::vector<double> values;
  values.reserve(static_cast<std::size_t>(a.size()));
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index j = 0; j < a.cols(); ++j) values.push_back(a(i, j));
  return reals(std::move(name), std::move(values),
               {static_cast<hsize_t>(a.rows()), static_cast<hsize_t>(a.cols())});
}

/// rows.size() × cols, one vector per row.
Column rows_column(std::string name, const std::vector<Eigen::VectorXd>& rows, Eigen::Index cols) {
  std::vector<double> values;
  values.reserve(rows.size() * static_cast<std::size_t>(cols));
  for (const Eigen::VectorXd& row : rows) {
    if (row.size() != cols)
      throw std::logic_error("results: " + name + ": a row has " + std::to_string(row.size()) +
                             " entries, expected " + std::to_string(cols));
    values.insert(values.end(), row.data(), row.data() + row.size());
  }
  return reals(std::move(name), std::move(values),
               {static_cast<hsize_t>(rows.size()), static_cast<hsize_t>(cols)});
}

/// columns.cols() × cols from the columns of an n × r matrix (Samples' layout, column-major: its
/// storage is already the r × n array row by row).
Column rows_column(std::string name, const Eigen::MatrixXd& columns, Eigen::Index cols) {
  if (columns.cols() > 0 && columns.rows() != cols)
    throw std::logic_error("results: " + name + ": the columns have " + std::to_string(columns.rows()) +
                           " entries, expected " + std::to_string(cols));
  return reals(std::move(name), std::vector<double>(columns.data(), columns.data() + columns.size()),
               {static_cast<hsize_t>(columns.cols()), static_cast<hsize_t>(cols)});
}

/// "[2, 1]" for flat index 5 of a 3×2 array.
std::string index_text(hsize_t flat, const Dims& shape) {
  std::vector<hsize_t> index(shape.size());
  for (std::size_t k = shape.size(); k-- > 0;) {
    const hsize_t extent = std::max<hsize_t>(shape[k], 1);
    index[k] = flat % extent;
    flat /= extent;
  }
  std::string out = "[";
  for (std::size_t k = 0; k < index.size(); ++k) out += (k ? ", " : "") + std::to_string(index[k]);
  return out + "]";
}

/// An open HDF5 file and the name used in messages.
class Store {
 public:
  /// memory: a new file held in memory (HDF5's core driver, nothing on disk; `name` only labels
  /// it and must be unique among open files); image: read-only, from the bytes of a file.
  enum class Mode { create, read, write, memory, image };

  Store(std::string name, Mode mode, const std::vector<char>* image = nullptr) : name_(std::move(name)) {
    silence_hdf5();
    // SEMI: closing fails if an object is still open, which would be a leak in this file.
    Hid fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    H5Pset_fclose_degree(fapl, H5F_CLOSE_SEMI);
    if (mode == Mode::memory || mode == Mode::image) H5Pset_fapl_core(fapl, 1 << 20, /*backing_store=*/0);
    if (mode == Mode::image && image && !image->empty()) H5Pset_file_image(fapl, const_cast<char*>(image->data()), image->size());
    hid_t id = -1;
    switch (mode) {
      // EXCL: never an existing file, never through a symbolic link (O_CREAT | O_EXCL).
      case Mode::create: id = H5Fcreate(name_.c_str(), H5F_ACC_EXCL, H5P_DEFAULT, fapl); break;
      case Mode::memory: id = H5Fcreate(name_.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl); break;
      case Mode::read: case Mode::image: id = H5Fopen(name_.c_str(), H5F_ACC_RDONLY, fapl); break;
      case Mode::write: id = H5Fopen(name_.c_str(), H5F_ACC_RDWR, fapl); break;
    }
    if (id < 0)
      fail("/", mode == Mode::create || mode == Mode::memory ? "cannot create the file"
                : mode == Mode::image                       ? "not an HDF5 file image"
                                                            : "cannot open the file");
    file_ = Hid(id, H5Fclose);
  }

  /// A unique label for a file held in memory (HDF5 takes two open files of one name for one).
  static std::string memory_name(const char* what) {
    static std::atomic<unsigned long> count{0};
    return std::string("<") + what + " " + std::to_string(++count) + ">";
  }

  /// The bytes of the file as it is now (flushed first): what it would be on disk.
  std::vector<char> image() const {
    flush();
    const ssize_t size = H5Fget_file_image(file_, nullptr, 0);
    if (size < 0) fail("/", "cannot take the file's image");
    std::vector<char> bytes(static_cast<std::size_t>(size));
    if (size > 0 && H5Fget_file_image(file_, bytes.data(), bytes.size()) != size)
      fail("/", "cannot take the file's image");
    return bytes;
  }

  const std::string& name() const { return name_; }

  [[noreturn]] void fail(const std::string& object, const std::string& what) const {
    const std::string reason = hdf5_reason();
    throw ResultError(name_ + ": " + object + ": " + what +
                      (reason.empty() ? "" : " (HDF5: " + reason + ")"));
  }
  hid_t check_id(hid_t id, const std::string& object, const std::string& what) const {
    if (id < 0) fail(object, what);
    return id;
  }
  void check(herr_t status, const std::string& object, const std::string& what) const {
    if (status < 0) fail(object, what);
  }

  void flush() const { check(H5Fflush(file_, H5F_SCOPE_GLOBAL), "/", "cannot flush to disk"); }
  void close() { check(file_.reset(), "/", "cannot close the file"); }

  // Objects.

  /// Whether the group or dataset at `path` exists (every link along the path is checked).
  bool exists(const std::string& path) const {
    if (path.empty() || path == "/") return true;
    std::size_t end = 0;
    do {
      end = path.find('/', end + 1);
      if (H5Lexists(file_, path.substr(0, end).c_str(), H5P_DEFAULT) <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return false;
      }
    } while (end != std::string::npos);
    return true;
  }

  Hid open_object(const std::string& path) const {
    return Hid(check_id(H5Oopen(file_, path.c_str(), H5P_DEFAULT), path, "cannot open"), H5Oclose);
  }
  Hid open_dataset(const std::string& path) const {
    return Hid(check_id(H5Dopen2(file_, path.c_str(), H5P_DEFAULT), path, "cannot open the dataset"),
               H5Dclose);
  }
  bool is_dataset(const std::string& path) const {
    if (!exists(path)) return false;
    Hid object = open_object(path);
    return H5Iget_type(object) == H5I_DATASET;
  }

  void create_group(const std::string& path) const {
    Hid group(check_id(H5Gcreate2(file_, path.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path,
                       "cannot create the group"),
              H5Gclose);
  }

  /// Names of the links in a group, in name order.
  std::vector<std::string> children(const std::string& group_path) const {
    std::vector<std::string> names;
    Hid group(check_id(H5Gopen2(file_, group_path.c_str(), H5P_DEFAULT), group_path,
                       "cannot open the group"),
              H5Gclose);
    hsize_t index = 0;
    check(H5Literate(
              group, H5_INDEX_NAME, H5_ITER_INC, &index,
              [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
                static_cast<std::vector<std::string>*>(data)->push_back(name);
                return 0;
              },
              &names),
          group_path, "cannot list the group");
    return names;
  }

  /// Every group and dataset below the root, as absolute paths.
  std::vector<std::string> objects() const {
    std::vector<std::string> names;
    check(H5Lvisit(
              file_, H5_INDEX_NAME, H5_ITER_INC,
              [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
                static_cast<std::vector<std::string>*>(data)->push_back(std::string("/") + name);
                return 0;
              },
              &names),
          "/", "cannot list the file");
    std::sort(names.begin(), names.end());
    return names;
  }

  // Datasets.

  /// A new dataset of exactly c.shape, written whole (no chunks; empty datasets allowed).
  void write(const std::string& path, const Column& c) const {
    Hid space(check_id(H5Screate_simple(static_cast<int>(c.shape.size()), c.shape.data(), nullptr),
                       path, "cannot describe its shape"),
              H5Sclose);
    Hid strings = c.type == Type::str ? string_type() : Hid();
    const hid_t ftype = c.type == Type::str ? hid_t(strings) : file_type(c.type);
    const hid_t mtype = c.type == Type::str ? hid_t(strings) : memory_type(c.type);
    Hid dataset(check_id(H5Dcreate2(file_, path.c_str(), ftype, space, H5P_DEFAULT, H5P_DEFAULT,
                                    H5P_DEFAULT),
                         path, "cannot create the dataset"),
                H5Dclose);
    if (element_count(c.shape) > 0) {
      std::vector<const char*> pointers;
      for (const std::string& s : c.str) pointers.push_back(s.c_str());
      const void* data = c.type == Type::str ? static_cast<const void*>(pointers.data()) : c.data();
      check(H5Dwrite(dataset, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), path,
            "cannot write the dataset");
    }
    for (const auto& [attribute, values] : c.labels) set_texts(path, attribute, values);
  }

  /// A new chunked dataset, every dimension extendible, starting at `dims`; missing entries
  /// read as NaN (reals) or -1 (integers).
  void create_extendible(const std::string& path, Type type, const Dims& dims,
                         const Dims& chunk) const {
    const Dims unlimited(dims.size(), H5S_UNLIMITED);
    Hid space(check_id(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), unlimited.data()),
                       path, "cannot describe its shape"),
              H5Sclose);
    Hid dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    check(H5Pset_chunk(dcpl, static_cast<int>(chunk.size()), chunk.data()), path,
          "cannot set its chunks");
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const std::int64_t minus_one = -1;
    if (type == Type::f64)
      check(H5Pset_fill_value(dcpl, H5T_NATIVE_DOUBLE, &nan), path, "cannot set its fill value");
    else
      check(H5Pset_fill_value(dcpl, H5T_NATIVE_INT64, &minus_one), path,
            "cannot set its fill value");
    Hid dataset(check_id(H5Dcreate2(file_, path.c_str(), file_type(type), space, H5P_DEFAULT, dcpl,
                                    H5P_DEFAULT),
                         path, "cannot create the dataset"),
                H5Dclose);
  }

  Dims extent(const std::string& path) const {
    Hid dataset = open_dataset(path);
    Hid space(check_id(H5Dget_space(dataset), path, "cannot read its shape"), H5Sclose);
    const int rank = H5Sget_simple_extent_ndims(space);
    if (rank < 0) fail(path, "cannot read its rank");
    Dims dims(static_cast<std::size_t>(rank));
    if (rank > 0) check(H5Sget_simple_extent_dims(space, dims.data(), nullptr), path,
                        "cannot read its shape");
    return dims;
  }

  void set_extent(const std::string& path, const Dims& dims) const {
    Hid dataset = open_dataset(path);
    check(H5Dset_extent(dataset, dims.data()), path, "cannot resize the dataset");
  }

  /// Writes the block [start, start + count) of an existing dataset.
  void write_block(const std::string& path, Type type, const Dims& start, const Dims& count,
                   const void* data) const {
    if (element_count(count) == 0) return;
    Hid dataset = open_dataset(path);
    Hid file_space(check_id(H5Dget_space(dataset), path, "cannot read its shape"), H5Sclose);
    check(H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, count.data(),
                              nullptr),
          path, "cannot select the block to write");
    Hid memory_space(check_id(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr),
                              path, "cannot describe the block"),
                     H5Sclose);
    check(H5Dwrite(dataset, memory_type(type), memory_space, file_space, H5P_DEFAULT, data), path,
          "cannot write");
  }

  /// Reads the block [start, start + count) of a dataset, converted to `type`.
  void read_block(const std::string& path, Type type, const Dims& start, const Dims& count,
                  void* out) const {
    if (element_count(count) == 0) return;
    Hid dataset = open_dataset(path);
    Hid file_space(check_id(H5Dget_space(dataset), path, "cannot read its shape"), H5Sclose);
    check(H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, count.data(),
                              nullptr),
          path, "cannot select the block to read");
    Hid memory_space(check_id(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr),
                              path, "cannot describe the block"),
                     H5Sclose);
    check(H5Dread(dataset, memory_type(type), memory_space, file_space, H5P_DEFAULT, out), path,
          "cannot read");
  }

  Type stored_type(const std::string& path) const {
    const std::string name = type_name(path);
    if (name == "f64") return Type::f64;
    if (name == "i32") return Type::i32;
    if (name == "i64") return Type::i64;
    if (name == "str") return Type::str;
    fail(path, "has a type this file format does not use");
  }

  template <class T>
  std::vector<T> read_all(const std::string& path, hid_t memory) const {
    Hid dataset = open_dataset(path);
    std::vector<T> values(static_cast<std::size_t>(element_count(extent(path))));
    if (!values.empty())
      check(H5Dread(dataset, memory, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), path,
            "cannot read");
    return values;
  }
  std::vector<double> read_reals(const std::string& path) const {
    return read_all<double>(path, H5T_NATIVE_DOUBLE);
  }
  std::vector<std::int64_t> read_integers(const std::string& path) const {
    return read_all<std::int64_t>(path, H5T_NATIVE_INT64);
  }
  std::vector<std::string> read_texts(const std::string& path) const {
    Hid dataset = open_dataset(path);
    Hid type(check_id(H5Dget_type(dataset), path, "cannot read its type"), H5Tclose);
    const auto count = static_cast<std::size_t>(element_count(extent(path)));
    return read_strings(
        path, type, count, [&](hid_t memory, void* buffer) {
          return H5Dread(dataset, memory, H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer);
        });
  }

  std::string type_name(const std::string& path) const {
    Hid dataset = open_dataset(path);
    Hid type(check_id(H5Dget_type(dataset), path, "cannot read its type"), H5Tclose);
    const std::size_t size = H5Tget_size(type);
    switch (H5Tget_class(type)) {
      case H5T_FLOAT: return size == 8 ? "f64" : "other";
      case H5T_INTEGER: return size == 4 ? "i32" : size == 8 ? "i64" : "other";
      case H5T_STRING: return "str";
      default: return "other";
    }
  }

  // Attributes.

  enum class Attribute { text, texts, integer, real };
  Attribute attribute_kind(const std::string& object, const std::string& name) const {
    Hid attribute = open_attribute(object, name);
    Hid type(check_id(H5Aget_type(attribute), object, "cannot read attribute `" + name + "`"),
             H5Tclose);
    Hid space(check_id(H5Aget_space(attribute), object, "cannot read attribute `" + name + "`"),
              H5Sclose);
    const bool scalar = H5Sget_simple_extent_type(space) == H5S_SCALAR;
    switch (H5Tget_class(type)) {
      case H5T_STRING: return scalar ? Attribute::text : Attribute::texts;
      case H5T_INTEGER: return Attribute::integer;
      default: return Attribute::real;
    }
  }

  void set_real(const std::string& object, const std::string& name, double value) const {
    put_attribute(object, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}, &value);
  }
  void set_integer(const std::string& object, const std::string& name, std::int64_t value) const {
    put_attribute(object, name, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, &value);
  }
  void set_text(const std::string& object, const std::string& name, const std::string& value) const {
    Hid type = string_type();
    const char* pointer = value.c_str();
    put_attribute(object, name, type, type, {}, &pointer);
  }
  void set_texts(const std::string& object, const std::string& name,
                 const std::vector<std::string>& values) const {
    Hid type = string_type();
    std::vector<const char*> pointers;
    for (const std::string& s : values) pointers.push_back(s.c_str());
    put_attribute(object, name, type, type, {static_cast<hsize_t>(values.size())}, pointers.data());
  }

  std::vector<std::string> attribute_names(const std::string& object) const {
    Hid handle = open_object(object);
    std::vector<std::string> names;
    hsize_t index = 0;
    check(H5Aiterate2(
              handle, H5_INDEX_NAME, H5_ITER_INC, &index,
              [](hid_t, const char* name, const H5A_info_t*, void* data) -> herr_t {
                static_cast<std::vector<std::string>*>(data)->push_back(name);
                return 0;
              },
              &names),
          object, "cannot list its attributes");
    return names;
  }
  bool attribute_is_text(const std::string& object, const std::string& name) const {
    Hid attribute = open_attribute(object, name);
    Hid type(check_id(H5Aget_type(attribute), object, "cannot read attribute `" + name + "`"),
             H5Tclose);
    return H5Tget_class(type) == H5T_STRING;
  }
  std::vector<double> reals_attribute(const std::string& object, const std::string& name) const {
    Hid attribute = open_attribute(object, name);
    std::vector<double> values(attribute_size(attribute, object, name));
    if (!values.empty())
      check(H5Aread(attribute, H5T_NATIVE_DOUBLE, values.data()), object,
            "cannot read attribute `" + name + "` as numbers");
    return values;
  }
  std::int64_t integer_attribute(const std::string& object, const std::string& name) const {
    Hid attribute = open_attribute(object, name);
    if (attribute_size(attribute, object, name) != 1)
      fail(object, "attribute `" + name + "` is not a single number");
    std::int64_t value = 0;
    check(H5Aread(attribute, H5T_NATIVE_INT64, &value), object,
          "cannot read attribute `" + name + "` as an integer");
    return value;
  }
  std::vector<std::string> texts_attribute(const std::string& object, const std::string& name) const {
    Hid attribute = open_attribute(object, name);
    Hid type(check_id(H5Aget_type(attribute), object, "cannot read attribute `" + name + "`"),
             H5Tclose);
    return read_strings(object + " attribute `" + name + "`", type,
                        attribute_size(attribute, object, name),
                        [&](hid_t memory, void* buffer) { return H5Aread(attribute, memory, buffer); });
  }
  std::string text_attribute(const std::string& object, const std::string& name) const {
    const std::vector<std::string> values = texts_attribute(object, name);
    if (values.size() != 1) fail(object, "attribute `" + name + "` is not a single string");
    return values.front();
  }

 private:
  Hid open_attribute(const std::string& object, const std::string& name) const {
    Hid handle = open_object(object);
    return Hid(check_id(H5Aopen(handle, name.c_str(), H5P_DEFAULT), object,
                        "cannot open attribute `" + name + "`"),
               H5Aclose);
  }

  std::size_t attribute_size(hid_t attribute, const std::string& object,
                             const std::string& name) const {
    Hid space(check_id(H5Aget_space(attribute), object, "cannot read attribute `" + name + "`"),
              H5Sclose);
    const hssize_t n = H5Sget_simple_extent_npoints(space);
    if (n < 0) fail(object, "cannot read the size of attribute `" + name + "`");
    return static_cast<std::size_t>(n);
  }

  /// Sets attribute `name` of `object` (dims empty = scalar): in place when it exists with this
  /// type and shape (one small metadata write: the `completed` counter of a sweep relies on it),
  /// else replaced.
  void put_attribute(const std::string& object, const std::string& name, hid_t ftype, hid_t mtype,
                     const Dims& dims, const void* data) const {
    Hid handle = open_object(object);  // kept open: HDF5 1.10 cannot write an orphan attribute
    const std::string what = "cannot write attribute `" + name + "`";
    const htri_t found = H5Aexists(handle, name.c_str());
    check(found, object, what);
    if (found > 0) {
      Hid existing(check_id(H5Aopen(handle, name.c_str(), H5P_DEFAULT), object, what), H5Aclose);
      Hid type(check_id(H5Aget_type(existing), object, what), H5Tclose);
      Hid space(check_id(H5Aget_space(existing), object, what), H5Sclose);
      Dims current(static_cast<std::size_t>(std::max(H5Sget_simple_extent_ndims(space), 0)));
      if (!current.empty()) H5Sget_simple_extent_dims(space, current.data(), nullptr);
      if (H5Tequal(type, ftype) > 0 && current == dims) {
        if (dims.empty() || element_count(dims) > 0) check(H5Awrite(existing, mtype, data), object, what);
        return;
      }
      existing.reset();
      check(H5Adelete(handle, name.c_str()), object, what);
    }
    Hid space(check_id(dims.empty() ? H5Screate(H5S_SCALAR)
                                    : H5Screate_simple(static_cast<int>(dims.size()), dims.data(),
                                                       nullptr),
                       object, what),
              H5Sclose);
    Hid attribute(check_id(H5Acreate2(handle, name.c_str(), ftype, space, H5P_DEFAULT, H5P_DEFAULT),
                           object, what),
                  H5Aclose);
    // An empty array (a scene without stops: /stats' `stops`) has nothing to write; HDF5
    // refuses a write of nothing (null buffer).
    if (!dims.empty() && element_count(dims) == 0) return;
    check(H5Awrite(attribute, mtype, data), object, what);
  }

  /// Reads `count` strings stored with `stored` type (variable or fixed length).
  template <class Read>
  std::vector<std::string> read_strings(const std::string& what, hid_t stored, std::size_t count,
                                        Read read) const {
    if (H5Tget_class(stored) != H5T_STRING) fail(what, "is not text");
    std::vector<std::string> out;
    if (H5Tis_variable_str(stored) > 0) {
      Hid memory = string_type();
      std::vector<char*> pointers(count, nullptr);
      if (count > 0) check(read(memory, pointers.data()), what, "cannot read the text");
      for (char* p : pointers) {
        out.emplace_back(p ? p : "");
        if (p) H5free_memory(p);
      }
    } else {
      const std::size_t size = H5Tget_size(stored);
      Hid memory(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(memory, size);
      std::vector<char> buffer(count * size);
      if (count > 0) check(read(memory, buffer.data()), what, "cannot read the text");
      for (std::size_t i = 0; i < count; ++i) {
        const char* begin = buffer.data() + i * size;
        out.emplace_back(begin, strnlen(begin, size));
      }
    }
    return out;
  }

  std::string name_;
  Hid file_;
};

// --- What gets written -----------------------------------------------------------------------------

/// One recorded group of one run: `rows` rows in every column.
struct Table {
  std::string group;
  bool ragged = false;  ///< events, contacts: a sweep concatenates them with a `point` column
  hsize_t rows = 0;
  std::vector<Column> columns;
};

constexpr const char* kGroups[] = {"events", "contacts", "samples", "poincare", "stats"};

bool is_ragged(const std::string& group) { return group == "events" || group == "contacts"; }

std::vector<std::string> event_kind_names() {
  return {to_string(EventKind::impact), to_string(EventKind::stick), to_string(EventKind::release),
          to_string(EventKind::chatter_limit)};
}

/// States is Samples' n × r matrix or Poincaré's vector of r vectors (see rows_column).
template <class States>
Table states_table(std::string group, const std::vector<double>& t, const States& x, const States& v,
                   Eigen::Index dof) {
  Table table{std::move(group), false, t.size(), {}};
  table.columns.push_back(reals("t", t, {t.size()}));
  table.columns.push_back(rows_column("x", x, dof));
  table.columns.push_back(rows_column("v", v, dof));
  return table;
}

/// The groups a recording writes. /stats gets one row per period begun in the recorded span
/// when the run completed: periods without contact or impact leave no row in the observer and
/// are zero rows here.
std::vector<Table> recorded_tables(const Recording& rec, Eigen::Index dof,
                                   const std::vector<std::string>& stop_names) {
  std::vector<Table> tables;
  if (rec.events) {
    const std::vector<Event>& events = rec.events->events;
    const hsize_t r = events.size();
    std::vector<double> t, before, after, force;
    std::vector<std::int32_t> stop, kind;
    for (const Event& e : events) {
      t.push_back(e.t);
      stop.push_back(e.stop);
      kind.push_back(static_cast<std::int32_t>(e.kind));
      before.push_back(e.v_before);
      after.push_back(e.v_after);
      force.push_back(e.force);
    }
    Table table{"events", true, r, {}};
    table.columns.push_back(reals("t", std::move(t), {r}));
    table.columns.push_back(int32s("stop", std::move(stop), {r}));
    table.columns.push_back(int32s("kind", std::move(kind), {r}));
    table.columns.back().labels.emplace_back("names", event_kind_names());
    table.columns.push_back(reals("v_before", std::move(before), {r}));
    table.columns.push_back(reals("v_after", std::move(after), {r}));
    table.columns.push_back(reals("force", std::move(force), {r}));
    tables.push_back(std::move(table));
  }
  if (rec.contacts) {
    const std::vector<ContactInterval>& intervals = rec.contacts->intervals;
    const hsize_t r = intervals.size();
    std::vector<double> t_start, t_end, force_min, t_force_min;
    std::vector<std::int32_t> stop, closed;
    for (const ContactInterval& c : intervals) {
      stop.push_back(c.stop);
      t_start.push_back(c.t_start);
      t_end.push_back(c.t_end);
      force_min.push_back(c.force_min);
      t_force_min.push_back(c.t_force_min);
      closed.push_back(c.closed ? 1 : 0);
    }
    Table table{"contacts", true, r, {}};
    table.columns.push_back(int32s("stop", std::move(stop), {r}));
    table.columns.push_back(reals("t_start", std::move(t_start), {r}));
    table.columns.push_back(reals("t_end", std::move(t_end), {r}));
    table.columns.push_back(reals("force_min", std::move(force_min), {r}));
    table.columns.push_back(reals("t_force_min", std::move(t_force_min), {r}));
    table.columns.push_back(int32s("closed", std::move(closed), {r}));
    tables.push_back(std::move(table));
  }
  if (rec.samples) tables.push_back(states_table("samples", rec.samples->t, rec.samples->x,
                                                 rec.samples->v, dof));
  if (rec.poincare) tables.push_back(states_table("poincare", rec.poincare->t, rec.poincare->x,
                                                  rec.poincare->v, dof));
  if (rec.statistics) {
    const PeriodStatistics& s = *rec.statistics;
    const hsize_t m = stop_names.size();
    std::size_t rows = s.sticking_fraction.size();
    if (rec.summary.status == RunStatus::completed) rows = std::max(rows, rec.periods);
    std::vector<double> fraction(rows * m, 0.0);
    std::vector<std::int32_t> impacts(rows * m, 0);
    for (std::size_t k = 0; k < s.sticking_fraction.size(); ++k)
      for (hsize_t j = 0; j < m; ++j) {
        const auto jj = static_cast<Eigen::Index>(j);
        fraction[k * m + j] = s.sticking_fraction[k](jj);
        impacts[k * m + j] = s.impacts[k](jj);
      }
    Table table{"stats", false, rows, {}};
    table.columns.push_back(reals("sticking_fraction", std::move(fraction), {rows, m}));
    table.columns.push_back(int32s("impacts", std::move(impacts), {rows, m}));
    for (Column& c : table.columns) c.labels.emplace_back("stops", stop_names);
    tables.push_back(std::move(table));
  }
  return tables;
}

/// Throws ResultError naming the dataset and the entry if a value is not finite.
void require_finite(const std::string& file, const std::string& dataset, const Column& c,
                    const std::string& where = "") {
  for (std::size_t i = 0; i < c.f64.size(); ++i)
    if (!std::isfinite(c.f64[i]))
      throw ResultError(file + ": " + dataset + ": entry " + index_text(i, c.shape) + where +
                        " is " + number_text(c.f64[i]) + ": not written, result values must be finite");
}

/// The resolved scene as datasets of /scene.
/// A scene run by the modal engine gives its chain in banded form (O(n)): its dense matrices are
/// never built (at n = 10 000 each would take 800 MB).
std::vector<Column> scene_columns(const Scene& scene) {
  std::vector<Column> c;
  if (scene.engine == EngineKind::modal && scene.chain) {
    const BandedChain& chain = *scene.chain;
    c.push_back(vector_column("mass_diagonal", chain.mass));
    c.push_back(vector_column("stiffness_diagonal", chain.stiffness_diagonal));
    c.push_back(vector_column("stiffness_off_diagonal", chain.stiffness_off));
    c.push_back(vector_column("rayleigh", Eigen::Vector2d(chain.rayleigh_mass, chain.rayleigh_stiffness)));
  } else {
    const LinearSystem& s = scene.system();
    c.push_back(matrix_column("mass", s.mass()));
    c.push_back(matrix_column("damping", s.damping()));
    c.push_back(matrix_column("stiffness", s.stiffness()));
  }
  const HarmonicForcing& f = scene.forcing();
  c.push_back(vector_column("forcing_constant", f.constant));
  c.push_back(vector_column("forcing_cosine", f.cosine));
  c.push_back(vector_column("forcing_sine", f.sine));

  // Stop names defaulted as in messages (a Scene made in code may leave them empty).
  const std::vector<Stop> stops = validated_stops(scene.stops, scene.dof(), f.frequency);
  const hsize_t m = stops.size();
  std::vector<std::int32_t> kind;
  std::vector<std::int64_t> mass, other;
  std::vector<double> position, restitution, amplitude, phase;
  Column name;
  name.name = "stop_name";
  name.type = Type::str;
  name.shape = {m};
  for (const Stop& stop : stops) {
    kind.push_back(static_cast<std::int32_t>(stop.kind));
    mass.push_back(stop.mass);
    other.push_back(stop.other);
    position.push_back(stop.position);
    restitution.push_back(stop.restitution);
    amplitude.push_back(stop.amplitude);
    phase.push_back(stop.phase);
    name.str.push_back(stop.name);
  }
  c.push_back(int32s("stop_kind", std::move(kind), {m}));
  c.back().labels.emplace_back("names", std::vector<std::string>{"upper", "lower", "between"});
  c.push_back(int64s("stop_mass", std::move(mass), {m}));
  c.push_back(int64s("stop_other", std::move(other), {m}));
  c.push_back(reals("stop_position", std::move(position), {m}));
  c.push_back(reals("stop_restitution", std::move(restitution), {m}));
  c.push_back(reals("stop_amplitude", std::move(amplitude), {m}));
  c.push_back(reals("stop_phase", std::move(phase), {m}));
  c.push_back(std::move(name));
  c.push_back(vector_column("x0", scene.x0));
  c.push_back(vector_column("v0", scene.v0));
  return c;
}

/// Numeric attributes of /scene (the resolved run settings).
std::vector<std::pair<std::string, double>> scene_numbers(const Scene& scene) {
  return {{"frequency", scene.forcing().frequency},
          {"t0", scene.t0},
          {"transient_periods", scene.run.transient_periods},
          {"periods", scene.run.periods},
          {"follow", scene.run.follow ? 1.0 : 0.0},
          {"reverse", scene.run.reverse ? 1.0 : 0.0}};
}

const char* flow_method_name(FlowMethod method) {
  switch (method) {
    case FlowMethod::automatic: return "automatic";
    case FlowMethod::spectral: return "spectral";
    case FlowMethod::exponential: return "exponential";
  }
  return "?";
}

/// The solver tolerances, written to /meta (and compared on resume); max_events is the one
/// integer among them (stored as i64, compared here as a double: exact below 2^53).
std::vector<std::pair<std::string, double>> tolerances(const SimulatorOptions& o) {
  return {{"trigger", o.trigger},
          {"simultaneity", o.simultaneity},
          {"chatter_height", o.chatter_height},
          {"chatter_velocity", o.chatter_velocity},
          {"contact_velocity", o.contact_velocity},
          {"max_events", static_cast<double>(o.max_events)},
          {"event_window", o.event_window},
          {"length_scale", o.length_scale},
          {"flow_max_condition", o.flow.max_condition}};
}

const char* status_name(RunStatus status) {
  switch (status) {
    case RunStatus::completed: return "completed";
    case RunStatus::event_cap: return "event_cap";
    case RunStatus::numerical_failure: return "numerical_failure";
    case RunStatus::unsupported: return "unsupported";
    case RunStatus::interrupted: return "interrupted";
  }
  return "?";
}

/// Columns of /sweep/counts and the /meta attributes that sum them.
const std::vector<std::string>& count_names() {
  static const std::vector<std::string> names{"impacts",  "sticks",   "releases",
                                              "chatters", "segments", "contact_sets_built",
                                              "sticking_flows_built"};
  return names;
}

std::vector<std::int64_t> counts(const RunSummary& s) {
  return {s.impacts,
          s.sticks,
          s.releases,
          s.chatters,
          s.segments,
          static_cast<std::int64_t>(s.contact_sets_built),
          static_cast<std::int64_t>(s.sticking_flows_built)};
}

std::vector<std::string> stop_names(const Scene& scene) {
  std::vector<std::string> names;
  // Names defaulted as in messages; O(m log m), no dense system.
  for (const Stop& stop : validated_stops(scene.stops, scene.dof(), scene.forcing().frequency))
    names.push_back(stop.name);
  return names;
}

/// The recorded groups of a scene, as named in the file.
std::vector<std::string> recorded_groups(const RecordSpec& record) {
  std::vector<std::string> groups;
  if (record.events) groups.push_back("events");
  if (record.contacts) groups.push_back("contacts");
  if (records_samples(record)) groups.push_back("samples");
  if (record.poincare) groups.push_back("poincare");
  if (record.statistics) groups.push_back("stats");
  return groups;
}

/// Resuming: the interrupted file's /scene (and tolerances) must be this scene's.
void require_same_scene(const Store& old, const Scene& scene) {
  const std::string hint = ": the interrupted run used another scene (edited file or other "
                           "--set values); it can only be resumed with the same one";
  if (!old.exists("/scene") || !old.exists("/meta"))
    throw ResultError(old.name() + ": not a vibro result file (no /scene or /meta)");
  if (old.text_attribute("/scene", "yaml") != scene.yaml_text)
    throw ResultError(old.name() + ": /scene attribute yaml: differs from " + scene.file + hint);
  for (const Column& c : scene_columns(scene)) {
    const std::string path = "/scene/" + c.name;
    bool same = old.exists(path) && old.extent(path) == c.shape;
    if (same && c.type == Type::str) same = old.read_texts(path) == c.str;
    if (same && c.type == Type::f64) same = old.read_reals(path) == c.f64;
    if (same && c.type == Type::i32)
      same = old.read_integers(path) == std::vector<std::int64_t>(c.i32.begin(), c.i32.end());
    if (same && c.type == Type::i64) same = old.read_integers(path) == c.i64;
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

/// One sweep point as written: its recorded groups and its row of each /sweep dataset.
struct PointRecord {
  std::vector<Table> tables;
  std::vector<double> values;
  std::int32_t status = 0;
  std::vector<std::int64_t> counts;
  double t_end = 0.0;
  std::vector<double> x_end, v_end;
};

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
    point.status = static_cast<std::int32_t>(status_[p]);
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
      Table table{group, is_ragged(group), static_cast<hsize_t>(r), {}};
      for (const std::string& name : old_.children("/" + group)) {
        if (name == "rows") continue;
        const std::string path = "/" + group + "/" + name;
        const Dims dims = old_.extent(path);
        Column c;
        c.name = name;
        c.type = old_.stored_type(path);
        Dims start, count;
        if (table.ragged) {
          start = {offset_[group]};
          c.shape = count = {table.rows};
          if (dims.size() != 1 || start[0] + table.rows > dims[0]) return std::nullopt;
        } else {
          if (dims.size() < 2 || p >= dims[0] || table.rows > dims[1]) return std::nullopt;
          c.shape = {table.rows};
          c.shape.insert(c.shape.end(), dims.begin() + 2, dims.end());
          start.assign(dims.size(), 0);
          start[0] = p;
          count = {1};
          count.insert(count.end(), c.shape.begin(), c.shape.end());
        }
        const std::size_t size = static_cast<std::size_t>(element_count(c.shape));
        void* buffer = nullptr;
        switch (c.type) {
          case Type::f64: c.f64.resize(size); buffer = c.f64.data(); break;
          case Type::i32: c.i32.resize(size); buffer = c.i32.data(); break;
          case Type::i64: c.i64.resize(size); buffer = c.i64.data(); break;
          case Type::str: return std::nullopt;
        }
        old_.read_block(path, c.type, start, count, buffer);
        if (!finite(c.f64) || !non_negative({c.i32.begin(), c.i32.end()}) || !non_negative(c.i64))
          return std::nullopt;
        for (const std::string& attribute : old_.attribute_names(path))
          if (old_.attribute_kind(path, attribute) == Store::Attribute::texts)
            c.labels.emplace_back(attribute, old_.texts_attribute(path, attribute));
        if (name == "point") {  // regenerated when written; here only checked
          if (!std::all_of(c.i64.begin(), c.i64.end(),
                           [p](std::int64_t q) { return q == static_cast<std::int64_t>(p); }))
            return std::nullopt;
          continue;
        }
        table.columns.push_back(std::move(c));
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
  std::size_t parameters_ = 0, dof_ = 0;
  std::map<std::string, std::vector<std::int64_t>> rows_;
  std::map<std::string, hsize_t> offset_;
};

}  // namespace

// --- ResultFile --------------------------------------------------------------------------------------

struct ResultFile::Impl {
  /// Held from before the file exists until after it is closed and published or removed.
  std::unique_ptr<detail::OutputLock> lock;
  std::string path, partial;
  std::string file_name;  ///< the open file: `partial`, or while resuming a rebuilt copy of it
  Store store;
  RecordSpec record;
  bool sweep_run = false;
  /// Whether an unfinished file stays on disk: a sweep's, for --resume, once its start is
  /// written; a simulation's never.
  bool keep_unfinished = false;
  std::string status = "running", message;  ///< written to /meta by finish()
  Eigen::Index dof = 0;
  std::vector<std::string> stops;
  bool simulation_written = false;
  bool sweep_begun = false;
  std::size_t completed = 0, total = 0, parameters = 0;
  bool finished = false;
  bool in_memory = false;        ///< create_in_memory(): no file on disk, nothing to rename
  std::vector<char> final_image; ///< in memory: the finished file's bytes (taken by finish())

  Impl(std::unique_ptr<detail::OutputLock> output_lock, std::string final_path, std::string file,
       Store::Mode mode, const Scene& scene)
      : lock(std::move(output_lock)),
        path(std::move(final_path)),
        partial(partial_path(path)),
        file_name(std::move(file)),
        store(file_name, mode),
        record(scene.record),
        sweep_run(scene.run.kind == RunSpec::Kind::sweep),
        dof(scene.dof()),
        stops(stop_names(scene)) {}

  void write_scene(const Scene& scene) const {
    store.create_group("/scene");
    store.set_text("/scene", "yaml", scene.yaml_text);
    store.set_text("/scene", "file", scene.file);
    store.set_text("/scene", "name", scene.name);
    store.set_text("/scene", "run_kind",
                   to_string(scene.run.kind));
    store.set_real("/scene", "period", scene.period());
    for (const auto& [name, value] : scene_numbers(scene)) store.set_real("/scene", name, value);
    for (const Column& c : scene_columns(scene)) {
      require_finite(store.name(), "/scene/" + c.name, c);
      store.write("/scene/" + c.name, c);
    }
  }

  void write_meta(const RunMeta& meta, const Scene& scene) const {
    store.create_group("/meta");
    store.set_text("/meta", "version", meta.version);
    store.set_text("/meta", "git_commit", meta.git_commit);
    store.set_text("/meta", "date", meta.date);
    store.set_text("/meta", "compiler", meta.compiler);
    store.set_integer("/meta", "threads", meta.threads);
    for (const auto& [name, value] : tolerances(scene.solver))
      if (name == "max_events")
        store.set_integer("/meta", name, scene.solver.max_events);
      else
        store.set_real("/meta", name, value);
    store.set_text("/meta", "flow_method", flow_method_name(scene.solver.flow.method));
    store.set_text("/meta", "chatter_rule", to_string(scene.solver.chatter_rule));
    store.set_text("/meta", "engine", to_string(scene.engine));
    store.set_text("/meta", "engine_choice", to_string(scene.engine_choice));
    store.set_text("/meta", "status", "running");
    store.set_text("/meta", "message", "");
    store.set_integer("/meta", "resumed", 0);
  }

  /// The recording must carry exactly the groups the scene records.
  void require_groups(const Recording& rec) const {
    const bool expected[] = {record.events, record.contacts, records_samples(record),
                             record.poincare, record.statistics};
    const bool present[] = {rec.events.has_value(), rec.contacts.has_value(),
                            rec.samples.has_value(), rec.poincare.has_value(),
                            rec.statistics.has_value()};
    for (std::size_t g = 0; g < std::size(kGroups); ++g)
      if (expected[g] != present[g])
        throw std::logic_error(std::string("results: the recording ") +
                               (present[g] ? "has " : "lacks ") + kGroups[g] +
                               " but the scene records " + (expected[g] ? "it" : "no such group") +
                               ": use Recording::for_scene");
  }

  std::vector<Table> checked_tables(const Recording& rec, const std::string& where) const {
    require_groups(rec);
    std::vector<Table> tables = recorded_tables(rec, dof, stops);
    for (const Table& t : tables)
      for (const Column& c : t.columns)
        require_finite(store.name(), "/" + t.group + "/" + c.name, c, where);
    return tables;
  }

  void start_sweep(const std::vector<std::string>& names, std::size_t points) {
    store.create_group("/sweep");
    store.set_texts("/sweep", "parameters", names);
    store.set_integer("/sweep", "points", static_cast<std::int64_t>(points));
    store.set_integer("/sweep", "completed", 0);
    const hsize_t k = names.size(), n = static_cast<hsize_t>(dof), c = count_names().size();
    store.create_extendible("/sweep/values", Type::f64, {0, k}, {256, std::max<hsize_t>(k, 1)});
    store.set_texts("/sweep/values", "parameters", names);
    store.create_extendible("/sweep/status", Type::i32, {0}, {256});
    store.set_texts("/sweep/status", "names",
                    {status_name(RunStatus::completed), status_name(RunStatus::event_cap),
                     status_name(RunStatus::numerical_failure), status_name(RunStatus::unsupported),
                     status_name(RunStatus::interrupted)});
    store.create_extendible("/sweep/counts", Type::i64, {0, c}, {256, c});
    store.set_texts("/sweep/counts", "columns", count_names());
    store.create_extendible("/sweep/t_end", Type::f64, {0}, {256});
    store.create_extendible("/sweep/x_end", Type::f64, {0, n}, {256, std::max<hsize_t>(n, 1)});
    store.create_extendible("/sweep/v_end", Type::f64, {0, n}, {256, std::max<hsize_t>(n, 1)});
    sweep_begun = true;
    total = points;
    parameters = names.size();
  }

  /// Appends one row (of shape row_shape) at index `row` of an extendible dataset, creating it.
  void put_row(const std::string& path, Type type, const Dims& row_shape, hsize_t row,
               const void* data) const {
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

  /// Fixed-size data of point p at [p, 0 … rows, …] of (points × rows × …) datasets.
  void append_stacked(const Table& table, hsize_t p) const {
    const std::string group = "/" + table.group;
    if (!store.exists(group)) {
      store.create_group(group);
      store.set_text(group, "stacking", "stacked");
    }
    for (const Column& c : table.columns) {
      const std::string path = group + "/" + c.name;
      const Dims trailing(c.shape.begin() + 1, c.shape.end());
      if (!store.exists(path)) {
        Dims dims{0, 0};
        dims.insert(dims.end(), trailing.begin(), trailing.end());
        const hsize_t row_size = std::max<hsize_t>(element_count(trailing), 1);
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
      dims[1] = std::max(dims[1], c.shape[0]);
      store.set_extent(path, dims);
      Dims start(dims.size(), 0), count{1};
      start[0] = p;
      count.insert(count.end(), c.shape.begin(), c.shape.end());
      store.write_block(path, c.type, start, count, c.data());
    }
    const std::int64_t rows = static_cast<std::int64_t>(table.rows);
    put_row(group + "/rows", Type::i64, {}, p, &rows);
  }

  /// Ragged data of point p appended to 1-D datasets, with a `point` column.
  void append_ragged(const Table& table, hsize_t p) const {
    const std::string group = "/" + table.group;
    if (!store.exists(group)) {
      store.create_group(group);
      store.set_text(group, "stacking", "concatenated");
    }
    std::vector<Column> columns = table.columns;
    columns.push_back(int64s("point",
                             std::vector<std::int64_t>(table.rows, static_cast<std::int64_t>(p)),
                             {table.rows}));
    const hsize_t before = store.exists(group + "/point") ? store.extent(group + "/point")[0] : 0;
    for (const Column& c : columns) {
      const std::string path = group + "/" + c.name;
      if (!store.exists(path)) {
        store.create_extendible(path, c.type, {before}, {4096});
        for (const auto& [attribute, values] : c.labels) store.set_texts(path, attribute, values);
      }
      store.set_extent(path, {before + table.rows});
      store.write_block(path, c.type, {before}, {table.rows}, c.data());
    }
    const std::int64_t rows = static_cast<std::int64_t>(table.rows);
    put_row(group + "/rows", Type::i64, {}, p, &rows);
  }

  /// Writes point p's data and its rows of /sweep (not yet counted: see commit).
  void write_point(hsize_t p, const PointRecord& point) const {
    for (const Table& table : point.tables)
      table.ragged ? append_ragged(table, p) : append_stacked(table, p);
    const hsize_t n = static_cast<hsize_t>(dof);
    put_row("/sweep/values", Type::f64, {point.values.size()}, p, point.values.data());
    put_row("/sweep/status", Type::i32, {}, p, &point.status);
    put_row("/sweep/counts", Type::i64, {point.counts.size()}, p, point.counts.data());
    put_row("/sweep/t_end", Type::f64, {}, p, &point.t_end);
    put_row("/sweep/x_end", Type::f64, {n}, p, point.x_end.data());
    put_row("/sweep/v_end", Type::f64, {n}, p, point.v_end.data());
  }

  /// Counts the `completed` points, in this order: everything written is flushed, then the
  /// counter is set (in place) and flushed. A kill during the first flush leaves the old count,
  /// during the second either count, and each counted point is whole on disk.
  void commit() const {
    store.flush();
    if (sweep_begun) store.set_integer("/sweep", "completed", static_cast<std::int64_t>(completed));
    store.flush();
  }
};

ResultFile::ResultFile(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ResultFile::ResultFile(ResultFile&&) noexcept = default;
ResultFile& ResultFile::operator=(ResultFile&&) noexcept = default;

ResultFile::~ResultFile() {
  if (!impl_ || impl_->finished) return;
  try {
    impl_->store.close();
  } catch (...) {
    // Nothing better to do in a destructor; the file is abandoned either way.
  }
  if (!impl_->keep_unfinished && !impl_->in_memory) std::remove(impl_->file_name.c_str());
}

ResultFile ResultFile::create(const std::string& path, const Scene& scene, const RunMeta& meta, bool overwrite) {
  const std::string partial = partial_path(path);
  auto lock = std::make_unique<detail::OutputLock>(path, scene.file, overwrite);
  lock->discard_stale_partial(scene.run.kind == RunSpec::Kind::sweep);
  ResultFile file(std::make_unique<Impl>(std::move(lock), path, partial, Store::Mode::create, scene));
  Impl& f = *file.impl_;  // from here on, a failure removes the new file
  f.write_scene(scene);
  f.write_meta(meta, scene);
  f.commit();
  f.keep_unfinished = f.sweep_run;
  return file;
}

ResultFile ResultFile::create_in_memory(const Scene& scene, const RunMeta& meta) {
  const std::string name = Store::memory_name("memory");
  ResultFile file(std::make_unique<Impl>(nullptr, name, name, Store::Mode::memory, scene));
  Impl& f = *file.impl_;
  f.in_memory = true;
  f.write_scene(scene);
  f.write_meta(meta, scene);
  f.commit();
  return file;
}

std::vector<char> ResultFile::image() const {
  return impl_->finished ? impl_->final_image : impl_->store.image();
}

ResultFile ResultFile::open_partial(const std::string& path, const Scene& scene, bool overwrite) {
  const std::string partial = partial_path(path);
  if (scene.run.kind != RunSpec::Kind::sweep)
    throw ResultError(partial + ": only a sweep can be resumed (this scene's run.kind is simulate)");
  auto lock = std::make_unique<detail::OutputLock>(path, scene.file, overwrite);
  if (!std::filesystem::exists(partial))
    throw ResultError(partial + ": no interrupted run to resume (file not found)");
  Store old(partial, Store::Mode::read);
  require_same_scene(old, scene);

  // The finished points are copied into a new file that then replaces the old one: nothing a
  // kill may have left half-flushed in the old file is carried over, and until the rename the
  // old file is untouched (a failure here removes only the copy).
  const std::string rebuilt = partial + ".resume";
  detail::OutputLock::remove_if_present(rebuilt);  // a killed resume's scratch copy (we hold the lock)
  ResultFile file(std::make_unique<Impl>(std::move(lock), path, rebuilt, Store::Mode::create, scene));
  Impl& f = *file.impl_;
  f.write_scene(scene);
  f.store.create_group("/meta");
  copy_attributes(old, f.store, "/meta");
  f.store.set_integer("/meta", "resumed", old.integer_attribute("/meta", "resumed") + 1);
  if (old.exists("/sweep")) {
    const std::vector<std::string> names = old.texts_attribute("/sweep", "parameters");
    f.start_sweep(names, static_cast<std::size_t>(old.integer_attribute("/sweep", "points")));
    const auto counted = static_cast<std::size_t>(old.integer_attribute("/sweep", "completed"));
    CompletedPoints points(old, recorded_groups(f.record), counted);
    for (std::size_t p = 0; p < points.readable(); ++p) {
      const std::optional<PointRecord> point = points.read(p);
      if (!point) break;
      f.write_point(p, *point);
      f.completed = p + 1;
    }
  }
  f.commit();
  f.store.close();
  old.close();
  if (std::rename(rebuilt.c_str(), partial.c_str()) != 0)
    throw ResultError(rebuilt + ": cannot rename to " + partial + ": " + std::strerror(errno));
  f.file_name = partial;
  f.keep_unfinished = true;  // whatever happens now, the finished points stay
  f.store = Store(partial, Store::Mode::write);
  return file;
}

void ResultFile::write_simulation(const Recording& recording) {
  Impl& f = *impl_;
  if (f.sweep_run) throw std::logic_error("results: write_simulation on a sweep (use append_point)");
  if (f.simulation_written) throw std::logic_error("results: write_simulation called twice");
  const std::vector<Table> tables = f.checked_tables(recording, "");
  for (const Table& table : tables) {
    f.store.create_group("/" + table.group);
    for (const Column& c : table.columns) f.store.write("/" + table.group + "/" + c.name, c);
  }
  const RunSummary& s = recording.summary;
  const std::vector<std::int64_t> values = counts(s);
  for (std::size_t k = 0; k < values.size(); ++k)
    f.store.set_integer("/meta", count_names()[k], values[k]);
  f.store.set_real("/meta", "t_reached", s.t);
  f.store.set_texts("/meta", "warnings", s.warnings);
  f.store.flush();
  f.status = status_name(s.status);
  f.message = s.message;
  f.simulation_written = true;
}

void ResultFile::write_group(const std::string& group, const std::vector<Dataset>& datasets,
                             const std::vector<std::pair<std::string, std::string>>& attributes) {
  Impl& f = *impl_;
  if (f.sweep_run) throw std::logic_error("results: write_group on a sweep");
  const std::string path = "/" + group;
  std::vector<Column> columns;
  for (const Dataset& d : datasets) {
    const Dims shape(d.shape.begin(), d.shape.end());
    Column c = d.integer ? int64s(d.name, d.integers, shape) : reals(d.name, d.reals, shape);
    c.labels = d.labels;
    require_finite(f.store.name(), path + "/" + d.name, c, "");
    columns.push_back(std::move(c));
  }
  f.store.create_group(path);
  for (const Column& c : columns) f.store.write(path + "/" + c.name, c);
  for (const auto& [name, text] : attributes) f.store.set_text(path, name, text);
  f.store.flush();
}

void ResultFile::set_outcome(const std::string& status, const std::string& message,
                             const std::vector<std::pair<std::string, std::int64_t>>& counts) {
  Impl& f = *impl_;
  f.status = status;
  f.message = message;
  for (const auto& [name, value] : counts) f.store.set_integer("/meta", name, value);
  f.simulation_written = true;  // finish() may now complete the file
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
  PointRecord point;
  point.tables = f.checked_tables(recording, where);
  point.values = values;
  point.status = static_cast<std::int32_t>(s.status);
  point.counts = counts(s);
  point.t_end = s.t;
  point.x_end.assign(s.x.data(), s.x.data() + s.x.size());
  point.v_end.assign(s.v.data(), s.v.data() + s.v.size());
  const Column checks[] = {reals("values", point.values, {values.size()}),
                           reals("t_end", {s.t}, {1}), vector_column("x_end", s.x),
                           vector_column("v_end", s.v)};
  for (const Column& c : checks) require_finite(f.store.name(), "/sweep/" + c.name, c, where);

  f.write_point(static_cast<hsize_t>(index), point);
  f.completed = index + 1;
  f.commit();
}

std::size_t ResultFile::completed_points() const { return impl_->completed; }
std::size_t ResultFile::total_points() const { return impl_->total; }
const std::string& ResultFile::path() const { return impl_->path; }

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

void ResultFile::finish(const RunMeta& meta) {
  Impl& f = *impl_;
  if (f.finished) throw std::logic_error("results: finish called twice");
  if (f.sweep_run) {
    if (!f.sweep_begun || f.completed != f.total)
      throw std::logic_error("results: finish: the sweep has " + std::to_string(f.completed) +
                             " of " + std::to_string(f.total) + " points");
    const std::vector<std::int64_t> all = f.store.read_integers("/sweep/counts");
    const std::size_t columns = count_names().size();
    for (std::size_t k = 0; k < columns; ++k) {
      std::int64_t sum = 0;
      for (std::size_t i = k; i < all.size(); i += columns) sum += all[i];
      f.store.set_integer("/meta", count_names()[k], sum);
    }
    const std::vector<std::int64_t> status = f.store.read_integers("/sweep/status");
    const auto early = std::count_if(status.begin(), status.end(), [](std::int64_t s) { return s != 0; });
    f.status = early == 0 ? "completed" : "points_stopped_early";
    f.message = early == 0 ? std::string()
                           : std::to_string(early) + " of " + std::to_string(f.total) +
                                 " points stopped early (see /sweep/status)";
  } else if (!f.simulation_written) {
    throw std::logic_error("results: finish before write_simulation");
  }
  f.store.set_text("/meta", "status", f.status);
  f.store.set_text("/meta", "message", f.message);
  f.store.set_real("/meta", "wall_time", meta.wall_seconds);
  f.store.set_integer("/meta", "threads", meta.threads);
  f.store.flush();
  if (f.in_memory) f.final_image = f.store.image();
  f.store.close();
  f.finished = true;  // closed: from here on the destructor leaves the file alone
  if (f.in_memory) return;
  try {
    f.lock->publish(f.partial);
  } catch (const ResultError&) {
    if (!f.keep_unfinished) std::remove(f.partial.c_str());  // a sweep's stays, for --resume
    f.lock.reset();
    throw;
  }
  f.lock.reset();  // released and removed: the file is complete
}

// --- ResultReader ----------------------------------------------------------------------------------

struct ResultReader::Impl {
  Store store;
};

ResultReader::ResultReader(const std::string& path)
    : impl_(std::make_unique<Impl>(Impl{Store(path, Store::Mode::read)})) {}
ResultReader::ResultReader(const std::vector<char>& image)
    : impl_(std::make_unique<Impl>(Impl{Store(Store::memory_name("image"), Store::Mode::image, &image)})) {}
ResultReader::ResultReader(ResultReader&&) noexcept = default;
ResultReader& ResultReader::operator=(ResultReader&&) noexcept = default;
ResultReader::~ResultReader() = default;

bool ResultReader::exists(const std::string& object) const { return impl_->store.exists(object); }
bool ResultReader::is_dataset(const std::string& object) const {
  return impl_->store.is_dataset(object);
}
std::vector<std::string> ResultReader::objects() const { return impl_->store.objects(); }

std::vector<std::size_t> ResultReader::shape(const std::string& dataset) const {
  const Dims dims = impl_->store.extent(dataset);
  return {dims.begin(), dims.end()};
}
std::string ResultReader::type(const std::string& dataset) const {
  return impl_->store.type_name(dataset);
}
std::vector<double> ResultReader::read(const std::string& dataset) const {
  return impl_->store.read_reals(dataset);
}
std::vector<std::int64_t> ResultReader::read_integers(const std::string& dataset) const {
  return impl_->store.read_integers(dataset);
}
std::vector<std::string> ResultReader::read_strings(const std::string& dataset) const {
  return impl_->store.read_texts(dataset);
}

Eigen::MatrixXd ResultReader::read_matrix(const std::string& dataset) const {
  const std::vector<std::size_t> dims = shape(dataset);
  const std::vector<double> values = read(dataset);
  const auto rows = static_cast<Eigen::Index>(dims.empty() ? 1 : dims[0]);
  const auto cols = rows == 0 ? Eigen::Index{0} : static_cast<Eigen::Index>(values.size()) / rows;
  Eigen::MatrixXd out(rows, dims.size() == 1 ? 1 : cols);
  for (Eigen::Index i = 0; i < out.rows(); ++i)
    for (Eigen::Index j = 0; j < out.cols(); ++j)
      out(i, j) = values[static_cast<std::size_t>(i * out.cols() + j)];
  return out;
}

std::vector<std::string> ResultReader::attributes(const std::string& object) const {
  return impl_->store.attribute_names(object);
}
bool ResultReader::attribute_is_string(const std::string& object, const std::string& name) const {
  return impl_->store.attribute_is_text(object, name);
}
std::string ResultReader::attribute_type(const std::string& object, const std::string& name) const {
  switch (impl_->store.attribute_kind(object, name)) {
    case Store::Attribute::text: return "str";
    case Store::Attribute::texts: return "str[]";
    case Store::Attribute::integer: return "i64";
    case Store::Attribute::real: break;
  }
  return "f64";
}
std::string ResultReader::attribute_string(const std::string& object, const std::string& name) const {
  return impl_->store.text_attribute(object, name);
}
std::vector<std::string> ResultReader::attribute_strings(const std::string& object,
                                                         const std::string& name) const {
  return impl_->store.texts_attribute(object, name);
}
double ResultReader::attribute_number(const std::string& object, const std::string& name) const {
  const std::vector<double> values = attribute_numbers(object, name);
  if (values.size() != 1)
    throw ResultError(object + ": attribute `" + name + "` is not a single number");
  return values.front();
}
std::vector<double> ResultReader::attribute_numbers(const std::string& object,
                                                    const std::string& name) const {
  return impl_->store.reals_attribute(object, name);
}

}  // namespace vibro::io
