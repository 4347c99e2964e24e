// Bindings: cancel token, progress event, Cancelled exception.
#include <pybind11/pybind11.h>

#include "common/run_control.hpp"

namespace py = pybind11;

namespace diffavatar {

void bind_common(py::module_& m) {
  py::class_<CancelToken, std::shared_ptr<CancelToken>>(m, "CancelToken",
      "Thread-safe cancel flag polled by long core calls once per iteration.")
      .def(py::init<>())
      .def("cancel", &CancelToken::cancel)
      .def("reset", &CancelToken::reset)
      .def_property_readonly("cancelled", &CancelToken::cancelled);

  py::class_<ProgressEvent>(m, "ProgressEvent", "Progress of a long core call.")
      .def_readonly("stage", &ProgressEvent::stage)
      .def_readonly("done", &ProgressEvent::done)
      .def_readonly("total", &ProgressEvent::total)
      .def_readonly("value", &ProgressEvent::value)
      .def("__repr__", [](const ProgressEvent& e) {
        return "<ProgressEvent " + e.stage + " " + std::to_string(e.done) + "/" + std::to_string(e.total) + ">";
      });

  py::register_exception<Cancelled>(m, "Cancelled", PyExc_RuntimeError);
}

}  // namespace diffavatar
