// The rules of the detector's options, applied to options built in code (validate_options).
#include "lidartag/detector/options.hpp"

#include "lidartag/detector/tag_family.hpp"

namespace lidartag::detector {

namespace {

std::string message(const std::string& key, const std::string& value, const std::string& reason) {
  if (key.empty()) return "detector options: " + reason;
  return "detector options: " + key + ": '" + value + "': " + reason;
}

// Throws the detector's error for the first option that breaks its rule.
void fail(const std::string& key, const std::string& value, const std::string& reason) {
  throw OptionsError(key, value, reason);
}

}  // namespace

OptionsError::OptionsError(std::string key, std::string value, std::string reason)
    : std::invalid_argument(message(key, value, reason)),
      key_(std::move(key)),
      value_(std::move(value)),
      reason_(std::move(reason)) {}

namespace rules {

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
    throw OptionsError("features.max_range_m", rules::value_text(o.features.max_range_m),
                       "must be above features.min_range_m");
}

void validate_options(const DetectorOptions& options) {
  DetectorOptions copy = options;  // the visitor takes fields by reference
  rules::RuleChecker checker("", fail);
  visit_options(checker, copy);
  check_option_relations(copy);
}

}  // namespace lidartag::detector
