// Bindings: headless rasterizer and shaded renderer (diffavatar_core/render/).
// Inputs arrive validated (float64 / int32, C-contiguous) from the Python layer.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "render/rasterize.hpp"
#include "render/shade.hpp"

namespace py = pybind11;

namespace diffavatar {

namespace {
Camera make_camera(const Vec3& eye, const Vec3& target, const Vec3& up, bool orthographic, double fov_y,
                   double ortho_height, int width, int height, double near) {
  Camera cam;
  cam.eye = eye, cam.target = target, cam.up = up;
  cam.orthographic = orthographic, cam.fov_y = fov_y, cam.ortho_height = ortho_height;
  cam.width = width, cam.height = height, cam.near = near;
  check_camera(cam);
  return cam;
}
}  // namespace

void bind_render(py::module_& m) {
  m.def("rasterize",
        [](const RefX3d& V, const RefX3i& F, const Vec3& eye, const Vec3& target, const Vec3& up, bool orthographic,
           double fov_y, double ortho_height, int width, int height, double near) {
          const Camera cam = make_camera(eye, target, up, orthographic, fov_y, ortho_height, width, height, near);
          RasterResult r;
          {
            py::gil_scoped_release nogil;
            r = rasterize(V, F, cam);
          }
          return py::make_tuple(std::move(r.face), std::move(r.depth), std::move(r.bary));
        },
        py::arg("V").noconvert(), py::arg("F").noconvert(), py::arg("eye"), py::arg("target"), py::arg("up"),
        py::arg("orthographic"), py::arg("fov_y"), py::arg("ortho_height"), py::arg("width"), py::arg("height"),
        py::arg("near"));

  m.def("render_image",
        [](const RefX3d& V, const RefX3i& F, const RefX3d& face_colors, const Vec3& eye, const Vec3& target,
           const Vec3& up, bool orthographic, double fov_y, double ortho_height, int width, int height, double near,
           bool smooth, double ambient, const Vec3& background, int supersample) {
          const Camera cam = make_camera(eye, target, up, orthographic, fov_y, ortho_height, width, height, near);
          ShadingOptions opt;
          opt.smooth = smooth, opt.ambient = ambient, opt.background = background, opt.supersample = supersample;
          ImageRGB8 img;
          {
            py::gil_scoped_release nogil;
            img = render_image(V, F, face_colors, cam, opt);
          }
          return img;
        },
        py::arg("V").noconvert(), py::arg("F").noconvert(), py::arg("face_colors").noconvert(), py::arg("eye"),
        py::arg("target"), py::arg("up"), py::arg("orthographic"), py::arg("fov_y"), py::arg("ortho_height"),
        py::arg("width"), py::arg("height"), py::arg("near"), py::arg("smooth"), py::arg("ambient"),
        py::arg("background"), py::arg("supersample"));
}

}  // namespace diffavatar
