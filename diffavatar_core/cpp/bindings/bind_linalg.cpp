// Bindings: the sparse LDLᵀ factorizations (linalg/) — ours and Eigen's SimplicialLDLT, the
// reference the tests and bench/newton.py compare it with. Matrices: scipy.sparse (CSC; the
// lower triangle is read). Each binding checks the call order and the pattern, so a misuse from
// Python is a ValueError / RuntimeError, not undefined behaviour.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>

#include <Eigen/SparseCholesky>
#include <stdexcept>
#include <string>

#include "linalg/sparsity_pattern.hpp"
#include "linalg/supernodal_ldlt.hpp"

namespace py = pybind11;

namespace diffavatar {

namespace {
using Matrix = Eigen::SparseMatrix<double>;

template <class F>
struct Checked {  // F with the pattern it analysed and whether its last factorization succeeded
  F f;
  SparsityPattern pattern;
  bool factorized = false;
};

template <class F>
void bind_ldlt(py::module_& m, const char* name, const char* doc) {
  using C = Checked<F>;
  py::class_<C>(m, name, doc)
      .def(py::init<>())
      .def("analyze_pattern", [](C& c, Matrix A) {
             if (A.rows() != A.cols()) throw std::invalid_argument("analyze_pattern: A must be square");
             A.makeCompressed();
             c.f.analyzePattern(A);
             c.pattern.assign(A);
             c.factorized = false;
           }, py::arg("A"), py::call_guard<py::gil_scoped_release>())
      .def("factorize", [](C& c, Matrix A) {
             A.makeCompressed();
             if (A.rows() != A.cols() || !c.pattern.matches(A))
               throw std::invalid_argument("factorize: A is not the pattern analyze_pattern saw (analyze it first)");
             c.f.factorize(A);
             c.factorized = c.f.info() == Eigen::Success;
           }, py::arg("A"), py::call_guard<py::gil_scoped_release>(), "Numeric factorization of A (the analysed pattern).")
      .def_property_readonly("ok", [](const C& c) { return c.factorized; },
                             "Whether the last factorize() succeeded (False after a zero pivot).")
      .def("solve", [](const C& c, const Eigen::VectorXd& b) -> Eigen::VectorXd {
             if (!c.factorized) throw std::runtime_error("solve: no successful factorization (zero pivot, or none yet)");
             if (b.size() != c.pattern.cols())
               throw std::invalid_argument("solve: b has " + std::to_string(b.size()) + " entries, the matrix " +
                                           std::to_string(c.pattern.cols()) + " rows");
             return Eigen::VectorXd(c.f.solve(b));
           }, py::arg("b"), py::call_guard<py::gil_scoped_release>());
}
}  // namespace

void bind_linalg(py::module_& m) {
  bind_ldlt<SupernodalLdlt>(m, "SupernodalLdlt",
                            "LDLᵀ (no pivoting, AMD order) by supernodes: the Newton refinement's solve.");
  bind_ldlt<Eigen::SimplicialLDLT<Matrix>>(
      m, "SimplicialLdlt", "Eigen's SimplicialLDLT (AMD order): the reference SupernodalLdlt is compared with.");
}

}  // namespace diffavatar
