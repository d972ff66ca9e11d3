#pragma once
// Private to vibro_io: the HDF5 layer of result files. Store is one open HDF5 file (on disk or in
// memory) with the operations the writer and the reader need: groups, datasets written whole
// from a Dataset (result_file.hpp) or extended block by block (sweeps), and attributes. Every
// failure becomes a ResultError naming the file, the object and HDF5's reason. Only this header
// and the units of the result file (result_file.cpp, resume.cpp, result_reader.cpp,
// kinds/simulate_layout.cpp, kinds/sweep_layout.cpp) include HDF5.
#include "vibro/io/result_file.hpp"

#include <hdf5.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace vibro::io::detail {

using Dims = std::vector<hsize_t>;
using Type = Dataset::Type;

/// A dataset whose stored bytes no longer match their checksum (a damaged file). Every extendible
/// dataset (a sweep's, written point by point and kept in `.partial` files) is stored with HDF5's
/// Fletcher32 filter, so damage is found on reading instead of read back as values.
class DamagedData : public ResultError {
 public:
  using ResultError::ResultError;
};

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

hsize_t element_count(const Dims& dims);

/// The HDF5 type stored in the file for `type`, and the native type a Dataset holds its values
/// in (f64: double; i32 and i64: std::int64_t, converted by HDF5 on writing and reading).
hid_t file_type(Type type);
hid_t held_type(Type type);
/// The values of `d` as HDF5 reads them with held_type() (not for strings).
const void* held_values(const Dataset& d);

/// "[2, 1]" for flat index 5 of a 3×2 array.
std::string index_text(std::size_t flat, const std::vector<std::size_t>& shape);

/// Throws ResultError naming the file, the dataset and the entry if a value is not finite
/// (`where`: e.g. " (point 3)").
void require_finite(const std::string& file, const std::string& dataset, const Dataset& d,
                    const std::string& where = "");

/// An open HDF5 file and the name used in messages.
class Store {
 public:
  /// memory: a new file held in memory (HDF5's core driver, nothing on disk; `name` only labels
  /// it and must be unique among open files); image: read-only, from the bytes of a file.
  enum class Mode { create, read, write, memory, image };

  Store(std::string name, Mode mode, const std::vector<char>* image = nullptr);

  /// A unique label for a file held in memory (HDF5 takes two open files of one name for one).
  static std::string memory_name(const char* what);

  /// The bytes of the file as it is now (flushed first): what it would be on disk.
  std::vector<char> image() const;

  const std::string& name() const { return name_; }

  [[noreturn]] void fail(const std::string& object, const std::string& what) const;
  hid_t check_id(hid_t id, const std::string& object, const std::string& what) const;
  void check(herr_t status, const std::string& object, const std::string& what) const;

  void flush() const { check(H5Fflush(file_, H5F_SCOPE_GLOBAL), "/", "cannot flush to disk"); }
  void close() { check(file_.reset(), "/", "cannot close the file"); }

  // Objects.

  /// Whether the group or dataset at `path` exists (every link along the path is checked).
  bool exists(const std::string& path) const;

  Hid open_object(const std::string& path) const;
  Hid open_dataset(const std::string& path) const;
  bool is_dataset(const std::string& path) const;

  void create_group(const std::string& path) const;

  /// Names of the links in a group, in name order.
  std::vector<std::string> children(const std::string& group_path) const;

  /// Every group and dataset below the root, as absolute paths.
  std::vector<std::string> objects() const;

  // Datasets.

  /// A new dataset of exactly c.shape, c.type, written whole (no chunks; empty datasets allowed).
  void write(const std::string& path, const Dataset& c) const;

  /// A new chunked dataset, every dimension extendible, starting at `dims`; missing entries
  /// read as NaN (reals), -1 (integers) or "" (texts).
  void create_extendible(const std::string& path, Type type, const Dims& dims,
                         const Dims& chunk) const;

  Dims extent(const std::string& path) const;

  void set_extent(const std::string& path, const Dims& dims) const;

  /// Writes the block [start, start + count) of an existing dataset from values held the way a
  /// Dataset of `type` holds them (held_type(); texts: an array of `const char*`).
  void write_block(const std::string& path, Type type, const Dims& start, const Dims& count,
                   const void* data) const;

  /// Reads the block [start, start + count) of a dataset, converted to how a Dataset of `type`
  /// holds values (held_type()).
  void read_block(const std::string& path, Type type, const Dims& start, const Dims& count,
                  void* out) const;

  Type stored_type(const std::string& path) const;

  template <class T>
  std::vector<T> read_all(const std::string& path, hid_t memory) const;
  std::vector<double> read_reals(const std::string& path) const;
  std::vector<std::int64_t> read_integers(const std::string& path) const;
  std::vector<std::string> read_texts(const std::string& path) const;

  std::string type_name(const std::string& path) const;

  // Attributes.

  enum class Attribute { text, texts, integer, real };
  Attribute attribute_kind(const std::string& object, const std::string& name) const;

  void set_real(const std::string& object, const std::string& name, double value) const;
  void set_integer(const std::string& object, const std::string& name, std::int64_t value) const;
  void set_text(const std::string& object, const std::string& name, const std::string& value) const;
  void set_texts(const std::string& object, const std::string& name,
                 const std::vector<std::string>& values) const;

  std::vector<std::string> attribute_names(const std::string& object) const;
  bool attribute_is_text(const std::string& object, const std::string& name) const;
  std::vector<double> reals_attribute(const std::string& object, const std::string& name) const;
  std::int64_t integer_attribute(const std::string& object, const std::string& name) const;
  std::vector<std::string> texts_attribute(const std::string& object, const std::string& name) const;
  std::string text_attribute(const std::string& object, const std::string& name) const;

 private:
  Hid open_attribute(const std::string& object, const std::string& name) const;

  std::size_t attribute_size(hid_t attribute, const std::string& object,
                             const std::string& name) const;

  /// Sets attribute `name` of `object` (dims empty = scalar): in place when it exists with this
  /// type and shape (one small metadata write: the `completed` counter of a sweep relies on it),
  /// else replaced.
  void put_attribute(const std::string& object, const std::string& name, hid_t ftype, hid_t mtype,
                     const Dims& dims, const void* data) const;

  /// Reads `count` strings stored with `stored` type (variable or fixed length).
  template <class Read>
  std::vector<std::string> read_strings(const std::string& what, hid_t stored, std::size_t count,
                                        Read read) const;

  std::string name_;
  Hid file_;
};

}  // namespace vibro::io::detail
