// Bindings: control-cage handles and mean value coordinates (paper §4.2.2).
// Inputs arrive validated (float64, C-contiguous) from diffavatar_core/pattern/cage.py.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>

#include "pattern/mean_value_coordinates.hpp"

namespace py = pybind11;

namespace diffavatar {

void bind_pattern(py::module_& m) {
  m.def("cage_handles", &cage_handles, py::arg("loop").noconvert(), py::arg("angle_threshold_deg"),
        py::call_guard<py::gil_scoped_release>());
  m.def("mean_value_coordinates", &mean_value_coordinates, py::arg("cage").noconvert(),
        py::arg("points").noconvert(), py::call_guard<py::gil_scoped_release>());
}

}  // namespace diffavatar
