// Non-temporal (streaming) stores for data written once and read back only after far more has
// been written than any cache holds — the trajectory adjoint's projection records (~100 MB per
// step of a 10k-vertex garment). An ordinary store first reads the cache line it writes (read
// for ownership) and then evicts it unused; a streaming store writes the line without reading
// it. Values are stored bit for bit (doubles moved as 64-bit integers). Stores made this way are
// weakly ordered: the writing thread calls stream_fence() before another thread may read them.
#pragma once
#include <cstdint>
#include <cstring>

#if defined(__x86_64__) || defined(_M_X64)
#include <emmintrin.h>
#define DIFFAVATAR_STREAM_STORES 1
#endif

namespace diffavatar {

inline void stream_store(double* dst, const double* src, int n) {
#ifdef DIFFAVATAR_STREAM_STORES
  for (int i = 0; i < n; ++i) {
    long long bits;
    std::memcpy(&bits, src + i, sizeof bits);
    _mm_stream_si64(reinterpret_cast<long long*>(dst + i), bits);
  }
#else
  std::memcpy(dst, src, sizeof(double) * static_cast<std::size_t>(n));
#endif
}

/// Orders this thread's streaming stores before its later stores (call before a barrier that
/// hands the records to other threads).
inline void stream_fence() {
#ifdef DIFFAVATAR_STREAM_STORES
  _mm_sfence();
#endif
}

}  // namespace diffavatar
