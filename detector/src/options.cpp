// The rules of the detector's options, applied to options built in code (validate_options).
#include "lidartag/detector/options.hpp"

#include <array>
#include <charconv>
#include <type_traits>

#include "lidartag/detector/tag_family.hpp"

namespace lidartag::detector {

namespace {

std::string message(const std::string& key, const std::string& value, const std::string& reason) {
  if (key.empty()) return "detector options: " + reason;
  return "detector options: " + key + ": '" + value + "': " + reason;
}

template <class T>
std::string value_text(const T& v) {
  if constexpr (std::is_same_v<T, bool>) {
    return v ? "true" : "false";
  } else if constexpr (std::is_same_v<T, std::string>) {
    return v;
  } else if constexpr (std::is_arithmetic_v<T>) {
    return rules::number_text(static_cast<double>(v));
  } else if constexpr (std::is_enum_v<T>) {
    return std::to_string(static_cast<int>(v));
  } else {
    std::string text = "[";
    for (size_t i = 0; i < v.size(); ++i) text += (i ? ", " : "") + value_text(v[i]);
    return text + "]";
  }
}

template <class T>
struct IsVector : std::false_type {};
template <class T>
struct IsVector<std::vector<T>> : std::true_type {};

// Applies every rule of visit_options to options built in code.
class Checker {
 public:
  explicit Checker(std::string path) : path_(std::move(path)) {}

  template <class T, class Rule>
  void field(const char* key, T& value, Rule rule, std::string_view /*unit*/) {
    const std::string name = path_ + key;
    if constexpr (IsVector<T>::value) {
      if constexpr (requires { rule.min_size; }) {
        if (value.size() < rule.min_size)
          throw OptionsError(name, value_text(value),
                             "needs at least " + std::to_string(rule.min_size) +
                                 (rule.min_size == 1 ? " element" : " elements"));
      }
      for (size_t i = 0; i < value.size(); ++i)
        if (std::string reason = rule(value[i]); !reason.empty())
          throw OptionsError(name + "[" + std::to_string(i) + "]", value_text(value[i]), reason);
    } else {
      if (std::string reason = rule(value); !reason.empty())
        throw OptionsError(name, value_text(value), reason);
    }
  }

  template <class E>
  void choice(const char* key, E& value, const std::vector<std::pair<std::string, E>>& names) {
    for (const auto& n : names)
      if (n.second == value) return;
    throw OptionsError(path_ + key, value_text(value), "not a known value");
  }

  template <class F>
  void section(const char* key, F&& body) {
    Checker sub(path_ + key + ".");
    body(sub);
  }

 private:
  std::string path_;
};

}  // namespace

OptionsError::OptionsError(std::string key, std::string value, std::string reason)
    : std::invalid_argument(message(key, value, reason)),
      key_(std::move(key)),
      value_(std::move(value)),
      reason_(std::move(reason)) {}

namespace rules {

std::string number_text(double v) {
  std::array<char, 32> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return ec == std::errc() ? std::string(buf.data(), end) : std::string("?");
}

std::string KnownFamily::operator()(const std::string& name) const {
  try {
    (void)tags::resolve_family(name);
    return {};
  } catch (const std::exception& e) {
    return e.what();
  }
}

}  // namespace rules

std::vector<std::pair<std::string, PoseAlgorithm>> pose_algorithm_names() {
  std::vector<std::pair<std::string, PoseAlgorithm>> names;
  for (auto a : {PoseAlgorithm::kMMA, PoseAlgorithm::kCCSAQ, PoseAlgorithm::kSLSQP,
                 PoseAlgorithm::kSBPLX, PoseAlgorithm::kBOBYQA})
    names.emplace_back(std::string(pose_algorithm_name(a)), a);
  return names;
}

void check_option_relations(const DetectorOptions& o) {
  if (!(o.features.max_range_m > o.features.min_range_m))
    throw OptionsError("features.max_range_m", value_text(o.features.max_range_m),
                       "must be above features.min_range_m");
}

void validate_options(const DetectorOptions& options) {
  DetectorOptions copy = options;  // the visitor takes fields by reference
  Checker checker("");
  visit_options(checker, copy);
  check_option_relations(copy);
}

}  // namespace lidartag::detector
