// Bindings: headless rasterizer.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>

#include "render/rasterize.hpp"

namespace py = pybind11;

namespace diffavatar {

void bind_render(py::module_& m) {
  m.def("rasterize",
        [](const RefX3d& V, const RefX3i& F, const Vec3& eye, const Vec3& target, const Vec3& up, double fov_y,
           int width, int height) {
          Camera cam{eye, target, up, fov_y, width, height};
          py::gil_scoped_release nogil;
          RasterResult r = rasterize(V, F, cam);
          return std::make_pair(std::move(r.face), std::move(r.depth));
        },
        py::arg("V").noconvert(), py::arg("F").noconvert(), py::arg("eye"), py::arg("target"), py::arg("up"),
        py::arg("fov_y"), py::arg("width"), py::arg("height"));
}

}  // namespace diffavatar
