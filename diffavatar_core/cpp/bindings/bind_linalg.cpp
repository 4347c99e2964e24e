// Bindings: the sparse LDLᵀ factorizations (linalg/) — ours and Eigen's SimplicialLDLT, the
// reference the tests and bench/newton.py compare it with. Matrices: scipy.sparse (CSC; the
// lower triangle is read).
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>

#include <Eigen/SparseCholesky>
#include <stdexcept>

#include "linalg/supernodal_ldlt.hpp"

namespace py = pybind11;

namespace diffavatar {

namespace {
template <class F>
void bind_ldlt(py::module_& m, const char* name, const char* doc) {
  using Matrix = Eigen::SparseMatrix<double>;
  py::class_<F>(m, name, doc)
      .def(py::init<>())
      .def("analyze_pattern", [](F& f, const Matrix& A) { f.analyzePattern(A); }, py::arg("A"),
           py::call_guard<py::gil_scoped_release>())
      .def("factorize", [](F& f, const Matrix& A) { f.factorize(A); }, py::arg("A"),
           py::call_guard<py::gil_scoped_release>(), "Numeric factorization of A (the analysed pattern).")
      .def_property_readonly("ok", [](const F& f) { return f.info() == Eigen::Success; },
                             "False after a zero pivot.")
      .def("solve", [](const F& f, const Eigen::VectorXd& b) -> Eigen::VectorXd {
             if (f.info() != Eigen::Success) throw std::runtime_error("solve: the factorization failed (zero pivot)");
             return f.solve(b);
           }, py::arg("b"), py::call_guard<py::gil_scoped_release>());
}
}  // namespace

void bind_linalg(py::module_& m) {
  bind_ldlt<SupernodalLdlt>(m, "SupernodalLdlt",
                            "LDLᵀ (no pivoting, AMD order) by supernodes: the Newton refinement's solve.");
  bind_ldlt<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>(
      m, "SimplicialLdlt", "Eigen's SimplicialLDLT (AMD order): the reference SupernodalLdlt is compared with.");
}

}  // namespace diffavatar
