// The number of fields of an aggregate (an options struct): the largest N for which
// T{x1, ..., xN} compiles. Tests compare it with what a rule table lists, so that a field added
// to a struct without a rule fails a test.
#pragma once

#include <cstddef>

namespace lidartag::test {

struct AnyField {
  template <class T>
  operator T() const;  // NOLINT: only used in unevaluated contexts
};

template <class T, class... A>
constexpr size_t field_count() {
  if constexpr (requires { T{A{}..., AnyField{}}; }) {
    return field_count<T, A..., AnyField>();
  } else {
    return sizeof...(A);
  }
}

}  // namespace lidartag::test
