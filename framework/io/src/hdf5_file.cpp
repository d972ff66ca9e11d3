// The HDF5 layer of result files (hdf5_file.hpp): HDF5's error reporting turned into
// ResultError, the types a Dataset is stored as, and Store's operations.
#include "hdf5_file.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <numeric>

namespace vibro::io::detail {

namespace {

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

/// Variable-length UTF-8 strings (read by h5py as str).
Hid string_type() {
  Hid type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type, H5T_VARIABLE);
  H5Tset_cset(type, H5T_CSET_UTF8);
  return type;
}

}  // namespace

hid_t held_type(Type type) {
  switch (type) {
    case Type::f64: return H5T_NATIVE_DOUBLE;
    case Type::i32: case Type::i64: return H5T_NATIVE_INT64;
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

const void* held_values(const Dataset& d) {
  switch (d.type) {
    case Type::f64: return d.reals.data();
    case Type::i32: case Type::i64: return d.integers.data();
    case Type::str: break;
  }
  return nullptr;
}

hsize_t element_count(const Dims& dims) {
  return std::accumulate(dims.begin(), dims.end(), hsize_t{1}, std::multiplies<>());
}

std::string index_text(std::size_t flat, const std::vector<std::size_t>& shape) {
  std::vector<std::size_t> index(shape.size());
  for (std::size_t k = shape.size(); k-- > 0;) {
    const std::size_t extent = std::max<std::size_t>(shape[k], 1);
    index[k] = flat % extent;
    flat /= extent;
  }
  std::string out = "[";
  for (std::size_t k = 0; k < index.size(); ++k) out += (k ? ", " : "") + std::to_string(index[k]);
  return out + "]";
}

void require_finite(const std::string& file, const std::string& dataset, const Dataset& d,
                    const std::string& where) {
  for (std::size_t i = 0; i < d.reals.size(); ++i)
    if (!std::isfinite(d.reals[i]))
      throw ResultError(file + ": " + dataset + ": entry " + index_text(i, d.shape) + where +
                        " is " + number_text(d.reals[i]) + ": not written, result values must be finite");
}

// --- Store -----------------------------------------------------------------------------------------

Store::Store(std::string name, Mode mode, const std::vector<char>* image) : name_(std::move(name)) {
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

std::string Store::memory_name(const char* what) {
  static std::atomic<unsigned long> count{0};
  return std::string("<") + what + " " + std::to_string(++count) + ">";
}

std::vector<char> Store::image() const {
  flush();
  const ssize_t size = H5Fget_file_image(file_, nullptr, 0);
  if (size < 0) fail("/", "cannot take the file's image");
  std::vector<char> bytes(static_cast<std::size_t>(size));
  if (size > 0 && H5Fget_file_image(file_, bytes.data(), bytes.size()) != size)
    fail("/", "cannot take the file's image");
  return bytes;
}

void Store::fail(const std::string& object, const std::string& what) const {
  const std::string reason = hdf5_reason();
  // HDF5's Fletcher32 filter says "data error detected by Fletcher32 checksum".
  if (reason.find("checksum") != std::string::npos)
    throw DamagedData(name_ + ": " + object + ": damaged: its stored checksum does not match its bytes (HDF5: " +
                      reason + ")");
  throw ResultError(name_ + ": " + object + ": " + what +
                    (reason.empty() ? "" : " (HDF5: " + reason + ")"));
}

hid_t Store::check_id(hid_t id, const std::string& object, const std::string& what) const {
  if (id < 0) fail(object, what);
  return id;
}

void Store::check(herr_t status, const std::string& object, const std::string& what) const {
  if (status < 0) fail(object, what);
}

bool Store::exists(const std::string& path) const {
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

Hid Store::open_object(const std::string& path) const {
  return Hid(check_id(H5Oopen(file_, path.c_str(), H5P_DEFAULT), path, "cannot open"), H5Oclose);
}

Hid Store::open_dataset(const std::string& path) const {
  return Hid(check_id(H5Dopen2(file_, path.c_str(), H5P_DEFAULT), path, "cannot open the dataset"),
             H5Dclose);
}

bool Store::is_dataset(const std::string& path) const {
  if (!exists(path)) return false;
  Hid object = open_object(path);
  return H5Iget_type(object) == H5I_DATASET;
}

void Store::create_group(const std::string& path) const {
  Hid group(check_id(H5Gcreate2(file_, path.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path,
                     "cannot create the group"),
            H5Gclose);
}

std::vector<std::string> Store::children(const std::string& group_path) const {
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

std::vector<std::string> Store::objects() const {
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

void Store::write(const std::string& path, const Dataset& c) const {
  const Dims shape(c.shape.begin(), c.shape.end());
  Hid space(check_id(H5Screate_simple(static_cast<int>(shape.size()), shape.data(), nullptr),
                     path, "cannot describe its shape"),
            H5Sclose);
  Hid strings = c.type == Type::str ? string_type() : Hid();
  const hid_t ftype = c.type == Type::str ? hid_t(strings) : file_type(c.type);
  const hid_t mtype = c.type == Type::str ? hid_t(strings) : held_type(c.type);
  Hid dataset(check_id(H5Dcreate2(file_, path.c_str(), ftype, space, H5P_DEFAULT, H5P_DEFAULT,
                                  H5P_DEFAULT),
                       path, "cannot create the dataset"),
              H5Dclose);
  if (element_count(shape) > 0) {
    std::vector<const char*> pointers;
    for (const std::string& s : c.texts) pointers.push_back(s.c_str());
    const void* data = c.type == Type::str ? static_cast<const void*>(pointers.data()) : held_values(c);
    check(H5Dwrite(dataset, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), path,
          "cannot write the dataset");
  }
  for (const auto& [attribute, values] : c.labels) set_texts(path, attribute, values);
}

void Store::create_extendible(const std::string& path, Type type, const Dims& dims,
                       const Dims& chunk) const {
  const Dims unlimited(dims.size(), H5S_UNLIMITED);
  Hid space(check_id(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), unlimited.data()),
                     path, "cannot describe its shape"),
            H5Sclose);
  Hid dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  check(H5Pset_chunk(dcpl, static_cast<int>(chunk.size()), chunk.data()), path,
        "cannot set its chunks");
  // A checksum per chunk: a sweep's datasets are what a resume reads back from a `.partial`
  // file, and a damaged byte there must be refused, never carried into the result. (HDF5 filters
  // take no variable-length strings: a sweep's messages go unchecked, its numbers never.)
  if (type != Type::str) check(H5Pset_fletcher32(dcpl), path, "cannot set its checksum");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::int64_t minus_one = -1;
  Hid strings = type == Type::str ? string_type() : Hid();
  if (type == Type::f64)
    check(H5Pset_fill_value(dcpl, H5T_NATIVE_DOUBLE, &nan), path, "cannot set its fill value");
  else if (type != Type::str)  // (variable-length strings are filled with empty ones)
    check(H5Pset_fill_value(dcpl, H5T_NATIVE_INT64, &minus_one), path,
          "cannot set its fill value");
  const hid_t ftype = type == Type::str ? hid_t(strings) : file_type(type);
  Hid dataset(check_id(H5Dcreate2(file_, path.c_str(), ftype, space, H5P_DEFAULT, dcpl,
                                  H5P_DEFAULT),
                       path, "cannot create the dataset"),
              H5Dclose);
}

Dims Store::extent(const std::string& path) const {
  Hid dataset = open_dataset(path);
  Hid space(check_id(H5Dget_space(dataset), path, "cannot read its shape"), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space);
  if (rank < 0) fail(path, "cannot read its rank");
  Dims dims(static_cast<std::size_t>(rank));
  if (rank > 0) check(H5Sget_simple_extent_dims(space, dims.data(), nullptr), path,
                      "cannot read its shape");
  return dims;
}

void Store::set_extent(const std::string& path, const Dims& dims) const {
  Hid dataset = open_dataset(path);
  check(H5Dset_extent(dataset, dims.data()), path, "cannot resize the dataset");
}

void Store::write_block(const std::string& path, Type type, const Dims& start, const Dims& count,
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
  Hid strings = type == Type::str ? string_type() : Hid();
  const hid_t mtype = type == Type::str ? hid_t(strings) : held_type(type);
  check(H5Dwrite(dataset, mtype, memory_space, file_space, H5P_DEFAULT, data), path, "cannot write");
}

void Store::read_block(const std::string& path, Type type, const Dims& start, const Dims& count,
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
  check(H5Dread(dataset, held_type(type), memory_space, file_space, H5P_DEFAULT, out), path,
        "cannot read");
}

Type Store::stored_type(const std::string& path) const {
  const std::string name = type_name(path);
  if (name == "f64") return Type::f64;
  if (name == "i32") return Type::i32;
  if (name == "i64") return Type::i64;
  if (name == "str") return Type::str;
  fail(path, "has a type this file format does not use");
}

template <class T>
std::vector<T> Store::read_all(const std::string& path, hid_t memory) const {
  Hid dataset = open_dataset(path);
  std::vector<T> values(static_cast<std::size_t>(element_count(extent(path))));
  if (!values.empty())
    check(H5Dread(dataset, memory, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), path,
          "cannot read");
  return values;
}

std::vector<double> Store::read_reals(const std::string& path) const {
  return read_all<double>(path, H5T_NATIVE_DOUBLE);
}

std::vector<std::int64_t> Store::read_integers(const std::string& path) const {
  return read_all<std::int64_t>(path, H5T_NATIVE_INT64);
}

std::vector<std::string> Store::read_texts(const std::string& path) const {
  Hid dataset = open_dataset(path);
  Hid type(check_id(H5Dget_type(dataset), path, "cannot read its type"), H5Tclose);
  const auto count = static_cast<std::size_t>(element_count(extent(path)));
  return read_strings(
      path, type, count, [&](hid_t memory, void* buffer) {
        return H5Dread(dataset, memory, H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer);
      });
}

std::string Store::type_name(const std::string& path) const {
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

Store::Attribute Store::attribute_kind(const std::string& object, const std::string& name) const {
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

void Store::set_real(const std::string& object, const std::string& name, double value) const {
  put_attribute(object, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}, &value);
}

void Store::set_integer(const std::string& object, const std::string& name, std::int64_t value) const {
  put_attribute(object, name, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, &value);
}

void Store::set_text(const std::string& object, const std::string& name, const std::string& value) const {
  Hid type = string_type();
  const char* pointer = value.c_str();
  put_attribute(object, name, type, type, {}, &pointer);
}

void Store::set_texts(const std::string& object, const std::string& name,
               const std::vector<std::string>& values) const {
  Hid type = string_type();
  std::vector<const char*> pointers;
  for (const std::string& s : values) pointers.push_back(s.c_str());
  put_attribute(object, name, type, type, {static_cast<hsize_t>(values.size())}, pointers.data());
}

std::vector<std::string> Store::attribute_names(const std::string& object) const {
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

bool Store::attribute_is_text(const std::string& object, const std::string& name) const {
  Hid attribute = open_attribute(object, name);
  Hid type(check_id(H5Aget_type(attribute), object, "cannot read attribute `" + name + "`"),
           H5Tclose);
  return H5Tget_class(type) == H5T_STRING;
}

std::vector<double> Store::reals_attribute(const std::string& object, const std::string& name) const {
  Hid attribute = open_attribute(object, name);
  std::vector<double> values(attribute_size(attribute, object, name));
  if (!values.empty())
    check(H5Aread(attribute, H5T_NATIVE_DOUBLE, values.data()), object,
          "cannot read attribute `" + name + "` as numbers");
  return values;
}

std::int64_t Store::integer_attribute(const std::string& object, const std::string& name) const {
  Hid attribute = open_attribute(object, name);
  if (attribute_size(attribute, object, name) != 1)
    fail(object, "attribute `" + name + "` is not a single number");
  std::int64_t value = 0;
  check(H5Aread(attribute, H5T_NATIVE_INT64, &value), object,
        "cannot read attribute `" + name + "` as an integer");
  return value;
}

std::vector<std::string> Store::texts_attribute(const std::string& object, const std::string& name) const {
  Hid attribute = open_attribute(object, name);
  Hid type(check_id(H5Aget_type(attribute), object, "cannot read attribute `" + name + "`"),
           H5Tclose);
  return read_strings(object + " attribute `" + name + "`", type,
                      attribute_size(attribute, object, name),
                      [&](hid_t memory, void* buffer) { return H5Aread(attribute, memory, buffer); });
}

std::string Store::text_attribute(const std::string& object, const std::string& name) const {
  const std::vector<std::string> values = texts_attribute(object, name);
  if (values.size() != 1) fail(object, "attribute `" + name + "` is not a single string");
  return values.front();
}

Hid Store::open_attribute(const std::string& object, const std::string& name) const {
  Hid handle = open_object(object);
  return Hid(check_id(H5Aopen(handle, name.c_str(), H5P_DEFAULT), object,
                      "cannot open attribute `" + name + "`"),
             H5Aclose);
}

std::size_t Store::attribute_size(hid_t attribute, const std::string& object,
                           const std::string& name) const {
  Hid space(check_id(H5Aget_space(attribute), object, "cannot read attribute `" + name + "`"),
            H5Sclose);
  const hssize_t n = H5Sget_simple_extent_npoints(space);
  if (n < 0) fail(object, "cannot read the size of attribute `" + name + "`");
  return static_cast<std::size_t>(n);
}

void Store::put_attribute(const std::string& object, const std::string& name, hid_t ftype, hid_t mtype,
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

template <class Read>
std::vector<std::string> Store::read_strings(const std::string& what, hid_t stored, std::size_t count,
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

}  // namespace vibro::io::detail
