// The heap counter of the virtmech_tests executable, defined in test_allocation.cpp: it
// interposes malloc, calloc, realloc, free and the aligned forms (glibc) and replaces
// operator new / delete, so every heap call of the process is seen, Eigen's and C
// libraries' included. One per executable: a second definition of malloc would not link,
// so every test file of virtmech_tests counts through this one.
#pragma once

#include <utility>

namespace vmtest {

/// Heap calls made while counting.
struct HeapCount {
  long allocations = 0;  //!< blocks handed out: malloc & co., and operator new through them
  long frees = 0;        //!< non-null blocks given back (realloc of a block counts one of each)
  long news = 0;         //!< operator new calls (also counted in allocations)
  long deletes = 0;      //!< non-null operator delete calls (also counted in frees)
};

/// True where the C allocator is interposed (glibc); elsewhere only new / delete count.
bool heap_counter_sees_malloc() noexcept;
/// Zeroes the counts and starts counting (every thread).
void start_heap_count() noexcept;
/// Stops counting; the counts since start_heap_count.
HeapCount stop_heap_count() noexcept;

/// The heap calls f() makes.
template <typename F>
HeapCount heap_count_of(F&& f) {
  start_heap_count();
  std::forward<F>(f)();
  return stop_heap_count();
}

}  // namespace vmtest
