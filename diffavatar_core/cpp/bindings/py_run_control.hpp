// Python side of RunControl: wraps an optional progress callable (called with the GIL
// re-acquired) and an optional CancelToken. Build it while holding the GIL, release the GIL
// only around the computation, so the callable is also destroyed under the GIL.
#pragma once
#include <pybind11/pybind11.h>

#include <memory>

#include "common/run_control.hpp"

namespace diffavatar {

inline RunControl make_run_control(const pybind11::object& progress,
                                   const std::shared_ptr<CancelToken>& cancel) {
  std::function<void(const ProgressEvent&)> cb;
  if (!progress.is_none()) {
    auto fn = std::make_shared<pybind11::object>(progress);
    cb = [fn](const ProgressEvent& ev) {
      pybind11::gil_scoped_acquire gil;
      (*fn)(ev);
    };
  }
  return RunControl(std::move(cb), cancel);
}

}  // namespace diffavatar
