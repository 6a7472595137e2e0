// ropes._core: the dataset container (ropes_core/dataset.hpp) for Python. The pure-Python
// module ropes.dataset (python/ropes/dataset.py) is what users import.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "ropes_core/dataset.hpp"
#include "ropes_core/python.hpp"

namespace py = pybind11;
namespace core = ropes::core;
namespace rp = ropes::python;

namespace {

core::DType dtype_of(const std::string& column, const py::dtype& dtype) {
  // numpy's dtype.str names the byte order too: "<f4" (the file's order), never ">f4"
  const std::string str = py::str(dtype.attr("str"));
  const std::pair<const char*, core::DType> known[] = {{"|u1", core::DType::kU8},
                                                       {"<i4", core::DType::kI32},
                                                       {"<i8", core::DType::kI64},
                                                       {"<f4", core::DType::kF32},
                                                       {"<f8", core::DType::kF64}};
  for (const auto& [name, d] : known) {
    if (str == name)
      return d;
  }
  throw rp::ShapeError("column '" + column + "': dtype " +
                       std::string(py::str(dtype.attr("name"))) + " ('" + str +
                       "') is not one a dataset stores; expected uint8, int32, int64, float32 "
                       "or float64, little-endian");
}

py::dict column_dict(const core::ColumnSpec& c) {
  py::dict d;
  d["name"] = c.name;
  d["dtype"] = rp::numpy_dtype_name(c.dtype);
  d["row_shape"] = py::tuple(py::cast(c.row_shape));
  return d;
}

// rows [first, first + count) of `column` into a new numpy array, read without the GIL
py::array read_rows(const core::DatasetReader& r, const std::string& column, std::int64_t first,
                    std::int64_t count) {
  const core::ColumnSpec& spec = r.column(column);
  if (count < 0 || first < 0 || first > r.rows() || count > r.rows() - first) {
    throw std::out_of_range("rows [" + std::to_string(first) + ", " +
                            std::to_string(first + count) + ") of column '" + column +
                            "': outside the dataset's " + std::to_string(r.rows()) + " rows");
  }
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(count)};
  shape.insert(shape.end(), spec.row_shape.begin(), spec.row_shape.end());
  py::array out(py::dtype(rp::numpy_dtype_name(spec.dtype)), shape);
  void* data = out.mutable_data();
  {
    py::gil_scoped_release release;
    r.read_rows(column, first, count, data);
  }
  return out;
}

py::array read_rows_at(const core::DatasetReader& r, const std::string& column,
                       const py::handle& rows_obj) {
  const core::ColumnSpec& spec = r.column(column);
  const auto rows = rp::require_array<std::int64_t>(rows_obj, "rows", {-1});
  std::vector<std::int64_t> wanted(rows.data(), rows.data() + rows.size());
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(wanted.size())};
  shape.insert(shape.end(), spec.row_shape.begin(), spec.row_shape.end());
  py::array out(py::dtype(rp::numpy_dtype_name(spec.dtype)), shape);
  void* data = out.mutable_data();
  {
    py::gil_scoped_release release;
    r.read_rows_at(column, wanted, data);
  }
  return out;
}

// a read-only numpy view of the memory-mapped shard file: zero copy
py::array map_shard(const core::DatasetReader& r, const std::string& column, int shard) {
  auto* mapped = new core::DatasetReader::MappedRows(r.map_shard(column, shard));
  py::capsule owner(mapped,
                    [](void* p) { delete static_cast<core::DatasetReader::MappedRows*>(p); });
  const std::vector<py::ssize_t> shape(mapped->shape.begin(), mapped->shape.end());
  py::array a(py::dtype(rp::numpy_dtype_name(mapped->dtype)), shape, mapped->data, owner);
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

// the columns and arrays of one shard, checked: the columns' specs come from the arrays
void write_shard(const std::string& dir, int shard, const std::vector<std::string>& names,
                 const std::vector<py::array>& arrays, const std::string& dataset_id) {
  if (names.size() != arrays.size()) {
    throw std::invalid_argument("write_shard: " + std::to_string(names.size()) + " names for " +
                                std::to_string(arrays.size()) + " arrays");
  }
  std::vector<core::ColumnSpec> columns;
  std::vector<core::NpyArray> data;
  for (std::size_t i = 0; i < names.size(); ++i) {
    const py::array a = py::array::ensure(arrays[i], py::array::c_style);
    if (a.ndim() < 1) {
      throw rp::ShapeError("column '" + names[i] +
                           "': expected an array with one row per sample (at least 1 "
                           "dimension), got " +
                           rp::describe_array(arrays[i]));
    }
    core::ColumnSpec c;
    c.name = names[i];
    c.dtype = dtype_of(names[i], a.dtype());
    core::NpyArray n;
    n.dtype = c.dtype;
    for (py::ssize_t d = 0; d < a.ndim(); ++d) {
      n.shape.push_back(a.shape(d));
      if (d > 0)
        c.row_shape.push_back(a.shape(d));
    }
    const auto* bytes = static_cast<const std::uint8_t*>(a.data());
    n.data.assign(bytes, bytes + a.nbytes());
    columns.push_back(std::move(c));
    data.push_back(std::move(n));
  }
  py::gil_scoped_release release;
  core::write_dataset_shard(dir, shard, columns, data, dataset_id);
}

void write_manifest(const std::string& dir, const std::vector<py::dict>& column_dicts,
                    int shard_count, const py::object& metadata, const std::string& dataset_id) {
  std::vector<core::ColumnSpec> columns;
  for (const py::dict& d : column_dicts) {
    core::ColumnSpec c;
    c.name = d["name"].cast<std::string>();
    c.dtype = dtype_of(c.name, py::dtype(d["dtype"].cast<std::string>()));
    c.row_shape = d["row_shape"].cast<std::vector<std::int64_t>>();
    columns.push_back(std::move(c));
  }
  const std::string metadata_json = rp::from_python(metadata).dump();
  py::gil_scoped_release release;
  core::write_dataset_manifest(dir, columns, shard_count, metadata_json, dataset_id);
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "ropes._core: the dataset container (use ropes.dataset)";
  rp::translate_core_exceptions();

  py::class_<core::DatasetReader>(m, "Reader")
      .def_static(
          "open", [](const std::string& dir) { return core::DatasetReader::open(dir); },
          py::arg("dir"))
      .def_property_readonly("dir", [](const core::DatasetReader& r) { return r.dir().string(); })
      .def_property_readonly("rows", &core::DatasetReader::rows)
      .def_property_readonly("shard_count", &core::DatasetReader::shard_count)
      .def_property_readonly("columns",
                             [](const core::DatasetReader& r) {
                               py::list out;
                               for (const core::ColumnSpec& c : r.columns())
                                 out.append(column_dict(c));
                               return out;
                             })
      .def_property_readonly(
          "metadata", [](const core::DatasetReader& r) { return rp::to_python(r.metadata()); })
      .def("shard_rows", &core::DatasetReader::shard_rows, py::arg("shard"))
      .def("read", &read_rows, py::arg("column"), py::arg("first"), py::arg("count"))
      .def("read_at", &read_rows_at, py::arg("column"), py::arg("rows"))
      .def("map_shard", &map_shard, py::arg("column"), py::arg("shard"))
      .def("verify", [](const core::DatasetReader& r) {
        py::gil_scoped_release release;
        r.verify();
      });

  m.def("write_shard", &write_shard, py::arg("dir"), py::arg("shard"), py::arg("names"),
        py::arg("arrays"), py::arg("dataset_id") = "");
  m.def("write_manifest", &write_manifest, py::arg("dir"), py::arg("columns"),
        py::arg("shard_count"), py::arg("metadata"), py::arg("dataset_id") = "");
  m.def(
      "shuffled_indices",
      [](std::int64_t n, std::uint64_t seed, std::uint64_t epoch) {
        std::vector<std::int64_t> v = core::shuffled_indices(n, seed, epoch);
        const auto size = static_cast<py::ssize_t>(v.size());
        return rp::to_numpy(std::move(v), {size});
      },
      py::arg("n"), py::arg("seed"), py::arg("epoch"));
}
