// The one vocabulary of option rules, used by every component's rule table (the driver's
// BatcherOptions and DecoderOptions, the detector's, the tracker's, lidartagd's configuration).
//
// A rule table is a function template visit_...(V& v, Options& o) that lists every setting once,
// with its key, its rule and its unit. A visitor V provides
//   template <class T, class Rule> void field(const char* key, T& value, Rule rule,
//                                             std::string_view unit);
//   template <class E> void choice(const char* key, E& value,
//                                  const std::vector<std::pair<std::string, E>>& names);
//   template <class F> void section(const char* key, F&& body);   // body(V&) for the section
// and, for lidartagd's own table, list(key, vector, prototype, body) and
// optional_section(key, std::optional<T>&, body): body(V&, T&) for a section that may be absent.
// The daemon's YAML reader and printer are such visitors, and so is RuleChecker below, which
// applies the rules to options built in code. A rule returns why a value is bad, or "".
#pragma once

#include <array>
#include <charconv>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace lidartag::rules {

// A number as the shortest text that reads back to it in its own type ("0.5", "0.1" for the
// float 0.1, "1e-06"): plain digits from 1e-4 to 1e16 ("0.0001", "100000"), an exponent outside.
template <class T>
std::string number_text(T v) {
  std::array<char, 48> buf{};
  std::to_chars_result r{};
  if constexpr (std::is_floating_point_v<T>) {
    const T a = v < 0 ? -v : v;
    r = a == 0 || (a >= T(1e-4) && a < T(1e16))
            ? std::to_chars(buf.data(), buf.data() + buf.size(), v, std::chars_format::fixed)
            : std::to_chars(buf.data(), buf.data() + buf.size(), v);
  } else {
    r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  }
  return r.ec == std::errc() ? std::string(buf.data(), r.ptr) : std::string("?");
}

template <class T>
struct IsVector : std::false_type {};
template <class T>
struct IsVector<std::vector<T>> : std::true_type {};

// A value as the text an error quotes: true/false, the string, the number, [a, b] for a list.
template <class T>
std::string value_text(const T& v) {
  if constexpr (std::is_same_v<T, bool>) {
    return v ? "true" : "false";
  } else if constexpr (std::is_same_v<T, std::string>) {
    return v;
  } else if constexpr (std::is_arithmetic_v<T>) {
    return number_text(v);
  } else if constexpr (std::is_enum_v<T>) {
    return std::to_string(static_cast<int>(v));
  } else if constexpr (IsVector<T>::value) {
    std::string text = "[";
    for (size_t i = 0; i < v.size(); ++i) text += (i ? ", " : "") + value_text(v[i]);
    return text + "]";
  } else {
    return "?";
  }
}

struct Any {
  template <class T>
  std::string operator()(const T&) const {
    return {};
  }
};

template <class T>
struct AtLeast {
  using value_type = T;
  T lo;
  std::string operator()(const T& v) const {
    return v >= lo ? std::string() : "must be >= " + number_text(lo);
  }
};
template <class T>
struct Above {
  using value_type = T;
  T lo;
  std::string operator()(const T& v) const {
    return v > lo ? std::string() : "must be > " + number_text(lo);
  }
};
// [lo, hi], [lo, hi), (lo, hi], (lo, hi).
template <class T, bool kLoIn, bool kHiIn>
struct Range {
  using value_type = T;
  T lo, hi;
  std::string operator()(const T& v) const {
    const bool ok = (kLoIn ? v >= lo : v > lo) && (kHiIn ? v <= hi : v < hi);
    return ok ? std::string()
              : std::string("must be in ") + (kLoIn ? "[" : "(") + number_text(lo) + ", " +
                    number_text(hi) + (kHiIn ? "]" : ")");
  }
};

template <class T>
AtLeast<T> at_least(T lo) {
  return {lo};
}
template <class T>
Above<T> above(T lo) {
  return {lo};
}
template <class T>
Range<T, true, true> closed(T lo, T hi) {
  return {lo, hi};
}
template <class T>
Range<T, true, false> half_open(T lo, T hi) {
  return {lo, hi};
}
template <class T>
Range<T, false, true> open_closed(T lo, T hi) {
  return {lo, hi};
}
template <class T>
Range<T, false, false> open(T lo, T hi) {
  return {lo, hi};
}

// A list: at least `min_size` elements, each passing `element`. Called on one element (so that an
// error can name it), the list's size is checked by whoever sees the whole list.
template <class R>
struct Each {
  using value_type = typename R::value_type;
  R element;
  size_t min_size = 1;
  std::string operator()(const value_type& v) const { return element(v); }
};
template <class R>
Each<R> each(R element, size_t min_size = 1) {
  return {element, min_size};
}

// Applies a rule table to options built in code: `fail(key, value_text, reason)` (which throws
// the component's own error) for the first bad value; keys are dotted paths from `path`.
template <class Fail>
class RuleChecker {
 public:
  RuleChecker(std::string path, Fail fail) : path_(std::move(path)), fail_(fail) {}

  template <class T, class Rule = Any>
  void field(const char* key, T& value, Rule rule = {}, std::string_view /*unit*/ = {}) {
    const std::string name = path_ + key;
    if constexpr (IsVector<T>::value && !std::is_invocable_v<Rule, const T&>) {
      if constexpr (requires { rule.min_size; }) {
        if (value.size() < rule.min_size) {
          fail_(name, value_text(value),
                "needs at least " + std::to_string(rule.min_size) +
                    (rule.min_size == 1 ? " element" : " elements"));
        }
      }
      for (size_t i = 0; i < value.size(); ++i) {
        if (std::string reason = rule(value[i]); !reason.empty())
          fail_(name + "[" + std::to_string(i) + "]", value_text(value[i]), reason);
      }
    } else {
      if (std::string reason = rule(value); !reason.empty()) fail_(name, value_text(value), reason);
    }
  }

  template <class E>
  void choice(const char* key, E& value, const std::vector<std::pair<std::string, E>>& names) {
    for (const auto& n : names)
      if (n.second == value) return;
    fail_(path_ + key, value_text(value), "not a known value");
  }

  template <class F>
  void section(const char* key, F&& body) {
    RuleChecker sub(path_ + key + ".", fail_);
    body(sub);
  }

  // A section that may be absent (std::optional; lidartagd's sensors[].sensor_in_body): its rules
  // when present.
  template <class T, class F>
  void optional_section(const char* key, std::optional<T>& value, F&& body) {
    if (!value) return;
    RuleChecker sub(path_ + key + ".", fail_);
    body(sub, *value);
  }

  // A list of option structs, each under KEY[i] (lidartagd's sensors): not empty.
  template <class T, class F>
  void list(const char* key, std::vector<T>& values, const T& /*prototype*/, F&& body) {
    const std::string name = path_ + key;
    if (values.empty()) fail_(name, "[]", "expected a non-empty list");
    for (size_t i = 0; i < values.size(); ++i) {
      RuleChecker sub(name + "[" + std::to_string(i) + "].", fail_);
      body(sub, values[i]);
    }
  }

 private:
  std::string path_;
  Fail fail_;
};

}  // namespace lidartag::rules
