// ResultReader (result_file.hpp): read access to a result file, or any HDF5 file, on disk or
// from its bytes, for tests, tools and the Python module.
#include "hdf5_file.hpp"

#include "vibro/io/result_file.hpp"

namespace vibro::io {

struct ResultReader::Impl {
  detail::Store store;
};

ResultReader::ResultReader(const std::string& path)
    : impl_(std::make_unique<Impl>(Impl{detail::Store(path, detail::Store::Mode::read)})) {}
ResultReader::ResultReader(const std::vector<char>& image)
    : impl_(std::make_unique<Impl>(Impl{detail::Store(detail::Store::memory_name("image"), detail::Store::Mode::image, &image)})) {}
ResultReader::ResultReader(ResultReader&&) noexcept = default;
ResultReader& ResultReader::operator=(ResultReader&&) noexcept = default;
ResultReader::~ResultReader() = default;

bool ResultReader::exists(const std::string& object) const { return impl_->store.exists(object); }
bool ResultReader::is_dataset(const std::string& object) const {
  return impl_->store.is_dataset(object);
}
std::vector<std::string> ResultReader::objects() const { return impl_->store.objects(); }

std::vector<std::size_t> ResultReader::shape(const std::string& dataset) const {
  const detail::Dims dims = impl_->store.extent(dataset);
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
    case detail::Store::Attribute::text: return "str";
    case detail::Store::Attribute::texts: return "str[]";
    case detail::Store::Attribute::integer: return "i64";
    case detail::Store::Attribute::real: break;
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
