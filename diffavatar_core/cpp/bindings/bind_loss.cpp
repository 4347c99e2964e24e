// Bindings: scan-matching loss terms (paper §4.2.5).
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>

#include <memory>

#include "bindings/py_run_control.hpp"
#include "loss/chamfer_loss.hpp"

namespace py = pybind11;

namespace diffavatar {

void bind_loss(py::module_& m) {
  py::class_<ChamferLossResult>(m, "ChamferLossResult")
      .def_readonly("value", &ChamferLossResult::value)
      .def_readonly("garment_to_scan", &ChamferLossResult::garment_to_scan)
      .def_readonly("scan_to_garment", &ChamferLossResult::scan_to_garment)
      .def_readonly("garment_trimmed", &ChamferLossResult::garment_trimmed)
      .def_readonly("scan_trimmed", &ChamferLossResult::scan_trimmed)
      .def_readonly("grad", &ChamferLossResult::grad);

  m.def("chamfer_loss",
        [](const RefX3d& X, const RefX3i& F, const VecXi& tri, const RowMatX3d& bary, const RefX3d& scan,
           double trim_distance, const py::object& progress, std::shared_ptr<CancelToken> cancel,
           const RowMatX3d& surface_V, const RowMatX3i& surface_F) {
          RunControl rc = make_run_control(progress, cancel);
          SurfaceSamples s{tri, bary};
          py::gil_scoped_release nogil;
          std::unique_ptr<TriangleMeshBvh> surface;   // none when surface_F is empty
          if (surface_F.rows() > 0) surface = std::make_unique<TriangleMeshBvh>(surface_V, surface_F);
          return chamfer_loss(X, F, s, scan, trim_distance, rc, surface.get());
        },
        py::arg("X").noconvert(), py::arg("F").noconvert(), py::arg("tri"), py::arg("bary"),
        py::arg("scan").noconvert(), py::arg("trim_distance"), py::arg("progress") = py::none(),
        py::arg("cancel") = nullptr, py::arg("surface_V") = RowMatX3d(0, 3), py::arg("surface_F") = RowMatX3i(0, 3));
}

}  // namespace diffavatar
