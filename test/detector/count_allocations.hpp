// The test program's heap allocations, counted by the operator new of count_allocations.cpp:
// add that file to the SOURCES of a test that checks a path does not allocate in steady state.
#pragma once

namespace lidartag::testing {

// operator new calls since the program started.
long heap_allocations();

}  // namespace lidartag::testing
