// SPDX-License-Identifier: Apache-2.0
// Named pipeline variants for the scoring tool and the benchmarks (the
// shipped defaults, the thesis's choices, ablations),
// and `section.field=value` overrides of PipelineParams.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/pipeline.hpp"

namespace tinyline::tomato_reasoning::eval {

class Variant {
 public:
  virtual ~Variant() = default;
  /// Runs on the scenario's cloud (gravity taken from the scenario).
  [[nodiscard]] virtual PipelineResult run(const Scenario& s) const = 0;
};

[[nodiscard]] std::vector<std::string> variant_names();
/// The parameters a variant starts from; throws std::invalid_argument for an unknown name.
[[nodiscard]] PipelineParams variant_params(const std::string& name);
[[nodiscard]] std::unique_ptr<Variant> make_variant(const std::string& name, const PipelineParams& params);

[[nodiscard]] std::vector<std::string> param_keys();
/// Sets one numeric field; throws std::invalid_argument naming an unknown key or a bad value.
void set_param(PipelineParams& p, const std::string& key, const std::string& value);

}  // namespace tinyline::tomato_reasoning::eval
