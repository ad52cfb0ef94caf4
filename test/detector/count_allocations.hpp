// The test program's heap allocations, counted by the operator new of count_allocations.cpp:
// add that file to the SOURCES of a test that checks a path does not allocate in steady state.
#pragma once

namespace lidartag::testing {

// operator new calls since the program started.
long heap_allocations();

// The allocation after the next `n` ones throws std::bad_alloc (once); -1 cancels.
void fail_allocation_after(long n);

}  // namespace lidartag::testing
