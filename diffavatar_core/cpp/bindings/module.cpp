// The compiled module only wires bindings, one bind_<area>.cpp per area (style note 8).
#include <pybind11/pybind11.h>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace py = pybind11;

namespace diffavatar {
void bind_common(py::module_& m);
void bind_geometry(py::module_& m);
void bind_linalg(py::module_& m);
void bind_loss(py::module_& m);
void bind_sim(py::module_& m);
void bind_render(py::module_& m);
void bind_pattern(py::module_& m);
void bind_body(py::module_& m);
}  // namespace diffavatar

PYBIND11_MODULE(_core, m) {
  m.doc() = "DiffAvatar C++ core (C++17, Eigen, OpenMP). Use it through diffavatar_core.";
  diffavatar::bind_common(m);
  diffavatar::bind_geometry(m);
  diffavatar::bind_linalg(m);
  diffavatar::bind_loss(m);
  diffavatar::bind_sim(m);
  diffavatar::bind_render(m);
  diffavatar::bind_pattern(m);
  diffavatar::bind_body(m);
  m.def("openmp_max_threads", []() {
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
  });
  m.def("set_num_threads", [](int n) {
#ifdef _OPENMP
    omp_set_num_threads(n);
#endif
  }, py::arg("n"), "Sets the OpenMP thread count used by the core (0 < n).");
}
