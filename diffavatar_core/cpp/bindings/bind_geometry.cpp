// Bindings: mesh quality, surface sampling, nearest-point and Chamfer distances.
// Inputs arrive validated (float64 / int32, C-contiguous) from diffavatar_core/_validate.py,
// so Eigen::Ref maps them without copies.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>

#include "bindings/py_run_control.hpp"
#include "geometry/chamfer.hpp"
#include "geometry/mesh_quality.hpp"
#include "geometry/surface_sampling.hpp"

namespace py = pybind11;

namespace diffavatar {

void bind_geometry(py::module_& m) {
  m.def("triangle_quality", &triangle_quality, py::arg("V").noconvert(), py::arg("F").noconvert(),
        py::call_guard<py::gil_scoped_release>());

  m.def("sample_surface",
        [](const RefX3d& V, const RefX3i& F, int n, uint64_t seed) {
          py::gil_scoped_release nogil;
          VecXi tri;
          RowMatX3d P = sample_surface(V, F, n, seed, &tri);
          return std::make_pair(P, tri);
        },
        py::arg("V").noconvert(), py::arg("F").noconvert(), py::arg("n"), py::arg("seed"));

  m.def("nearest_point_distances",
        [](const RefX3d& A, const RefX3d& B, const py::object& progress, std::shared_ptr<CancelToken> cancel) {
          RunControl rc = make_run_control(progress, cancel);
          py::gil_scoped_release nogil;
          return nearest_point_distances(A, B, rc);
        },
        py::arg("A").noconvert(), py::arg("B").noconvert(), py::arg("progress") = py::none(),
        py::arg("cancel") = nullptr);

  m.def("surface_distances",
        [](const RefX3d& P, const RefX3d& V, const RefX3i& F, const py::object& progress,
           std::shared_ptr<CancelToken> cancel) {
          RunControl rc = make_run_control(progress, cancel);
          py::gil_scoped_release nogil;
          return surface_distances(P, V, F, rc);
        },
        py::arg("P").noconvert(), py::arg("V").noconvert(), py::arg("F").noconvert(),
        py::arg("progress") = py::none(), py::arg("cancel") = nullptr);

  m.def("chamfer_points",
        [](const RefX3d& A, const RefX3d& B, const py::object& progress, std::shared_ptr<CancelToken> cancel) {
          RunControl rc = make_run_control(progress, cancel);
          py::gil_scoped_release nogil;
          return chamfer_points(A, B, rc);
        },
        py::arg("A").noconvert(), py::arg("B").noconvert(), py::arg("progress") = py::none(),
        py::arg("cancel") = nullptr);

  m.def("chamfer_meshes",
        [](const RefX3d& VA, const RefX3i& FA, const RefX3d& VB, const RefX3i& FB, int samples, uint64_t seed,
           const py::object& progress, std::shared_ptr<CancelToken> cancel) {
          RunControl rc = make_run_control(progress, cancel);
          py::gil_scoped_release nogil;
          return chamfer_meshes(VA, FA, VB, FB, samples, seed, rc);
        },
        py::arg("VA").noconvert(), py::arg("FA").noconvert(), py::arg("VB").noconvert(), py::arg("FB").noconvert(),
        py::arg("samples"), py::arg("seed"), py::arg("progress") = py::none(), py::arg("cancel") = nullptr);
}

}  // namespace diffavatar
