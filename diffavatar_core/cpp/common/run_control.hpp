// Progress reporting and cancellation for long core calls (brief: "long C++ calls release the
// GIL, report progress through a callback, and honour a cancel flag").
#pragma once
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>

namespace diffavatar {

/// Shared cancel flag: any thread may set it; long loops poll it once per iteration/chunk.
class CancelToken {
 public:
  void cancel() { flag_.store(true, std::memory_order_relaxed); }
  void reset() { flag_.store(false, std::memory_order_relaxed); }
  bool cancelled() const { return flag_.load(std::memory_order_relaxed); }

 private:
  std::atomic<bool> flag_{false};
};

/// Thrown by a core call that observed its cancel token; the Python layer maps it to
/// diffavatar_core.Cancelled. Partial results are never returned as if complete.
class Cancelled : public std::runtime_error {
 public:
  explicit Cancelled(const std::string& where) : std::runtime_error("cancelled during " + where) {}
};

/// Progress event: `stage` names the phase, `done`/`total` count its units (steps, samples...),
/// `value` carries a stage-specific scalar (e.g. the residual), NaN when none.
struct ProgressEvent {
  std::string stage;
  long done = 0;
  long total = 0;
  double value = 0.0;
};

/// What a long call receives: an optional progress callback (called from the calling thread,
/// at most every `min_interval_s` seconds, plus once at the end) and an optional cancel token.
class RunControl {
 public:
  RunControl() = default;
  RunControl(std::function<void(const ProgressEvent&)> cb, std::shared_ptr<CancelToken> token,
             double min_interval_s = 0.05)
      : callback_(std::move(cb)), token_(std::move(token)), min_interval_s_(min_interval_s) {}

  bool cancelled() const { return token_ && token_->cancelled(); }
  /// Throws Cancelled when the token is set; call once per iteration.
  void check(const std::string& where) const {
    if (cancelled()) throw Cancelled(where);
  }
  /// Reports progress; rate-limited unless `force`.
  void report(const ProgressEvent& ev, bool force = false) {
    if (!callback_) return;
    auto now = std::chrono::steady_clock::now();
    if (!force && last_ && std::chrono::duration<double>(now - *last_).count() < min_interval_s_) return;
    last_ = std::make_shared<std::chrono::steady_clock::time_point>(now);
    callback_(ev);
  }

 private:
  std::function<void(const ProgressEvent&)> callback_;
  std::shared_ptr<CancelToken> token_;
  double min_interval_s_ = 0.05;
  std::shared_ptr<std::chrono::steady_clock::time_point> last_;
};

}  // namespace diffavatar
